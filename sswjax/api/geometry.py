"""Depth maps and point clouds from a disparity map and the rig's calibration (the maths; the
files are :mod:`sswjax.data.calibration` and :mod:`sswjax.data.ply`), and the calibration of a
raw stereo camera, :class:`StereoCalibration` (its rectification: :mod:`sswjax.api.rectify`).

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
  convention), ``X = (u - cx) Z / f``, ``Y = (v - cy) Z / f`` at column ``u`` and row ``v``;
- a :class:`StereoCalibration` is OpenCV's: float64 camera matrices ``K (3, 3)``, distortion
  ``D (n,)`` (``k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]``, n in 0, 4, 5, 8, 12, 14),
  and the right camera's pose ``x_right = R x_left + T`` (``R (3, 3)``, ``T (3,)`` in the unit
  depths come out in); image sizes are ``(width, height)``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sswjax._checks import check_floating, check_rank
from sswjax.api.images import to_float_image

__all__ = ["Calibration", "PointCloud", "Rectification", "StereoCalibration", "check_calibration",
           "check_stereo_calibration", "checked_array", "colours", "depth_from_disparity",
           "point_cloud"]


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


def colours(image) -> np.ndarray:
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
    rgb = colours(image)
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


# ----------------------------------------------------------------------------- raw stereo rigs


class Rectification(NamedTuple):
    """A rig's rectification, as ``cv2.stereoRectify`` gives it (float64).

    ``r1``, ``r2`` (3, 3): rotations from each raw camera's frame to its rectified frame;
    ``p1``, ``p2`` (3, 4): projections from the rectified left frame into each rectified image;
    ``q`` (4, 4) or None: disparity-to-depth matrix (``cv2.reprojectImageTo3D``); ``size``
    ``(width, height)`` of the rectified images, or None for the raw images' size.
    """

    r1: np.ndarray
    r2: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    q: np.ndarray | None = None
    size: tuple[int, int] | None = None


class StereoCalibration(NamedTuple):
    """A calibrated stereo camera: OpenCV's ``K1 D1 K2 D2 R T`` (module docstring).

    ``image_size`` ``(width, height)`` of the raw images (None: not in the file);
    ``rectification`` the one the calibration tool computed, if any; ``rectified`` True for a
    rig whose images are rectified already (Middlebury's ``calib.txt``, KITTI's rectified
    cameras): rectification leaves its images as they are.
    """

    left_matrix: np.ndarray
    left_distortion: np.ndarray
    right_matrix: np.ndarray
    right_distortion: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    image_size: tuple[int, int] | None = None
    rectification: Rectification | None = None
    rectified: bool = False


NAMES = {"left_matrix": "K1", "left_distortion": "D1", "right_matrix": "K2",
         "right_distortion": "D2", "rotation": "R", "translation": "T", "image_size": "image size",
         "r1": "R1", "r2": "R2", "p1": "P1", "p2": "P2", "q": "Q", "size": "rectified size"}
"""Field of :class:`StereoCalibration` and :class:`Rectification` -> its name in messages."""

DISTORTION_SIZES = (0, 4, 5, 8, 12, 14)
"""Distortion vector lengths OpenCV's pinhole model takes."""


