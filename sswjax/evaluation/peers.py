"""Reference stereo methods from other projects, run under our protocol (optional dependencies).

Conventions: a peer is a callable ``(left, right, ndisp) -> float32 (H, W)`` taking images as
read from disk (uint8/uint16, gray or colour) and returning a dense disparity map in pixels.
Invalid pixels of a peer are filled like ours (:func:`sswjax.stages.background.fill_background`,
the smaller of the nearest valid disparities on the row), so every method is scored dense.

- ``bm``: OpenCV's ``StereoBM``, block 9 on the luma, uniqueness 10, the same speckle filter
  and left-right check as ``sgbm``.
- ``sgbm`` (and ``sgbm-hh``, its 8-path full-memory mode): OpenCV's ``StereoSGBM`` in 3-way mode (Hirschmuller, "Stereo Processing by
  Semiglobal Matching and Mutual Information", TPAMI 2008), block 3, P1 = 8 * 3 * 3^2,
  P2 = 32 * 3 * 3^2, uniqueness 10, speckle window 100 / range 2, left-right check 1 px.
  Needs ``opencv-python-headless`` (extra ``[bench]``).
- ``pandora``: CNES Pandora 1.9 (Cournet et al., "Ground truth generation and disparity
  estimation for optical satellite imagery", ISPRS Archives 2020) with its libSGM plugin
  (Hirschmuller 2008): census 5x5, SGM P1 8 / P2 32, WTA, vfit, median 3, accurate cross-check.
  Needs ``pandora`` and ``pandora-plugin-libsgm`` (extra ``[pandora]``).
"""

from __future__ import annotations

import copy

import numpy as np

from sswjax.stages.color import rgb_to_gray
from sswjax.stages.background import fill_background


