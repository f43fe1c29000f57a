"""Slanted-plane refinement: a robust plane ``d = a x + b y + c`` per superpixel, fitted to its
reliable pixels, replaces the unreliable ones where it fits.

Array conventions (whole module): disparity maps float32 ``(H, W)`` in pixels; weights float32
``(H, W)`` in [0, 1] (0 = unreliable, e.g. rejected by the left-right check); superpixel labels
int32 ``(H, W)`` in ``[0, num_segments)``; planes float32 ``(num_segments, 3)`` holding
``(a, b, c)`` in coordinates centred on each segment's weighted centroid (``d = a (x - x0) +
b (y - y0) + c``), with the centroids float32 ``(num_segments, 2)`` as ``(x0, y0)``.

The fit is weighted least squares through segment sums (one ``jax.ops.segment_sum`` per moment,
a closed-form 3 x 3 solve per segment), repeated a few times with Huber-style weights on the
residuals (iteratively reweighted least squares), as in segment-based stereo (Bleyer & Gelautz
2005; Klaus et al. 2006, who fit one plane per mean-shift segment). Segments fronto-parallel
to the camera get ``a = b = 0``; a segment with too little support keeps no plane.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from sswjax._checks import check_floating, check_integer, check_positive_int, check_rank

__all__ = ["SegmentPlanes", "fit_segment_planes", "plane_disparity", "plane_refine"]


class SegmentPlanes(NamedTuple):
    """Fitted planes of every segment.

    Attributes
    ----------
    planes : float32 (K, 3)
        ``(a, b, c)`` per segment, centred on ``centroids``.
    centroids : float32 (K, 2)
        Weighted centroid ``(x0, y0)`` of each segment's reliable pixels.
    support : float32 (K,)
        Sum of the final weights (reliable, inlying pixels) per segment.
    count : float32 (K,)
        Number of pixels per segment.
    """

    planes: jax.Array
    centroids: jax.Array
    support: jax.Array
    count: jax.Array


def _sums(values, labels, num_segments):
    return jax.ops.segment_sum(values.reshape(-1), labels.reshape(-1), num_segments=num_segments)


def _solve(disparity, weights, labels, num_segments, ridge):
    """One weighted least-squares fit per segment, in segment-centred coordinates."""
    height, width = disparity.shape
    y, x = jnp.mgrid[0:height, 0:width].astype(jnp.float32)
    w_sum = _sums(weights, labels, num_segments)
    safe = jnp.maximum(w_sum, 1e-6)
    x0 = _sums(weights * x, labels, num_segments) / safe
    y0 = _sums(weights * y, labels, num_segments) / safe
    u, v = x - x0[labels], y - y0[labels]
    moment = {name: _sums(weights * value, labels, num_segments) for name, value in
              (("uu", u * u), ("uv", u * v), ("vv", v * v), ("u", u), ("v", v),
               ("ud", u * disparity), ("vd", v * disparity), ("d", disparity))}
    # Normal equations of min sum w (a u + b v + c - d)^2, with a small ridge on a and b so that
    # a segment whose reliable pixels lie on a line gets the flattest plane through them.
    matrix = jnp.stack([
        jnp.stack([moment["uu"] + ridge * safe, moment["uv"], moment["u"]], -1),
        jnp.stack([moment["uv"], moment["vv"] + ridge * safe, moment["v"]], -1),
        jnp.stack([moment["u"], moment["v"], safe], -1),
    ], -2)
    rhs = jnp.stack([moment["ud"], moment["vd"], moment["d"]], -1)
    planes = jnp.linalg.solve(matrix, rhs[..., None])[..., 0]
    return planes, jnp.stack([x0, y0], -1), w_sum


def plane_disparity(fit: SegmentPlanes, labels: jax.Array) -> jax.Array:
    """The plane's disparity at every pixel: float32 (H, W)."""
    check_rank("labels", labels, 2)
    check_integer("labels", labels)
    height, width = labels.shape
    y, x = jnp.mgrid[0:height, 0:width].astype(jnp.float32)
    a, b, c = (fit.planes[labels, k] for k in range(3))
    return a * (x - fit.centroids[labels, 0]) + b * (y - fit.centroids[labels, 1]) + c


