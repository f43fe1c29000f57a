"""Reference stereo methods from other projects, run under our protocol (optional dependencies).

Conventions: a peer is a callable ``(left, right, ndisp) -> float32 (H, W)`` taking images as
read from disk (uint8/uint16, gray or colour) and returning a dense disparity map in pixels.
Invalid pixels of a peer are filled like ours (:func:`sswjax.refinement.fill_background`, the
smaller of the nearest valid disparities on the row), so every method is scored dense.

- ``sgbm``: OpenCV's ``StereoSGBM`` in 3-way mode (Hirschmuller, "Stereo Processing by
  Semiglobal Matching and Mutual Information", TPAMI 2008), block 3, P1 = 8 * 3 * 3^2,
  P2 = 32 * 3 * 3^2, uniqueness 10, speckle window 100 / range 2, left-right check 1 px.
  Needs ``opencv-python-headless`` (extra ``[bench]``).
"""

from __future__ import annotations

import numpy as np

from sswjax.refinement import fill_background


def _to_uint8(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype == np.uint16:
        return (image >> 8).astype(np.uint8)
    if np.issubdtype(image.dtype, np.floating):
        return np.clip(np.round(image * 255), 0, 255).astype(np.uint8)
    return image.astype(np.uint8)


def sgbm_disparity(left: np.ndarray, right: np.ndarray, ndisp: int, *, block_size: int = 3) -> np.ndarray:
    """OpenCV StereoSGBM (3-way) disparity, invalid pixels filled from the background side.

    Parameters
    ----------
    left, right : (H, W) or (H, W, 3) uint8/uint16/float images
    ndisp : int
        Disparities 0..ndisp-1 (rounded up to a multiple of 16 for OpenCV, then clipped).
    block_size : int, odd

    Returns
    -------
    float32 (H, W), dense.
    """
    try:
        import cv2
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ValueError("method sgbm needs OpenCV: pip install 'sswjax[bench]'") from error
    left, right = _to_uint8(left), _to_uint8(right)
    channels = 1 if left.ndim == 2 else 3
    num = int(np.ceil(ndisp / 16) * 16)
    matcher = cv2.StereoSGBM_create(
        minDisparity=0,
        numDisparities=num,
        blockSize=block_size,
        P1=8 * channels * block_size**2,
        P2=32 * channels * block_size**2,
        disp12MaxDiff=1,
        uniquenessRatio=10,
        speckleWindowSize=100,
        speckleRange=2,
        mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
    )
    raw = matcher.compute(left, right).astype(np.float32) / 16.0
    valid = raw >= 0
    filled = np.asarray(fill_background(raw, valid))
    return np.clip(filled, 0, ndisp - 1).astype(np.float32)
