"""Doubling a disparity map computed on the pair halved (the coarse-to-fine ``fast`` preset).

Array conventions (whole module): a coarse map is float32 ``(h, w)`` in coarse pixels, computed
on images halved by :func:`sswjax.stages.pyramid.halve_image`, so ``h = ceil(H / 2)`` and
``w = ceil(W / 2)`` for a fine ``(H, W)``; coarse pixel ``i`` covers fine pixels ``2 i`` and
``2 i + 1`` and its centre sits at fine ``2 i + 0.5``. Guides are float32 ``(H, W, C)`` (fine)
and ``(h, w, C)`` (the same image halved), values in [0, 1]. Returned maps are float32
``(H, W)`` in fine pixels (twice the coarse values).

The rule, per fine pixel: its four nearest coarse pixels (bilinear neighbours) give four
disparities. Where they agree within ``jump`` fine pixels the surface is smooth there, and the
pixel takes their bilinear interpolation (exact on planes: slanted roads and walls stay
slanted). Where they disagree the pixel lies near a depth edge, and it takes the disparity of
the neighbour whose mean colour (over its 2 x 2 pixels) is nearest to its own (sum of absolute
channel differences), so the edge follows the fine image instead of the coarse grid. The colour
choice is the range term of joint bilateral upsampling (Kopf et al., "Joint bilateral
upsampling", SIGGRAPH 2007) taken to its limit, a selection: averaging across a depth edge
would invent disparities of neither surface. ``docs/notes/speed.md`` gives the measurements that
chose it.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_floating, check_rank
from sswjax.stages.pyramid import axis_neighbours, interleave

__all__ = ["double_nearest", "upsample_disparity"]


def _neighbours(coarse: jax.Array, axis: int, fine: int) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The two nearest coarse values along ``axis`` of each fine index (clipped at the borders)
    and the bilinear weight of the first: fine ``2 i`` lies between coarse ``i - 1`` (weight
    1/4) and ``i`` (3/4), fine ``2 i + 1`` between ``i`` (3/4) and ``i + 1`` (1/4). Slices, not
    gathers: XLA CPU runs them as plain copies."""
    before, after = axis_neighbours(coarse, axis)
    first = lax.slice_in_dim(interleave(before, coarse, axis), 0, fine, axis=axis)
    second = lax.slice_in_dim(interleave(coarse, after, axis), 0, fine, axis=axis)
    weight = jnp.where(jnp.arange(fine) % 2 == 0, 0.25, 0.75).astype(jnp.float32)
    return first, second, weight


def _check_sizes(coarse_shape, fine_shape) -> None:
    expected = ((fine_shape[0] + 1) // 2, (fine_shape[1] + 1) // 2)
    if tuple(coarse_shape[:2]) != expected:
        raise ValueError(f"a coarse map of a {fine_shape[0]} x {fine_shape[1]} image must be "
                         f"{expected[0]} x {expected[1]}, got {coarse_shape[0]} x {coarse_shape[1]}")


def upsample_disparity(coarse: jax.Array, guide: jax.Array, coarse_guide: jax.Array, *,
                       jump) -> jax.Array:
    """Double a coarse disparity map: bilinear where the surface is smooth, the nearest colour
    at depth edges (module docstring).

    Parameters
    ----------
    coarse : float32 (h, w)
        Disparities of the halved pair, in coarse pixels.
    guide : float32 (H, W, C)
        The fine left image; ``h = ceil(H / 2)``, ``w = ceil(W / 2)``.
    coarse_guide : float32 (h, w, C)
        The left image halved (:func:`~sswjax.stages.pyramid.halve_image`).
    jump : float
        Largest spread, in fine pixels, of the four neighbours' disparities that still counts as
        a smooth surface (traced: it can be searched).

    Returns
    -------
    float32 (H, W), in fine pixels.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> from sswjax.stages.pyramid import halve_image
    >>> guide = jnp.zeros((4, 6, 1))
    >>> plane = jnp.tile(jnp.arange(3.0), (2, 1))
    >>> upsample_disparity(plane, guide, halve_image(guide), jump=4.0)[0].tolist()
    [0.0, 0.5, 1.5, 2.5, 3.5, 4.0]
    """
    check_rank("coarse", coarse, 2)
    check_floating("coarse", coarse)
    check_rank("guide", guide, 3)
    check_floating("guide", guide)
    check_rank("coarse_guide", coarse_guide, 3)
    check_floating("coarse_guide", coarse_guide)
    _check_sizes(coarse.shape, guide.shape)
    _check_sizes(coarse_guide.shape, guide.shape)
    if coarse_guide.shape[-1] != guide.shape[-1]:
        raise ValueError(f"guide and coarse_guide must have the same channels, got "
                         f"{guide.shape[-1]} and {coarse_guide.shape[-1]}")
    height, width = guide.shape[:2]
    channels = guide.shape[-1]
    # Channels first (the coarse colours and the doubled disparity as one (C + 1, h, w) stack,
    # the guide as C planes): on channels-last arrays the per-pixel colour distances ran 7x
    # slower on XLA CPU. Neighbours by rows, then by columns.
    stacked = jnp.concatenate([jnp.moveaxis(coarse_guide, -1, 0), 2.0 * coarse[None]], axis=0)
    planes = [guide[..., k] for k in range(channels)]
    first_row, second_row, row_weight = _neighbours(stacked, 1, height)
    values, weights, distances = [], [], []
    for rows, along_rows in ((first_row, row_weight), (second_row, 1.0 - row_weight)):
        first_col, second_col, col_weight = _neighbours(rows, 2, width)
        for neighbour, along_cols in ((first_col, col_weight), (second_col, 1.0 - col_weight)):
            values.append(neighbour[channels])
            weights.append(along_rows[:, None] * along_cols[None, :])
            distances.append(sum(jnp.abs(planes[k] - neighbour[k]) for k in range(channels)))
    # Chains of element-wise operations over the four neighbours (reductions and argmin over a
    # stacked major axis run several times slower on XLA CPU); ties keep the first neighbour.
    bilinear = sum(w * v for w, v in zip(weights, values))
    nearest_colour, best = values[0], distances[0]
    for value, distance in zip(values[1:], distances[1:]):
        closer = distance < best
        nearest_colour = jnp.where(closer, value, nearest_colour)
        best = jnp.where(closer, distance, best)
    spread = functools.reduce(jnp.maximum, values) - functools.reduce(jnp.minimum, values)
    smooth = spread <= jump
    return jnp.where(smooth, bilinear, nearest_colour)


def double_nearest(values: jax.Array, *, shape: tuple[int, int]) -> jax.Array:
    """Each coarse pixel's value on the fine pixels it covers (nearest-neighbour doubling).

    Parameters
    ----------
    values : (h, w), any dtype
    shape : (H, W) with ``h = ceil(H / 2)``, ``w = ceil(W / 2)``

    Returns
    -------
    (H, W), the dtype of ``values``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> double_nearest(jnp.array([[1, 2]]), shape=(1, 3)).tolist()
    [[1, 1, 2]]
    """
    check_rank("values", values, 2)
    _check_sizes(values.shape, shape)
    doubled = jnp.repeat(jnp.repeat(values, 2, axis=0), 2, axis=1)
    return doubled[:shape[0], :shape[1]]
