"""Depth and point clouds of a rectified match in the raw left camera's frame and pixels.

The disparity of the rectified left view (:func:`sswjax.api.rectify.rectify_pair`) is sampled
where each raw left pixel's ray crosses the rectified image: the raw pixel is undistorted
(``cv2.undistortPoints``) into its ray ``n = (x, y, 1)`` of the raw left camera, the ray is
rotated by ``R1`` into the rectified frame, ``r = R1 n``, and projected with ``P1``. The
rectified depth ``Z' = f B / (d + doffs)`` is the point ``Z' r / r_z``; in the raw frame
(``R1^T`` undone, the same centre) that is ``(Z' / r_z) n``: depth ``Z = Z' / r_z``.

Conventions (whole module): disparities float ``(H', W')`` of the rectified view in pixels
(non-finite: none); depth float32 ``(H, W)`` of the raw left image, ``inf`` where unknown;
points float32 ``(N, 3)`` in the raw left camera's frame (x right, y down, z forward; ``T``'s
unit), colours uint8 ``(N, 3)``.
"""

from __future__ import annotations

import numpy as np

from sswjax._checks import check_floating, check_rank
from sswjax.api.geometry import (PointCloud, Rectification, StereoCalibration,
                                 check_stereo_calibration, colours, depth_from_disparity,
                                 point_cloud)
from sswjax.api.rectify import MARGIN, lens, opencv, rectified_calibration

__all__ = ["raw_depth", "raw_point_cloud", "raw_rays"]


