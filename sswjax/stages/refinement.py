"""Disparity refinement (paper Section III-D, Eq. 9): left-right check, filling, side-window median.

Array conventions (whole module): cost volumes float32 ``(D, H, W)`` (slice ``d`` pairs left
``(y, x)`` with right ``(y, x - d)``); disparity maps float32 or int32 ``(H, W)`` in pixels;
validity masks bool ``(H, W)``.

Interpretation of Eq. (9). The paper fills invalid pixels with "the median of valid neighbours"
but a whole occluded band can have no valid neighbour in a small window. We therefore fill in
two steps: each invalid pixel first takes the smaller (background) of the nearest valid
disparities to its left and right on its row (occlusions belong to the farther surface), then
the filled pixels, and only those, are replaced by the median of their ``(2r+1)^2`` window.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_floating, check_rank, check_same_shape
from sswjax.stages.filters import median_filter, separable_median_filter

MEDIANS = {"square": median_filter, "separable": separable_median_filter}
"""The median of :func:`fill_invalid`: over the ``(2r+1)^2`` square (exact), or the separable
approximation (the median of the column medians: two ``2r + 1``-input sorting networks instead
of one ``(2r+1)^2``-input network)."""


def right_cost_volume(cost: jax.Array, *, disparities: jax.Array | None = None) -> jax.Array:
    """The right view's cost volume from the left one: ``C_R[d, y, x] = C_L[d, y, x + d]``.

    Where ``x + d >= W`` no left pixel matches and the cost is ``+inf``.

    Parameters
    ----------
    cost : float32 (K, H, W)
        Left-view cost slices.
    disparities : int32 (K,), optional
        The disparity of each slice (traced values are fine); default ``arange(K)``.

    Returns
    -------
    float32 (K, H, W)
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    count, _, width = cost.shape
    if disparities is None:
        disparities = jnp.arange(count)
    check_rank("disparities", disparities, 1)
    padded = jnp.pad(cost, ((0, 0), (0, 0), (0, width)), constant_values=jnp.inf)

    def shift_left(slice_, d):
        return lax.dynamic_slice_in_dim(slice_, jnp.clip(d, 0, width), width, axis=1)

    return jax.vmap(shift_left)(padded, disparities)


def left_right_distance(left_disparity: jax.Array, right_disparity: jax.Array) -> jax.Array:
    """``|d_L(x) - d_R(x - round(d_L(x)))|``, ``+inf`` where ``x - round(d_L(x)) < 0``.

    Parameters
    ----------
    left_disparity, right_disparity : float32 or int32 (H, W)

    Returns
    -------
    float32 (H, W), pixels

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> left_right_distance(jnp.array([[1, 1, 2, 0]]), jnp.array([[1, 1, 3, 0]])).tolist()
    [[inf, 0.0, 1.0, 0.0]]
    """
    check_rank("left_disparity", left_disparity, 2)
    check_same_shape("left_disparity", left_disparity, "right_disparity", right_disparity)
    width = left_disparity.shape[1]
    columns = jnp.arange(width)[None, :]
    target = columns - jnp.round(left_disparity).astype(jnp.int32)
    matched = jnp.take_along_axis(right_disparity, jnp.clip(target, 0, width - 1), axis=1)
    distance = jnp.abs(left_disparity.astype(jnp.float32) - matched.astype(jnp.float32))
    return jnp.where(target >= 0, distance, jnp.inf)


def left_right_consistency(
    left_disparity: jax.Array, right_disparity: jax.Array, *, tolerance
) -> jax.Array:
    """Left-right check: ``|d_L(x) - d_R(x - round(d_L(x)))| <= tolerance`` and ``x - d_L >= 0``.

    Parameters
    ----------
    left_disparity, right_disparity : float32 or int32 (H, W)
    tolerance : float >= 0, pixels

    Returns
    -------
    bool (H, W), True where the left disparity is confirmed.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> dl = jnp.array([[0, 1, 1, 1]])
    >>> dr = jnp.array([[1, 1, 3, 0]])
    >>> left_right_consistency(dl, dr, tolerance=0).tolist()
    [[False, True, True, False]]
    """
    return left_right_distance(left_disparity, right_disparity) <= tolerance


def fill_background(disparity: jax.Array, valid: jax.Array, *, left_band: bool = False
                    ) -> jax.Array:
    """Give each invalid pixel the smaller of the nearest valid disparities left and right of it.

    A side without a valid pixel is ignored; a row without any valid pixel gets 0.

    Parameters
    ----------
    disparity : float32 (H, W)
    valid : bool (H, W)
    left_band : bool, keyword-only
        Where the nearest valid disparity on the right, ``d_r``, exceeds the pixel's column
        ``x`` (so that surface, carried leftwards, has no match in the right image: what makes
        the pixel fail the check), take ``d_r`` rather than the smaller one: near the left
        border the smaller one is usually a wrong match, not the background.

    Returns
    -------
    float32 (H, W), equal to ``disparity`` where ``valid``.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.array([[9., 2., 0., 0., 5., 0.]])
    >>> v = jnp.array([[False, True, False, False, True, False]])
    >>> fill_background(d, v).tolist()
    [[2.0, 2.0, 2.0, 2.0, 5.0, 5.0]]
    """
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    check_same_shape("disparity", disparity, "valid", valid)
    width = disparity.shape[1]
    columns = jnp.broadcast_to(jnp.arange(width), disparity.shape)
    last_valid_left = lax.cummax(jnp.where(valid, columns, -1), axis=1)
    next_valid_right = lax.cummin(jnp.where(valid, columns, width), axis=1, reverse=True)
    from_left = jnp.take_along_axis(disparity, jnp.clip(last_valid_left, 0, width - 1), axis=1)
    from_right = jnp.take_along_axis(disparity, jnp.clip(next_valid_right, 0, width - 1), axis=1)
    from_left = jnp.where(last_valid_left >= 0, from_left, jnp.inf)
    from_right = jnp.where(next_valid_right < width, from_right, jnp.inf)
    fill = jnp.minimum(from_left, from_right)
    if left_band:
        fill = jnp.where(jnp.isfinite(from_right) & (columns < from_right), from_right, fill)
    fill = jnp.where(jnp.isfinite(fill), fill, 0.0)
    return jnp.where(valid, disparity, fill)


def fill_invalid(disparity: jax.Array, valid: jax.Array, *, radius: int, left_band: bool = False,
                 median: str = "square") -> jax.Array:
    """Eq. (9) as we read it: background fill, then a median over the filled pixels only.

    Parameters
    ----------
    disparity : float32 (H, W)
    valid : bool (H, W)
    radius : int >= 0
        Median window radius; 0 keeps the background fill.
    left_band : bool
        See :func:`fill_background`.
    median : {"square", "separable"}
        A key of :data:`MEDIANS`: the median over the ``(2r+1)^2`` window, or the separable
        approximation (the median of its column medians).

    Returns
    -------
    float32 (H, W), dense; equal to ``disparity`` where ``valid``.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.array([[1., 1., 1., 0., 5., 5.]] * 3)
    >>> v = jnp.array([[True, True, True, False, True, True]] * 3)
    >>> fill_invalid(d, v, radius=1, median="separable")[1].tolist()
    [1.0, 1.0, 1.0, 1.0, 5.0, 5.0]
    """
    if median not in MEDIANS:
        raise ValueError(f"median must be one of {tuple(MEDIANS)}, got {median!r}")
    filled = fill_background(disparity, valid, left_band=left_band)
    if radius == 0:
        return filled
    return jnp.where(valid, filled, MEDIANS[median](filled, radius=radius))