def fit_segment_planes(
    disparity: jax.Array,
    weights: jax.Array,
    labels: jax.Array,
    *,
    num_segments: int,
    iterations: int = 3,
    inlier_scale=1.0,
    ridge=1e-3,
) -> SegmentPlanes:
    """Robust weighted least-squares plane of every segment (IRLS with Huber weights).

    Parameters
    ----------
    disparity : float32 (H, W)
    weights : float32 (H, W), in [0, 1]
        Prior reliability of each pixel (0 excludes it).
    labels : int32 (H, W), values in [0, num_segments)
    num_segments : int
    iterations : int >= 1
        Fits; each after the first reweights pixels by ``min(1, inlier_scale / |residual|)``.
    inlier_scale : float, pixels
        Residual up to which a pixel keeps its full weight.
    ridge : float >= 0
        Regularisation of the slopes, relative to the segment's weight.

    Returns
    -------
    SegmentPlanes

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> y, x = jnp.mgrid[0:6, 0:8].astype(jnp.float32)
    >>> d = 0.5 * x + 0.25 * y + 3.0
    >>> fit = fit_segment_planes(d, jnp.ones_like(d), jnp.zeros((6, 8), jnp.int32), num_segments=1)
    >>> [round(float(v), 3) for v in plane_disparity(fit, jnp.zeros((6, 8), jnp.int32))[5, :3]]
    [4.25, 4.75, 5.25]
    """
    for name, value in (("disparity", disparity), ("weights", weights)):
        check_rank(name, value, 2)
        check_floating(name, value)
    check_rank("labels", labels, 2)
    check_integer("labels", labels)
    check_positive_int("num_segments", num_segments)
    check_positive_int("iterations", iterations)
    if not disparity.shape == weights.shape == labels.shape:
        raise ValueError(f"disparity, weights and labels must have one shape, got "
                         f"{disparity.shape}, {weights.shape} and {labels.shape}")
    current = weights
    for _ in range(iterations):
        planes, centroids, support = _solve(disparity, current, labels, num_segments, ridge)
        fit = SegmentPlanes(planes, centroids, support, jnp.zeros_like(support))
        residual = jnp.abs(disparity - plane_disparity(fit, labels))
        current = weights * jnp.minimum(1.0, inlier_scale / jnp.maximum(residual, 1e-6))
    count = _sums(jnp.ones_like(disparity), labels, num_segments)
    return SegmentPlanes(planes, centroids, support, count)


def plane_refine(
    disparity: jax.Array,
    valid: jax.Array,
    labels: jax.Array,
    *,
    num_segments: int,
    min_support=0.25,
    iterations: int = 3,
    inlier_scale=1.0,
) -> jax.Array:
    """Replace the unreliable pixels of segments whose plane is well supported by the plane.

    A segment's plane is used where its reliable, inlying pixels (IRLS weights) make up at
    least ``min_support`` of the segment; pixels of other segments keep ``disparity``.

    Parameters
    ----------
    disparity : float32 (H, W)
        Disparities, already filled where not ``valid`` (the fallback).
    valid : bool (H, W)
        Pixels that passed the left-right check.
    labels : int32 (H, W)
    num_segments : int
    min_support : float in [0, 1]
    iterations : int >= 1
    inlier_scale : float, pixels

    Returns
    -------
    float32 (H, W), equal to ``disparity`` where ``valid``.
    """
    check_rank("valid", valid, 2)
    fit = fit_segment_planes(disparity, valid.astype(jnp.float32), labels,
                             num_segments=num_segments, iterations=iterations,
                             inlier_scale=inlier_scale)
    supported = (fit.support >= min_support * jnp.maximum(fit.count, 1.0))[labels]
    planes = plane_disparity(fit, labels)
    return jnp.where(valid | ~supported | ~jnp.isfinite(planes), disparity, planes)