def checked_array(value, name: str, *, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """float64 array of ``value`` with ``shape`` (a vector ``(n,)`` takes any shape of ``n``
    numbers), every value finite; else ``ValueError`` of one line naming ``name``."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers, got {str(value)[:40]!r}") from None
    if shape is not None and len(shape) == 1 and array.size == shape[0]:
        array = array.reshape(shape)
    if shape is not None and array.shape != shape:
        want, got = "x".join(map(str, shape)), "x".join(map(str, array.shape)) or "one number"
        raise ValueError(f"{name} must be {want}, got {got}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} has non-finite values")
    return array


def _camera_matrix(value, name: str, columns: int = 3) -> np.ndarray:
    """A 3x3 (or 3x4 projection) ``[fx s cx; 0 fy cy; 0 0 1]`` with ``fx, fy > 0``."""
    matrix = checked_array(value, name, shape=(3, columns))
    if matrix[0, 0] == 0 or matrix[1, 1] == 0:
        raise ValueError(f"{name} is singular: a focal length is 0")
    if (matrix[1, 0], matrix[2, 0], matrix[2, 1]) != (0, 0, 0) or \
            not math.isclose(matrix[2, 2], 1.0, abs_tol=1e-9):
        raise ValueError(f"{name} is not a camera matrix [fx 0 cx; 0 fy cy; 0 0 1]")
    if matrix[0, 0] < 0 or matrix[1, 1] < 0:
        raise ValueError(f"{name} has a negative focal length")
    return matrix


def _rotation(value, name: str) -> np.ndarray:
    matrix = checked_array(value, name, shape=(3, 3))
    error = float(np.abs(matrix @ matrix.T - np.eye(3)).max())
    if error > 1e-4:
        detail = "singular" if abs(np.linalg.det(matrix)) < 1e-9 else f"R R^T - I up to {error:.2g}"
        raise ValueError(f"{name} is not a rotation matrix ({detail})")
    if np.linalg.det(matrix) < 0:
        raise ValueError(f"{name} is a reflection, not a rotation (determinant -1)")
    return matrix


def _size(value, name: str) -> tuple[int, int] | None:
    if value is None:
        return None
    width, height = checked_array(value, name, shape=(2,))
    if not (width.is_integer() and height.is_integer() and width >= 1 and height >= 1):
        raise ValueError(f"{name} must be two positive integers (width, height), "
                         f"got {width:g} x {height:g}")
    return int(width), int(height)


def _distortion(value, name: str) -> np.ndarray:
    flat = np.asarray(value, dtype=np.float64).reshape(-1) if value is not None else np.zeros(0)
    if flat.size not in DISTORTION_SIZES:
        raise ValueError(f"{name} must have 4, 5, 8, 12 or 14 coefficients, got {flat.size}")
    if not np.isfinite(flat).all():
        raise ValueError(f"{name} has non-finite values")
    return flat


def check_stereo_calibration(calib: StereoCalibration, *, names=None) -> StereoCalibration:
    """Validate a :class:`StereoCalibration`; return it with float64 arrays.

    Parameters
    ----------
    calib : StereoCalibration
    names : mapping, optional
        Field -> its name in the messages (default :data:`NAMES`, OpenCV's names); the
        readers of :mod:`sswjax.data.calibration` pass the keys of their format.

    Raises
    ------
    ValueError
        One line naming the field: a wrong shape, non-finite values, a camera matrix that is
        singular or not ``[fx 0 cx; 0 fy cy; 0 0 1]``, a distortion of the wrong length, a
        rotation that is not one, a zero translation, a bad image size.

    Examples
    --------
    >>> eye = np.eye(3)
    >>> check_stereo_calibration(StereoCalibration(eye, None, eye, None, eye, [0, 0, 0]))
    Traceback (most recent call last):
    ...
    ValueError: T is zero: the two cameras are at the same place
    """
    if not isinstance(calib, StereoCalibration):
        raise TypeError(f"calib must be a sswjax.api.geometry.StereoCalibration, "
                        f"got {type(calib).__name__}")
    name = {**NAMES, **(names or {})}
    translation = checked_array(calib.translation, name["translation"], shape=(3,))
    if not np.any(translation):
        raise ValueError(f"{name['translation']} is zero: the two cameras are at the same place")
    rect = calib.rectification
    if rect is not None:
        q = None if rect.q is None else checked_array(rect.q, name["q"], shape=(4, 4))
        rect = Rectification(_rotation(rect.r1, name["r1"]), _rotation(rect.r2, name["r2"]),
                             _camera_matrix(rect.p1, name["p1"], 4),
                             _camera_matrix(rect.p2, name["p2"], 4), q,
                             _size(rect.size, name["size"]))
    return StereoCalibration(
        _camera_matrix(calib.left_matrix, name["left_matrix"]),
        _distortion(calib.left_distortion, name["left_distortion"]),
        _camera_matrix(calib.right_matrix, name["right_matrix"]),
        _distortion(calib.right_distortion, name["right_distortion"]),
        _rotation(calib.rotation, name["rotation"]), translation,
        _size(calib.image_size, name["image_size"]), rect, bool(calib.rectified))
