"""Storage of a cost volume for the integer paths of :mod:`sswjax.stages.sgm`.

The paths run in int16, as OpenCV's SGBM does; the cost they read is stored in int16 steps at
the largest scale no sum of paths can overflow, or in 255 uint8 levels, each a whole number of
those int16 steps (a quarter of float32's bytes through the memory-bound scans).

The paths' sum comes back as the scans leave it (:class:`PathSums`, int16 steps), and the
selection reads it plane by plane (:func:`sum_planes`), converting as it goes.

Array conventions (whole module): costs float32 of any shape (elementwise), lower is better,
in the units of the aggregated cost; stored volumes int16 or uint8 of the same shape; volumes
``(D, H, W)``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

__all__ = ["SGM_DTYPES", "PathSums", "Quantisation", "as_volume", "dequantise", "quantisation",
           "quantise", "quantise_cost", "sum_planes"]

SGM_DTYPES = ("int16", "uint8", "float32")
"""What the paths read and compute in (``SemiGlobal.dtype``): ``"int16"`` and ``"uint8"`` the
cost quantised (``cost_bound`` and ``cost_levels`` of :func:`semi_global_sums`), int16 paths;
``"float32"`` exact."""


class Quantisation(NamedTuple):
    """How a cost volume is stored for the int16 paths (:func:`quantisation`).

    Attributes
    ----------
    scale : float32 scalar
        int16 steps of the paths per cost unit.
    step : int16 scalar or None
        int16 steps per stored level (uint8 storage); None: stored in int16 at ``scale``.
    cap : float scalar
        The largest cost stored, ``2 * cost_bound``; larger costs are clipped to it.
    levels : int or None
        Stored levels above 0 (uint8 storage), or None.
    """

    scale: Any
    step: Any
    cap: Any
    levels: int | None


def quantisation(*, cost_bound, paths: int, p1, p2, cost_levels=None) -> Quantisation:
    """The storage of a cost volume for :func:`semi_global_sums` with these options.

    The scale is the largest at which no sum of ``paths`` paths can overflow int16,
    ``(2 ** 15 - 1 - 2 * paths) / (paths * (2 * cost_bound + max(p1, p2)))`` steps per cost
    unit. With ``cost_levels`` (255) the cost is stored in uint8, ``[0, 2 * cost_bound]`` in
    that many levels, and a level is the largest whole number of int16 steps that keeps that
    bound (the scale is rounded down to it).

    Examples
    --------
    >>> q = quantisation(cost_bound=1.0, paths=4, p1=0.1, p2=0.8, cost_levels=255)
    >>> int(q.step), round(float(q.scale), 1)
    (22, 2805.0)
    """
    if cost_levels not in (None, 255):
        raise ValueError(f"cost_levels must be None or 255, got {cost_levels!r}")
    cap = 2.0 * cost_bound
    scale = (jnp.iinfo(jnp.int16).max - 2 * paths) / (paths * (cap + jnp.maximum(p1, p2)))
    if cost_levels is None:
        return Quantisation(scale, None, cap, None)
    step = jnp.floor(scale * cap / cost_levels).astype(jnp.int16)
    return Quantisation(step * (cost_levels / cap), step, cap, cost_levels)


def quantise_cost(cost: jax.Array, quant: Quantisation) -> jax.Array:
    """A float32 cost (any shape) as :func:`semi_global_sums` stores it: clipped to
    ``[0, quant.cap]``, int16 at ``quant.scale`` or uint8 in ``quant.levels`` levels.

    Elementwise, so a volume may be stored slice by slice as it is built.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> q = quantisation(cost_bound=1.0, paths=4, p1=0.1, p2=0.8, cost_levels=255)
    >>> quantise_cost(jnp.array([-1.0, 0.5, 1.0, 9.0]), q).tolist()
    [0, 64, 128, 255]
    """
    clipped = jnp.clip(cost, 0.0, quant.cap)
    if quant.levels is None:
        return quantise(clipped, quant.scale)
    return jnp.round(clipped * (quant.levels / quant.cap)).astype(jnp.uint8)


def quantise(values: jax.Array, scale) -> jax.Array:
    """``round(values * scale)`` as int16 (the caller keeps the result within its range)."""
    return jnp.round(values * scale).astype(jnp.int16)


def dequantise(values: jax.Array, scale) -> jax.Array:
    """Cost units of ``values`` quantised by :func:`quantise` (float32 as is when ``scale`` is
    None)."""
    return values if scale is None else values.astype(jnp.float32) / scale


class PathSums(NamedTuple):
    """The sum of the paths as the scans leave it, before any conversion.

    Attributes
    ----------
    sums : int16 or float32 (D, H, W)
    scale : float32 scalar or None
        Quantisation steps per cost unit of int16 ``sums`` (the cost is ``sums / scale``);
        ``None`` for float32 sums, which are the cost.
    carried : Seeds or None
        With seeds given to the scans (:mod:`sswjax.stages.paths`): the vertical paths'
        states captured for the neighbouring windows.
    """

    sums: jax.Array
    scale: Any
    carried: Any = None


def sum_planes(path_sums: PathSums, disparities) -> list[jax.Array]:
    """Float32 (H, W) cost planes of ``path_sums`` at ``disparities``, in range: int32 (K,)
    (gathered), or a sequence of ints (sliced, no copy).

    The conversion happens in the consumer's pass, so the float32 (D, H, W) volume is never
    written.
    """
    sums = path_sums.sums
    if isinstance(disparities, (list, tuple)):
        planes = [sums[d] for d in disparities]
    else:
        block = jnp.take(sums, disparities, axis=0)
        planes = [block[k] for k in range(block.shape[0])]
    return [dequantise(plane, path_sums.scale) for plane in planes]


def as_volume(cost) -> jax.Array:
    """The float32 (D, H, W) cost volume of a :class:`PathSums` (an array is returned as is)."""
    return cost if not isinstance(cost, PathSums) else dequantise(cost.sums, cost.scale)
