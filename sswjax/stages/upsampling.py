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
the neighbour whose mean colour is nearest to its own, so the edge follows the fine image
instead of the coarse grid. The colour choice is the range term of joint bilateral upsampling
(Kopf et al., "Joint bilateral upsampling", SIGGRAPH 2007) taken to its limit, a selection:
averaging across a depth edge would invent disparities of neither surface. The design notes
of the README give the measurements that chose it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax._checks import check_floating, check_rank

__all__ = ["double_nearest", "upsample_disparity"]


def _neighbours(fine: int, coarse: int) -> tuple[jax.Array, jax.Array, jax.Array]:
    """For each fine index along one axis: the two nearest coarse indices (clipped to the
    grid) and the bilinear weight of the second."""
    position = (jnp.arange(fine, dtype=jnp.float32) + 0.5) / 2 - 0.5
    low = jnp.floor(position)
    weight = position - low
    low = low.astype(jnp.int32)
    return jnp.clip(low, 0, coarse - 1), jnp.clip(low + 1, 0, coarse - 1), weight


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
    rows = _neighbours(height, coarse.shape[0])
    cols = _neighbours(width, coarse.shape[1])
    doubled = 2.0 * coarse
    values, weights, distances = [], [], []
    for row, row_weight in ((rows[0], 1.0 - rows[2]), (rows[1], rows[2])):
        for col, col_weight in ((cols[0], 1.0 - cols[2]), (cols[1], cols[2])):
            values.append(doubled[row][:, col])
            weights.append(row_weight[:, None] * col_weight[None, :])
            distances.append(jnp.abs(guide - coarse_guide[row][:, col]).mean(axis=-1))
    values, weights, distances = jnp.stack(values), jnp.stack(weights), jnp.stack(distances)
    bilinear = (weights * values).sum(axis=0)
    nearest_colour = jnp.take_along_axis(values, jnp.argmin(distances, axis=0)[None], axis=0)[0]
    smooth = values.max(axis=0) - values.min(axis=0) <= jump
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
    return values[jnp.arange(shape[0]) // 2][:, jnp.arange(shape[1]) // 2]
