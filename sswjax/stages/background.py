"""The background fill of the pixels the checks rejected (paper Section III-D, Eq. 9).

Array conventions (whole module): disparity maps float32 ``(H, W)`` in pixels; validity masks
bool ``(H, W)``.

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
from sswjax.stages.medians import median_filter, separable_median_filter

MEDIANS = {"square": median_filter, "separable": separable_median_filter}
"""The median of :func:`fill_invalid`: over the ``(2r+1)^2`` square (exact), or the separable
approximation (the median of the column medians: two ``2r + 1``-input sorting networks instead
of one ``(2r+1)^2``-input network)."""


def nearest_valid(disparity: jax.Array, valid: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The disparities of the nearest valid pixels to the left and to the right on each row
    (a pixel's own where it is valid); ``+inf`` where a side has none.

    Parameters
    ----------
    disparity : float32 (H, W)
    valid : bool (H, W)

    Returns
    -------
    (float32 (H, W), float32 (H, W)): from the left, from the right.
    """
    width = disparity.shape[1]
    columns = jnp.broadcast_to(jnp.arange(width), disparity.shape)
    last_valid_left = lax.cummax(jnp.where(valid, columns, -1), axis=1)
    next_valid_right = lax.cummin(jnp.where(valid, columns, width), axis=1, reverse=True)
    from_left = jnp.take_along_axis(disparity, jnp.clip(last_valid_left, 0, width - 1), axis=1)
    from_right = jnp.take_along_axis(disparity, jnp.clip(next_valid_right, 0, width - 1), axis=1)
    return (jnp.where(last_valid_left >= 0, from_left, jnp.inf),
            jnp.where(next_valid_right < width, from_right, jnp.inf))


def fill_background(disparity: jax.Array, valid: jax.Array, *, left_band: bool = False,
                    band_fit: int = 0) -> jax.Array:
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
    band_fit : int >= 0, keyword-only
        With ``left_band``, ``k > 0``: the pixels left of their row's first valid pixel ``x0``
        (the band of the left border that has no match) take the straight line
        ``d = a + b (x - x0)`` fitted by least squares to the valid pixels of columns
        ``x0 .. x0 + k - 1``, when at least a third of them are valid (else the rule above),
        clipped below at 0: a slanted surface continues into the band, where a constant leaves
        it over a band as wide as its disparity. 0: the constant.

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
    columns = jnp.arange(disparity.shape[1])[None, :]
    from_left, from_right = nearest_valid(disparity, valid)
    fill = jnp.minimum(from_left, from_right)
    if left_band:
        fill = jnp.where(jnp.isfinite(from_right) & (columns < from_right), from_right, fill)
    fill = jnp.where(jnp.isfinite(fill), fill, 0.0)
    if band_fit > 0:
        if not left_band:
            raise ValueError("band_fit > 0 needs left_band=True")
        fill = _fit_band(disparity, valid, fill, band_fit)
    return jnp.where(valid, disparity, fill)


def _fit_band(disparity: jax.Array, valid: jax.Array, fill: jax.Array, width: int) -> jax.Array:
    """``fill`` with each row's pixels left of its first valid one on the row's fitted line
    (:func:`fill_background`'s ``band_fit``); all arrays (H, W)."""
    columns = jnp.arange(disparity.shape[1])[None, :]
    first = jnp.argmax(valid, axis=1)[:, None]
    offset = (columns - first).astype(jnp.float32)
    counted = valid & (offset < width) & (offset >= 0)

    def total(x):
        return jnp.sum(jnp.where(counted, x, 0.0), axis=1, keepdims=True)

    safe = jnp.where(counted, disparity, 0.0)
    n, sx, sd = total(1.0), total(offset), total(safe)
    sxx, sxd = total(offset * offset), total(offset * safe)
    det = n * sxx - sx * sx
    slope = jnp.where(det > 0, (n * sxd - sx * sd) / jnp.where(det > 0, det, 1.0), 0.0)
    intercept = (sd - slope * sx) / jnp.maximum(n, 1.0)
    # Clipped below only: an upper bound read from the image (its largest disparity, or its
    # row's) would differ in a window of strips or tiles and change the fill there; the graph
    # clips the map to the search range after the fill (docs/cluster.md).
    line = jnp.maximum(intercept + slope * offset, 0.0)
    return jnp.where((offset < 0) & (3 * n >= width), line, fill)


def fill_invalid(disparity: jax.Array, valid: jax.Array, *, radius: int, left_band: bool = False,
                 median: str = "square", band_fit: int = 0) -> jax.Array:
    """Eq. (9) as we read it: background fill, then a median over the filled pixels only.

    Parameters
    ----------
    disparity : float32 (H, W)
    valid : bool (H, W)
    radius : int >= 0
        Median window radius; 0 keeps the background fill.
    left_band : bool
        See :func:`fill_background`.
    band_fit : int >= 0
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
    filled = fill_background(disparity, valid, left_band=left_band, band_fit=band_fit)
    if radius == 0:
        return filled
    return jnp.where(valid, filled, MEDIANS[median](filled, radius=radius))