def _sample(disparity: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The disparity at rectified positions ``(u, v)``: bilinear where the four neighbours are
    finite and within 1 px of each other, else the nearest; NaN outside the map."""
    height, width = disparity.shape
    ok = (u >= -MARGIN) & (u <= width - 1 + MARGIN) & (v >= -MARGIN) & (v <= height - 1 + MARGIN)
    u, v = np.where(ok, u, 0.0), np.where(ok, v, 0.0)
    nearest = disparity[np.clip(np.rint(v), 0, height - 1).astype(np.intp),
                        np.clip(np.rint(u), 0, width - 1).astype(np.intp)]
    x0 = np.clip(np.floor(u), 0, max(width - 2, 0)).astype(np.intp)
    y0 = np.clip(np.floor(v), 0, max(height - 2, 0)).astype(np.intp)
    x1, y1 = np.minimum(x0 + 1, width - 1), np.minimum(y0 + 1, height - 1)
    a = np.clip(u - x0, 0, 1)
    b = np.clip(v - y0, 0, 1)
    taps = np.stack([disparity[y0, x0], disparity[y0, x1], disparity[y1, x0], disparity[y1, x1]])
    with np.errstate(invalid="ignore"):
        smooth = np.isfinite(taps).all(axis=0) & (np.ptp(taps, axis=0) <= 1.0)
        blend = ((1 - b) * ((1 - a) * taps[0] + a * taps[1])
                 + b * ((1 - a) * taps[2] + a * taps[3]))
    return np.where(ok, np.where(smooth, blend, nearest), np.nan)


def raw_rays(calib: StereoCalibration, size: tuple[int, int]) -> np.ndarray:
    """float64 (H, W, 2): the undistorted normalised coordinates ``(x, y)`` of every raw left
    pixel (the ray ``(x, y, 1)`` of the raw left camera)."""
    cv2 = opencv()
    width, height = size
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    pixels = np.stack([u.ravel(), v.ravel()], axis=-1)[:, None, :]
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    rays = cv2.undistortPoints(pixels, calib.left_matrix, lens(calib.left_distortion),
                               criteria=criteria)
    return rays.reshape(height, width, 2)


def _raw(disparity, calib: StereoCalibration, rect: Rectification):
    """Depth float64 (H, W) in the raw left frame, on the raw pixels, and the rays (H, W, 2)."""
    disparity = np.asarray(disparity)
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    calib = check_stereo_calibration(calib)
    size = calib.image_size
    if size is None:
        raise ValueError("the calibration gives no image size: the raw frame is unknown")
    expected = rect.size or size
    if disparity.shape != (expected[1], expected[0]):
        raise ValueError(f"disparity of {disparity.shape[1]}x{disparity.shape[0]} is not the "
                         f"rectified size {expected[0]}x{expected[1]}")
    rig = rectified_calibration(rect)
    rays = raw_rays(calib, size)
    ray = np.concatenate([rays, np.ones(rays.shape[:2] + (1,))], axis=-1) @ np.asarray(rect.r1).T
    with np.errstate(divide="ignore", invalid="ignore"):
        forward = ray[..., 2] > 1e-9
        z = np.where(forward, ray[..., 2], 1.0)
        u = rig.focal * ray[..., 0] / z + rig.principal[0]
        v = rig.focal * ray[..., 1] / z + rig.principal[1]
        shifted = _sample(disparity.astype(np.float64), u, v) + rig.doffs
        good = forward & np.isfinite(shifted) & (shifted > 0)
        depth = np.where(good, rig.focal * rig.baseline / np.where(good, shifted, 1.0) / z, np.inf)
    return depth, rays


def raw_depth(disparity, calib: StereoCalibration, rect: Rectification) -> np.ndarray:
    """Depth of every raw left pixel in the raw left camera's frame.

    Parameters
    ----------
    disparity : floating (H', W')
        Disparity of the rectified left view (non-finite = unknown; set the pixels to leave
        out, e.g. :func:`~sswjax.api.rectify.outside_view`'s, to ``inf`` first).
    calib : StereoCalibration
        With its image size ``(W, H)``.
    rect : Rectification
        The one the pair was rectified with
        (:attr:`sswjax.api.rectify.RectifiedPair.rectification`).

    Returns
    -------
    numpy.ndarray float32 (H, W)
        ``Z`` of the raw left camera (``T``'s unit), ``inf`` where the rectified map has no
        depth; the disparity is sampled where the raw pixel's ray crosses the rectified image
        (bilinear where its four neighbours agree within 1 px, else the nearest). A
        ``rectified`` rig's depth is :func:`~sswjax.api.geometry.depth_from_disparity`'s.
    """
    calib = check_stereo_calibration(calib)
    if calib.rectified:
        rig = rectified_calibration(rect)
        return depth_from_disparity(disparity, focal=rig.focal, baseline=rig.baseline,
                                    doffs=rig.doffs)
    depth, _ = _raw(disparity, calib, rect)
    with np.errstate(over="ignore"):
        return depth.astype(np.float32)


def raw_point_cloud(disparity, image, calib: StereoCalibration, rect: Rectification
                    ) -> PointCloud:
    """The raw left pixels of finite positive depth as points in the raw left camera's frame.

    Parameters
    ----------
    disparity, calib, rect
        As for :func:`raw_depth`.
    image : array_like (H, W) or (H, W, 1|3|4)
        The raw left image, for the colours.

    Returns
    -------
    PointCloud
        float32 ``xyz (N, 3)``, ``Z`` times the pixel's undistorted ray ``(x, y, 1)``, and uint8
        ``rgb (N, 3)``, row-major over the raw pixels with ``0 < Z < inf``.
    """
    calib = check_stereo_calibration(calib)
    if calib.rectified:
        return point_cloud(disparity, image, rectified_calibration(rect))
    rgb = colours(image)
    depth, rays = _raw(disparity, calib, rect)
    if rgb.shape[:2] != depth.shape:
        raise ValueError(f"image of {rgb.shape[1]}x{rgb.shape[0]} is not the calibration's "
                         f"{depth.shape[1]}x{depth.shape[0]}")
    rows, cols = np.nonzero(np.isfinite(depth) & (depth > 0))
    z = depth[rows, cols]
    xyz = np.stack([rays[rows, cols, 0] * z, rays[rows, cols, 1] * z, z], axis=-1)
    return PointCloud(xyz.astype(np.float32), rgb[rows, cols])