def _to_uint8(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype == np.uint16:
        return (image >> 8).astype(np.uint8)
    if np.issubdtype(image.dtype, np.floating):
        return np.clip(np.round(image * 255), 0, 255).astype(np.uint8)
    return image.astype(np.uint8)


def _opencv():
    try:
        import cv2
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ValueError("OpenCV peers need OpenCV: pip install 'sswjax[bench]'") from error
    return cv2


def _dense(raw: np.ndarray, ndisp: int) -> np.ndarray:
    """OpenCV's fixed-point map (1/16 px, negative = invalid) -> dense float32 in [0, ndisp-1]."""
    raw = raw.astype(np.float32) / 16.0
    filled = np.asarray(fill_background(raw, raw >= 0))
    return np.clip(filled, 0, ndisp - 1).astype(np.float32)


SGBM_MODES = ("3way", "hh", "sgbm")
"""OpenCV StereoSGBM modes: 3-way (4 paths, the default), HH (8 paths, full-size buffers),
SGBM (5 paths)."""


def sgbm_disparity(left: np.ndarray, right: np.ndarray, ndisp: int, *, block_size: int = 3,
                   mode: str = "3way") -> np.ndarray:
    """OpenCV StereoSGBM disparity, invalid pixels filled from the background side.

    Parameters
    ----------
    left, right : (H, W) or (H, W, 3) uint8/uint16/float images
    ndisp : int
        Disparities 0..ndisp-1 (rounded up to a multiple of 16 for OpenCV, then clipped).
    block_size : int, odd
    mode : {"3way", "hh", "sgbm"}
        See :data:`SGBM_MODES`.

    Returns
    -------
    float32 (H, W), dense.
    """
    cv2 = _opencv()
    modes = {"3way": cv2.STEREO_SGBM_MODE_SGBM_3WAY, "hh": cv2.STEREO_SGBM_MODE_HH,
             "sgbm": cv2.STEREO_SGBM_MODE_SGBM}
    if mode not in modes:
        raise ValueError(f"mode must be one of {SGBM_MODES}, got {mode!r}")
    left, right = _to_uint8(left), _to_uint8(right)
    channels = 1 if left.ndim == 2 else 3
    matcher = cv2.StereoSGBM_create(
        minDisparity=0,
        numDisparities=int(np.ceil(ndisp / 16) * 16),
        blockSize=block_size,
        P1=8 * channels * block_size**2,
        P2=32 * channels * block_size**2,
        disp12MaxDiff=1,
        uniquenessRatio=10,
        speckleWindowSize=100,
        speckleRange=2,
        mode=modes[mode],
    )
    return _dense(matcher.compute(left, right), ndisp)


def bm_disparity(left: np.ndarray, right: np.ndarray, ndisp: int, *, block_size: int = 9) -> np.ndarray:
    """OpenCV StereoBM (block matching on the x-Sobel prefiltered gray images), filled like
    :func:`sgbm_disparity`: OpenCV's fastest matcher.

    Parameters
    ----------
    left, right : (H, W) or (H, W, 3) uint8/uint16/float images (colour is converted to luma)
    ndisp : int
        Disparities 0..ndisp-1 (rounded up to a multiple of 16 for OpenCV, then clipped).
    block_size : int, odd, >= 5

    Returns
    -------
    float32 (H, W), dense.
    """
    cv2 = _opencv()
    left, right = (np.clip(_gray_float32(_to_uint8(image)).round(), 0, 255).astype(np.uint8)
                   for image in (left, right))
    matcher = cv2.StereoBM_create(numDisparities=int(np.ceil(ndisp / 16) * 16),
                                  blockSize=block_size)
    matcher.setUniquenessRatio(10)
    matcher.setSpeckleWindowSize(100)
    matcher.setSpeckleRange(2)
    matcher.setDisp12MaxDiff(1)
    return _dense(matcher.compute(left, right), ndisp)


def _gray_float32(image: np.ndarray) -> np.ndarray:
    """Single-band float32 image (BT.601 luma of colour input, at the input's own scale)."""
    image = np.asarray(image, dtype=np.float32)
    if image.ndim == 3:
        image = np.asarray(rgb_to_gray(image))
    return np.ascontiguousarray(image, dtype=np.float32)


def _pandora_image(gray: np.ndarray, disparity: tuple[int, int]):
    """A Pandora input dataset (what ``pandora.create_dataset_from_inputs`` builds from a file)."""
    import xarray as xr
    from pandora.img_tools import add_disparity

    height, width = gray.shape
    dataset = xr.Dataset(
        {"im": (["row", "col"], gray)},
        coords={"row": np.arange(height), "col": np.arange(width)},
        attrs={"no_data_img": -9999, "valid_pixels": 0, "no_data_mask": 1, "crs": None, "transform": None},
    )
    return dataset.pipe(add_disparity, disparity=list(disparity), window=None)


def _pandora_metadata(shape: tuple[int, int], disparity: tuple[int, int]):
    """What ``pandora.img_tools.get_metadata`` returns for a single-band image, for the conf check."""
    import xarray as xr
    from pandora.img_tools import add_disparity

    metadata = xr.Dataset(coords={"band_im": [None], "row": np.arange(shape[0]), "col": np.arange(shape[1])})
    return metadata.pipe(add_disparity, disparity=list(disparity), window=None)


PANDORA_PIPELINE: dict[str, dict] = {
    "matching_cost": {"matching_cost_method": "census", "window_size": 5, "subpix": 1},
    "optimization": {
        "optimization_method": "sgm",
        "sgm_version": "c++",
        "penalty": {"penalty_method": "sgm_penalty", "P1": 8, "P2": 32},
    },
    "disparity": {"disparity_method": "wta", "invalid_disparity": "NaN"},
    "refinement": {"refinement_method": "vfit"},
    "filter": {"filter_method": "median", "filter_size": 3},
    "validation": {"validation_method": "cross_checking_accurate"},
}
"""The Pandora pipeline of :func:`pandora_disparity` (steps run in this order)."""


def pandora_disparity(left: np.ndarray, right: np.ndarray, ndisp: int) -> np.ndarray:
    """CNES Pandora (census + libSGM) disparity, invalid pixels filled from the background side.

    Pandora: Cournet et al., "Ground truth generation and disparity estimation for optical
    satellite imagery", ISPRS Archives XLIII-B2, 2020; its SGM optimisation (libSGM plugin)
    is Hirschmuller, "Stereo Processing by Semiglobal Matching and Mutual Information",
    TPAMI 2008. Pipeline (:data:`PANDORA_PIPELINE`): census 5x5 matching cost, SGM with
    P1 = 8, P2 = 32 (``sgm_penalty``, constant P2), winner-takes-all, V-fit sub-pixel
    refinement, 3x3 median filter, accurate left-right cross-check (threshold 1 px, Pandora's
    default). Pixels Pandora leaves invalid (NaN: image border of the census window,
    occlusions, mismatches) are filled with :func:`sswjax.stages.background.fill_background`.

    Pandora's disparity is ``x_right - x_left`` (negative for a standard rectified pair), so it
    searches ``[-(ndisp - 1), 0]`` and the result is negated to Middlebury's positive convention.

    Parameters
    ----------
    left, right : (H, W) or (H, W, 3) uint8/uint16/float images
        Colour is converted to one band (BT.601 luma), as Pandora's census needs a single band.
    ndisp : int
        Disparities 0..ndisp-1.

    Returns
    -------
    float32 (H, W), dense, in [0, ndisp - 1].

    Raises
    ------
    ValueError
        If Pandora or its libSGM plugin is not installed.
    """
    try:
        import pandora
        from pandora.check_configuration import check_datasets, check_pipeline_section
        from pandora.state_machine import PandoraMachine
        from pandora_plugin_libsgm import lib_sgm  # noqa: F401  (the "sgm" optimization plugin)
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ValueError("method pandora needs CNES Pandora: pip install 'sswjax[pandora]'") from error

    gray_left, gray_right = _gray_float32(left), _gray_float32(right)
    if gray_left.shape != gray_right.shape:
        raise ValueError(f"left and right shapes differ: {gray_left.shape} vs {gray_right.shape}")
    left_range, right_range = (-(int(ndisp) - 1), 0), (0, int(ndisp) - 1)
    image_left = _pandora_image(gray_left, left_range)
    image_right = _pandora_image(gray_right, right_range)
    check_datasets(image_left, image_right)

    pandora.import_plugin()
    machine = PandoraMachine()
    user_cfg = {"pipeline": copy.deepcopy(PANDORA_PIPELINE)}
    cfg = check_pipeline_section(
        user_cfg,
        _pandora_metadata(gray_left.shape, left_range),
        _pandora_metadata(gray_right.shape, right_range),
        machine,
    )
    left_out, _ = pandora.run(machine, image_left, image_right, cfg)

    raw = -np.asarray(left_out["disparity_map"].data, dtype=np.float32)
    valid = np.isfinite(raw)
    if "validity_mask" in left_out:
        from pandora.constants import Criteria

        valid &= (np.asarray(left_out["validity_mask"].data) & int(Criteria.PANDORA_MSK_PIXEL_INVALID)) == 0
    raw = np.where(valid, raw, 0.0).astype(np.float32)
    filled = np.asarray(fill_background(raw, valid))
    return np.clip(filled, 0, ndisp - 1).astype(np.float32)
