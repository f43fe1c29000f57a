"""Rectification of a raw stereo pair with OpenCV.

A :class:`~sswjax.api.geometry.StereoCalibration` (OpenCV's ``K1 D1 K2 D2 R T``) is turned into
a :class:`~sswjax.api.geometry.Rectification` (``cv2.stereoRectify``, or the one the calibration
tool computed), the pair is resampled into it (``cv2.initUndistortRectifyMap`` and
``cv2.remap``, bilinear) and matched as any rectified pair; :mod:`sswjax.api.raw_frame` takes
the depth and the cloud back to the raw left camera.

Conventions (whole module):

- images: NumPy ``(H, W)`` or ``(H, W, C)``, uint8, uint16 or floating, kept in their dtype;
- rectified images are edge-replicated where they come from outside the raw image (no black
  border for the matcher to match), and ``inside`` masks, bool ``(H', W')``, say which pixels
  came from inside it (a half-pixel margin: bilinear taps at most half a pixel beyond the
  border); the validity bit :data:`~sswjax.stages.confidence.OUTSIDE_VIEW` marks the pixels
  outside, or whose match is, and depth and clouds leave them out;
- frames: the rectified left camera's frame is ``R1`` times the raw left camera's (the same
  centre);
- OpenCV (``pip install "sswjax[camera]"``) is imported where it is used.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from sswjax._checks import check_rank
from sswjax.api.geometry import (Calibration, Rectification, StereoCalibration, check_calibration,
                                 check_stereo_calibration)
from sswjax.api.images import to_float_image
from sswjax.stages.confidence import OUTSIDE_VIEW

__all__ = ["MARGIN", "OUTSIDE_VIEW", "RectifiedPair", "as_rectified", "disparity_matrix",
           "lens", "opencv", "outside_view", "rectification", "rectified_calibration",
           "rectify_pair"]

MARGIN = 0.5
"""Pixels a rectified pixel's source may lie beyond the raw image's border and count as inside."""


def opencv():
    """The ``cv2`` module, or ``ImportError`` with one line saying how to install it."""
    try:
        import cv2
    except ImportError:
        raise ImportError('rectification needs OpenCV: pip install "sswjax[camera]"') from None
    return cv2


def _zero_disparity(cv2) -> int:
    return getattr(cv2, "STEREO_ZERO_DISPARITY", getattr(cv2, "CALIB_ZERO_DISPARITY", 1024))


def lens(distortion: np.ndarray) -> np.ndarray:
    """OpenCV's distortion vector (1, n): five zeros for none."""
    return (distortion if distortion.size else np.zeros(5)).reshape(1, -1)


