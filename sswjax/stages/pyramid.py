"""Scale changes of images and cost volumes by a factor of two (for cross-scale optimisation).

Array conventions (whole module): images are float32 ``(H, W, C)``; cost volumes are float32
``(D, H, W)``, disparity first. Halving averages 2 x 2 blocks (2 x 2 x 2 for volumes, an odd
last row, column or disparity paired with itself as if edge-replicated), so a coarse disparity
``j`` stands for the fine disparities ``2 j`` and ``2 j + 1``: the volume keeps its disparity
units only in the spatial directions, see :func:`halve_volume`. Doubling is the inverse
mapping, trilinear with the centres aligned: coarse pixel (or disparity) ``i`` sits at fine
``2 i + 0.5``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax._checks import check_floating, check_rank

__all__ = ["double_volume", "halve_image", "halve_volume"]


def _mean_of_pairs(x: jax.Array, axis: int) -> jax.Array:
    """Mean of the samples ``(2 i, 2 i + 1)`` along ``axis``; an odd last sample is paired
    with itself (the edge replicated). The edge joins the half-size odd samples, not the input:
    XLA CPU runs an edge padding of the whole image as a concatenation element by element
    (6.7 ms of ``fast``'s 80 on trainingQ Motorcycle for the pair's one padded row and column).
    """
    even = jax.lax.slice_in_dim(x, 0, None, 2, axis)
    odd = jax.lax.slice_in_dim(x, 1, None, 2, axis)
    if x.shape[axis] % 2:
        odd = jnp.concatenate([odd, jax.lax.slice_in_dim(x, x.shape[axis] - 1, None, 1, axis)],
                              axis=axis)
    return 0.5 * (even + odd)


def halve_image(image: jax.Array) -> jax.Array:
    """Mean of 2 x 2 pixel blocks.

    Parameters
    ----------
    image : float32 (H, W, C)

    Returns
    -------
    float32 (ceil(H / 2), ceil(W / 2), C)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> halve_image(jnp.arange(6.0).reshape(2, 3, 1))[..., 0].tolist()
    [[2.0, 3.5]]
    """
    check_rank("image", image, 3)
    check_floating("image", image)
    return _mean_of_pairs(_mean_of_pairs(image, 0), 1)


def halve_volume(cost: jax.Array) -> jax.Array:
    """Mean of 2 x 2 x 2 blocks of a cost volume (disparity pairs and 2 x 2 pixels).

    A disparity of ``d`` fine pixels is ``d / 2`` coarse pixels, so averaging the disparity
    pairs ``(2 j, 2 j + 1)`` gives the cost of coarse disparity ``j`` (to half a pixel).

    Parameters
    ----------
    cost : float32 (D, H, W)

    Returns
    -------
    float32 (ceil(D / 2), ceil(H / 2), ceil(W / 2))

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> halve_volume(jnp.ones((3, 2, 2))).shape
    (2, 1, 1)
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    return _mean_of_pairs(_mean_of_pairs(_mean_of_pairs(cost, 0), 1), 2)


def double_volume(coarse: jax.Array, *, shape: tuple[int, int, int]) -> jax.Array:
    """The inverse of :func:`halve_volume`: trilinear interpolation, centres aligned.

    Linear in disparity too, so that a sum with a fine volume stays smooth in ``d`` for the
    parabola of the sub-pixel fit (a repeated coarse plane biased it by a quarter pixel).

    Parameters
    ----------
    coarse : float32 (D', H', W')
    shape : (D, H, W), keyword-only
        The fine volume's shape, with ``D' = ceil(D / 2)`` etc.

    Returns
    -------
    float32 (D, H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> fine = double_volume(jnp.arange(2.0).reshape(1, 1, 2), shape=(2, 1, 4))
    >>> fine[1, 0].tolist()                      # pixel centres: 0.5 -> 0, 2.5 -> 1
    [0.0, 0.25, 0.75, 1.0]
    """
    check_rank("coarse", coarse, 3)
    check_floating("coarse", coarse)
    depth, height, width = shape
    expected = tuple(-(-n // 2) for n in shape)
    if tuple(coarse.shape) != expected:
        raise ValueError(f"coarse volume of shape {tuple(coarse.shape)} does not halve {shape}")
    # Linear interpolation with half-pixel centres, one axis at a time in O(n) (jax.image.resize
    # builds dense weight matrices: O(n^2) per axis, slower than the SGM it serves): fine 2i
    # samples the coarse grid at i - 1/4, fine 2i + 1 at i + 1/4; the borders are clamped.
    fine = coarse
    for axis, size in enumerate(shape):
        fine = jax.lax.slice_in_dim(_double_axis(fine, axis), 0, size, axis=axis)
    return fine


def _double_axis(x: jax.Array, axis: int) -> jax.Array:
    before, after = axis_neighbours(x, axis)
    return interleave(0.75 * x + 0.25 * before, 0.75 * x + 0.25 * after, axis)


def axis_neighbours(x: jax.Array, axis: int) -> tuple[jax.Array, jax.Array]:
    """Each element's neighbours before and after it along ``axis``, the borders repeated
    (shapes of ``x``): what doubling an axis with half-pixel centres reads."""
    n = x.shape[axis]
    before = jnp.concatenate([jax.lax.slice_in_dim(x, 0, 1, axis=axis),
                              jax.lax.slice_in_dim(x, 0, n - 1, axis=axis)], axis=axis)
    after = jnp.concatenate([jax.lax.slice_in_dim(x, 1, n, axis=axis),
                             jax.lax.slice_in_dim(x, n - 1, n, axis=axis)], axis=axis)
    return before, after


def interleave(even: jax.Array, odd: jax.Array, axis: int) -> jax.Array:
    """``even[i]`` at ``2 i`` and ``odd[i]`` at ``2 i + 1`` along ``axis`` (same shapes in, that
    axis doubled out): slices and a reshape, no gather."""
    pairs = jnp.stack([even, odd], axis=axis + 1)
    return pairs.reshape(even.shape[:axis] + (2 * even.shape[axis],) + even.shape[axis + 1:])
