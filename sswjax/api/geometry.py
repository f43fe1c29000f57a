"""Depth maps and point clouds from a disparity map and the rig's calibration (the maths; the
files are :mod:`sswjax.data.calibration` and :mod:`sswjax.data.ply`).

Conventions (whole module):

- disparities: floating ``(H, W)`` in pixels, left view, row 0 at the top (``inf`` or NaN =
  unknown);
- a :class:`Calibration` holds the left camera's focal length ``f`` and principal point
  ``(cx, cy)`` in pixels, the ``baseline`` (in the unit depths come out in: millimetres for
  Middlebury) and ``doffs``, the x-difference of the two principal points (Middlebury's
  ``calib.txt``; 0 for a rig rectified to one principal point);
- depth ``Z = baseline * f / (d + doffs)``, float32 ``(H, W)``, ``inf`` where ``d + doffs <= 0``
  or ``d`` is not finite;
- points: the camera frame of the left view (x right, y down, z forward, OpenCV's
  convention), ``X = (u - cx) Z / f``, ``Y = (v - cy) Z / f`` at column ``u`` and row ``v``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sswjax._checks import check_floating, check_rank
from sswjax.api.images import to_float_image

__all__ = ["Calibration", "PointCloud", "check_calibration", "depth_from_disparity", "point_cloud"]


class Calibration(NamedTuple):
    """A rectified rig: focal length and principal point (pixels), baseline, ``doffs``.

    ``principal=None`` puts the principal point at the image centre, ``((W - 1) / 2,
    (H - 1) / 2)``, when the image is known.
    """

    focal: float
    baseline: float
    doffs: float = 0.0
    principal: tuple[float, float] | None = None


class PointCloud(NamedTuple):
    """Points of the valid pixels, row by row: float32 ``xyz (N, 3)`` and uint8 ``rgb (N, 3)``."""

    xyz: np.ndarray
    rgb: np.ndarray


def _finite(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    return float(value)


def _positive(name: str, value) -> float:
    value = _finite(name, value)
    if value <= 0:
        raise ValueError(f"{name} must be > 0, got {value:g}")
    return value


def check_calibration(calib: Calibration) -> Calibration:
    """Validate a :class:`Calibration`; return it with plain floats.

    Raises
    ------
    TypeError
        If ``calib`` is not a :class:`Calibration`.
    ValueError
        On a non-positive or non-finite focal length or baseline, a non-finite ``doffs`` or
        principal point, or a principal point that is not a pair.

    Examples
    --------
    >>> check_calibration(Calibration(focal=700, baseline=0.5))
    Calibration(focal=700.0, baseline=0.5, doffs=0.0, principal=None)
    """
    if not isinstance(calib, Calibration):
        raise TypeError(f"calib must be a sswjax.Calibration, got {type(calib).__name__}")
    principal = calib.principal
    if principal is not None:
        if len(principal) != 2:
            raise ValueError(f"principal point must be (cx, cy), got {principal!r}")
        principal = (_finite("principal point cx", principal[0]),
                     _finite("principal point cy", principal[1]))
    return Calibration(_positive("focal length", calib.focal),
                       _positive("baseline", calib.baseline), _finite("doffs", calib.doffs),
                       principal)


def depth_from_disparity(disparity, *, focal: float, baseline: float, doffs: float = 0.0
                         ) -> np.ndarray:
    """Depth ``Z = baseline * focal / (disparity + doffs)`` of every pixel.

    Parameters
    ----------
    disparity : array_like floating (H, W)
        Pixels; ``inf``/NaN = unknown.
    focal : float > 0
        Focal length in pixels.
    baseline : float > 0
        Distance between the camera centres; ``Z`` comes out in its unit.
    doffs : float
        x-difference of the principal points (right minus left as Middlebury defines it),
        pixels.

    Returns
    -------
    numpy.ndarray float32 (H, W)
        ``Z``; ``inf`` where ``disparity + doffs <= 0`` or the disparity is not finite.

    Examples
    --------
    >>> depth_from_disparity(np.array([[10.0, 0.0]]), focal=100, baseline=0.5)
    array([[ 5., inf]], dtype=float32)
    """
    disparity = np.asarray(disparity)
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    calib = check_calibration(Calibration(focal, baseline, doffs))
    shifted = disparity.astype(np.float64) + calib.doffs
    valid = np.isfinite(shifted) & (shifted > 0)
    depth = np.full(disparity.shape, np.inf, np.float32)
    with np.errstate(over="ignore"):  # a tiny d + doffs gives a depth beyond float32: inf
        depth[valid] = calib.baseline * calib.focal / shifted[valid]
    return depth


def _colours(image) -> np.ndarray:
    """uint8 ``(H, W, 3)`` colours of a user image (the formats of :func:`sswjax.match`)."""
    rgb = np.round(to_float_image(image) * 255).clip(0, 255).astype(np.uint8)
    return np.repeat(rgb, 3, axis=-1) if rgb.shape[-1] == 1 else rgb


def point_cloud(disparity, image, calib: Calibration) -> PointCloud:
    """The left view's pixels of finite positive depth as 3-D points with their colours.

    Parameters
    ----------
    disparity : array_like floating (H, W)
        Disparity of the left view in pixels.
    image : array_like (H, W) or (H, W, 1|3|4), uint8, uint16 or float in [0, 1]
        The left image (gray is repeated to three channels).
    calib : Calibration
        ``principal=None``: the image centre.

    Returns
    -------
    PointCloud
        float32 ``xyz (N, 3)`` (camera frame: x right, y down, z forward, the baseline's unit)
        and uint8 ``rgb (N, 3)``, row-major over the pixels with ``0 < Z < inf``.

    Examples
    --------
    >>> cloud = point_cloud(np.full((1, 3), 10.0), np.zeros((1, 3), np.uint8),
    ...                     Calibration(focal=100, baseline=0.5))
    >>> cloud.xyz.tolist()
    [[-0.05000000074505806, 0.0, 5.0], [0.0, 0.0, 5.0], [0.05000000074505806, 0.0, 5.0]]
    """
    calib = check_calibration(calib)
    disparity = np.asarray(disparity)
    check_rank("disparity", disparity, 2)
    rgb = _colours(image)
    if rgb.shape[:2] != disparity.shape:
        raise ValueError(f"image of {rgb.shape[1]}x{rgb.shape[0]} and disparity of "
                         f"{disparity.shape[1]}x{disparity.shape[0]} differ in size")
    depth = depth_from_disparity(disparity, focal=calib.focal, baseline=calib.baseline,
                                 doffs=calib.doffs)
    height, width = depth.shape
    cx, cy = calib.principal or ((width - 1) / 2, (height - 1) / 2)
    rows, cols = np.nonzero(np.isfinite(depth) & (depth > 0))
    z = depth[rows, cols].astype(np.float64)
    xyz = np.stack([(cols - cx) * z / calib.focal, (rows - cy) * z / calib.focal, z], axis=-1)
    return PointCloud(xyz.astype(np.float32), rgb[rows, cols])