def disparity_matrix(p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """``Q`` float64 (4, 4) of ``cv2.stereoRectify`` from two rectified projections (3, 4).

    Raises ``ValueError`` when the two projections share their x (no horizontal baseline:
    ``Q`` would divide by zero)."""
    tx = p2[0, 3] / p2[0, 0] - p1[0, 3] / p1[0, 0]
    if tx == 0:
        raise ValueError("P1 and P2 have the same x: no baseline along the rows")
    (f, cx1, cy), cx2 = (p1[0, 0], p1[0, 2], p1[1, 2]), p2[0, 2]
    return np.array([[1, 0, 0, -cx1], [0, 1, 0, -cy], [0, 0, 0, f],
                     [0, 0, -1 / tx, (cx1 - cx2) / tx]], np.float64)


def _identity(calib: StereoCalibration) -> Rectification:
    """The rectification of a rig already rectified: no rotation, ``P = K [I | t]`` (``q``
    None: :func:`_side_by_side` fills it in)."""
    p1 = np.hstack([calib.left_matrix, np.zeros((3, 1))])
    p2 = np.hstack([calib.right_matrix, calib.right_matrix @ calib.translation[:, None]])
    return Rectification(np.eye(3), np.eye(3), p1, p2, None, calib.image_size)


def _side_by_side(rect: Rectification) -> Rectification:
    """``rect`` checked to be a side-by-side pair (:func:`_check_side_by_side`), then its ``Q``
    computed when it has none: checked first, since ``Q`` divides by the baseline's x."""
    rect = _check_side_by_side(rect)
    return rect if rect.q is not None else rect._replace(q=disparity_matrix(rect.p1, rect.p2))


def _check_side_by_side(rect: Rectification) -> Rectification:
    tx, ty = rect.p2[0, 3] / rect.p2[0, 0], rect.p2[1, 3] / rect.p2[1, 1]
    if abs(ty) > abs(tx):
        raise ValueError("the cameras are one above the other after rectification (a vertical "
                         "rig): only side-by-side rigs are supported")
    if tx - rect.p1[0, 3] / rect.p1[0, 0] >= 0:
        raise ValueError("the right camera is left of the left one (T's x > 0): swap LEFT and "
                         "RIGHT and their calibrations")
    if not np.isclose(rect.p1[0, 0], rect.p1[1, 1], rtol=1e-6) or \
            not np.isclose(rect.p1[1, 2], rect.p2[1, 2], rtol=0, atol=1e-6):
        raise ValueError("P1 and P2 are not a rectified side-by-side pair (square pixels, one "
                         "row of principal points)")
    return rect


def rectification(calib: StereoCalibration, *, size: tuple[int, int] | None = None,
                  alpha: float | None = None) -> Rectification:
    """The rectification of a rig: its own, or ``cv2.stereoRectify``'s.

    Parameters
    ----------
    calib : StereoCalibration
    size : (width, height), optional
        The raw images' size when the calibration has none.
    alpha : float in [0, 1], optional
        ``cv2.stereoRectify``'s free scaling: 0 crops to valid pixels, 1 keeps every raw pixel.
        None (default): the calibration's own rectification when it has one, else 0.

    Returns
    -------
    Rectification
        Float64, ``q`` and ``size`` filled in. The identity for a ``rectified`` rig. Computed
        here: ``cv2.stereoRectify`` with ``STEREO_ZERO_DISPARITY``, then the right view moved
        along its rows so that each view is centred on its raw image (the middle of its middle
        row): a verged rig keeps its overlap, the principal points then differing by
        ``doffs`` (about 0 for a parallel rig); ``q`` follows.

    Raises
    ------
    ValueError
        On a bad calibration, no size, an ``alpha`` outside [0, 1], a vertical rig or swapped
        cameras.
    ImportError
        Without OpenCV, when the rectification must be computed.
    """
    calib = check_stereo_calibration(calib)
    if alpha is not None and (isinstance(alpha, bool) or not 0.0 <= float(alpha) <= 1.0):
        raise ValueError(f"alpha must be a number in [0, 1], got {alpha!r}")
    image_size = calib.image_size or (None if size is None else (int(size[0]), int(size[1])))
    if calib.rectified:
        return _side_by_side(_identity(calib._replace(image_size=image_size)))
    own = calib.rectification
    if own is not None and alpha is None:
        return _side_by_side(own._replace(size=own.size or image_size))
    if image_size is None:
        raise ValueError("the calibration gives no image size: pass the images' size")
    cv2 = opencv()
    r1, r2, p1, p2, _, _, _ = cv2.stereoRectify(
        calib.left_matrix, lens(calib.left_distortion), calib.right_matrix,
        lens(calib.right_distortion), image_size, calib.rotation,
        calib.translation.reshape(3, 1), flags=_zero_disparity(cv2),
        alpha=0.0 if alpha is None else float(alpha))
    p2 = p2.copy()  # each view centred on its raw image: a verged rig keeps its overlap
    p2[0, 2] += (_centre(cv2, image_size, calib.left_matrix, calib.left_distortion, r1, p1)
                 - _centre(cv2, image_size, calib.right_matrix, calib.right_distortion, r2, p2))
    return _side_by_side(Rectification(r1, r2, p1, p2, None, image_size))


def _centre(cv2, size, camera, distortion, rotation, projection) -> float:
    """The rectified column of the middle of a raw image's middle row's span."""
    width, height = size
    row = np.stack([np.arange(width, dtype=np.float64), np.full(width, (height - 1) / 2)], -1)
    columns = cv2.undistortPoints(row[:, None], camera, lens(distortion), R=rotation,
                                  P=projection[:, :3])[:, 0, 0]
    return float(columns.min() + columns.max()) / 2


def rectified_calibration(rect: Rectification) -> Calibration:
    """The rectified rig as a :class:`~sswjax.api.geometry.Calibration`: focal length and
    principal point of ``P1``, baseline ``-Tx`` (``T``'s unit), ``doffs = cx2 - cx1``.

    Examples
    --------
    >>> p1 = np.array([[500.0, 0, 320, 0], [0, 500, 240, 0], [0, 0, 1, 0]])
    >>> p2 = p1.copy(); p2[0, 3] = -500 * 0.12
    >>> rectified_calibration(Rectification(np.eye(3), np.eye(3), p1, p2))
    Calibration(focal=500.0, baseline=0.12, doffs=0.0, principal=(320.0, 240.0))
    """
    p1, p2 = np.asarray(rect.p1, np.float64), np.asarray(rect.p2, np.float64)
    baseline = p1[0, 3] / p1[0, 0] - p2[0, 3] / p2[0, 0]
    return check_calibration(Calibration(float(p1[0, 0]), float(baseline),
                                         float(p2[0, 2] - p1[0, 2]),
                                         (float(p1[0, 2]), float(p1[1, 2]))))


def as_rectified(calib: StereoCalibration) -> StereoCalibration:
    """The rig of images already rectified by ``calib``'s own rectification (KITTI's
    ``image_0x`` of ``calib_cam_to_cam.txt``): its rectified cameras, ``rectified=True``."""
    calib = check_stereo_calibration(calib)
    if calib.rectification is None:
        raise ValueError("the calibration has no rectification (R1 R2 P1 P2)")
    rect = _check_side_by_side(calib.rectification)
    rig = rectified_calibration(rect)
    eye, zeros = np.eye(3), np.zeros(0)
    return StereoCalibration(rect.p1[:, :3], zeros, rect.p2[:, :3], zeros, eye,
                             np.array([-rig.baseline, 0.0, 0.0]),
                             rect.size or calib.image_size, None, True)


class RectifiedPair(NamedTuple):
    """What :func:`rectify_pair` returns: the rectified images (the input dtype), the masks of
    their pixels that came from inside the raw images (bool), and the rectification."""

    left: np.ndarray
    right: np.ndarray
    left_inside: np.ndarray
    right_inside: np.ndarray
    rectification: Rectification


def _image(name: str, image) -> np.ndarray:
    image = np.asarray(image)
    to_float_image(image[:1, :1], name=name)  # the dtypes and channels of sswjax.match
    return image.astype(np.float32) if image.dtype == np.float64 else image


def _resample(cv2, image, camera, distortion, rotation, projection, size):
    maps = cv2.initUndistortRectifyMap(camera, lens(distortion), rotation, projection[:, :3], size,
                                       cv2.CV_32FC1)
    height, width = image.shape[:2]
    x, y = maps
    inside = ((x >= -MARGIN) & (x <= width - 1 + MARGIN) & (y >= -MARGIN)
              & (y <= height - 1 + MARGIN))
    out = cv2.remap(image, x, y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(size[1], size[0], *image.shape[2:]), inside


def rectify_pair(left, right, calib: StereoCalibration, *, alpha: float | None = None
                 ) -> RectifiedPair:
    """Rectify a raw pair: undistort both views and rotate them onto one image plane.

    Parameters
    ----------
    left, right : array_like (H, W) or (H, W, C), uint8, uint16 or float
        The raw images of the calibrated cameras.
    calib : StereoCalibration
    alpha : float in [0, 1], optional
        See :func:`rectification` (None: the calibration's own, else 0: valid pixels only).

    Returns
    -------
    RectifiedPair
        Images ``(H', W'[, C])`` of the input dtype (float64 comes back float32), masks bool
        ``(H', W')``, with ``(W', H')`` the rectification's size. A ``rectified`` rig's images
        come back as they are, every pixel inside.

    Raises
    ------
    ValueError
        If the images differ in size, or from the calibration's image size (one line), or
        as :func:`rectification`.
    """
    calib = check_stereo_calibration(calib)
    left, right = _image("left", left), _image("right", right)
    if left.shape[:2] != right.shape[:2]:
        raise ValueError(f"left and right images differ in size: {left.shape[1]}x"
                         f"{left.shape[0]} and {right.shape[1]}x{right.shape[0]}")
    size = (left.shape[1], left.shape[0])
    if calib.image_size is not None and calib.image_size != size:
        raise ValueError(f"image size {calib.image_size[0]}x{calib.image_size[1]} of the "
                         f"calibration does not match the images' {size[0]}x{size[1]}")
    rect = rectification(calib, size=size, alpha=alpha)
    if calib.rectified:
        every = np.ones(left.shape[:2], bool)
        return RectifiedPair(left, right, every, every.copy(), rect)
    cv2 = opencv()
    out = rect.size or size
    left, left_inside = _resample(cv2, left, calib.left_matrix, calib.left_distortion, rect.r1,
                                  rect.p1, out)
    right, right_inside = _resample(cv2, right, calib.right_matrix, calib.right_distortion,
                                    rect.r2, rect.p2, out)
    return RectifiedPair(left, right, left_inside, right_inside, rect)


def outside_view(disparity, left_inside, right_inside) -> np.ndarray:
    """The pixels of a rectified left view that came from outside the raw left image, or
    whose match ``x - d`` in the right view did (the bit :data:`OUTSIDE_VIEW`).

    Parameters
    ----------
    disparity : floating (H, W), pixels (non-finite: no match to look at)
    left_inside, right_inside : bool (H, W), :class:`RectifiedPair`'s masks

    Returns
    -------
    numpy.ndarray bool (H, W)

    Examples
    --------
    >>> inside = np.array([[False, True, True, True]])
    >>> outside_view(np.array([[0.0, 0.0, 2.0, 1.0]]), np.ones((1, 4), bool), inside).tolist()
    [[True, False, True, False]]
    """
    disparity = np.asarray(disparity)
    check_rank("disparity", disparity, 2)
    height, width = disparity.shape
    if np.shape(left_inside) != disparity.shape or np.shape(right_inside) != disparity.shape:
        raise ValueError(f"the masks must be {width}x{height} like the disparity")
    columns = np.arange(width)[None, :] - np.where(np.isfinite(disparity), disparity, 0)
    match = np.clip(np.rint(columns), 0, width - 1).astype(np.intp)
    rows = np.arange(height)[:, None]
    return ~np.asarray(left_inside, bool) | ~np.asarray(right_inside, bool)[rows, match]
