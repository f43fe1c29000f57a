"""Integer disparity images that store ``round(disparity * scale)`` with 0 = unknown.

KITTI's 16-bit PNGs use scale 256; Middlebury 2001 ``disp2.pgm`` 8, 2003 4, 2005/2006
``disp1.png`` 1, 2 or 3 (full, half, third size). Disparities are ``float32`` ``(H, W)`` in
pixels, ``inf`` = unknown, row 0 at the top.
"""

from __future__ import annotations

import os

import imageio.v3 as iio
import numpy as np

from sswjax._checks import check_floating, check_rank
from sswjax._files import InputError, output_file
from sswjax.data.io import read_image

__all__ = ["read_scaled_disparity", "write_scaled_disparity"]


def read_scaled_disparity(path: str | os.PathLike, *, scale: float) -> np.ndarray:
    """Read an integer disparity image that stores ``disparity * scale`` with 0 = unknown.

    Parameters
    ----------
    path : str or os.PathLike
        Gray ``uint8`` or ``uint16`` image (PNG, PGM, ...).
    scale : float
        File value per pixel of disparity (256 for KITTI, 8 for Middlebury 2001, ...).

    Returns
    -------
    numpy.ndarray
        ``float32`` ``(H, W)`` disparity in pixels, ``inf`` where the file holds 0.

    Raises
    ------
    InputError
        If the file is missing or unreadable, or not a gray integer image.

    Examples
    --------
    >>> gt = read_scaled_disparity("training/disp_noc/000100_10.png", scale=256)  # doctest: +SKIP
    >>> gt.dtype  # doctest: +SKIP
    dtype('float32')
    """
    image = read_image(path)
    if image.ndim != 2 or image.dtype not in (np.uint8, np.uint16):
        raise InputError(f"disparity image {path} must be 8- or 16-bit gray, got {image.dtype} "
                         f"{image.shape}")
    disparity = image.astype(np.float32) / np.float32(scale)
    disparity[image == 0] = np.inf
    return disparity


def write_scaled_disparity(path: str | os.PathLike, disparity, *, scale: float = 256.0,
                           atomic: bool = True) -> None:
    """Atomically write a 16-bit PNG of ``round(disparity * scale)``, 0 = invalid (KITTI's format).

    The inverse of :func:`read_scaled_disparity` up to the rounding (``1 / (2 * scale)`` px).

    Parameters
    ----------
    path : str or os.PathLike
        Output PNG file.
    disparity : array_like floating (H, W)
        Pixels. Invalid, written as 0: non-finite, ``<= 0``, rounding to 0, or beyond
        ``65535 / scale`` (255.996 px for KITTI).
    scale : float > 0
        File value per pixel of disparity (256 for KITTI).
    atomic : bool
        False: write ``path`` itself (a temporary file already).

    Raises
    ------
    ValueError, TypeError
        On a bad shape, dtype or scale.
    InputError
        If the file cannot be written.

    Examples
    --------
    >>> write_scaled_disparity("000000_10.png", np.full((2, 3), 4.5, np.float32))  # doctest: +SKIP
    """
    disparity = np.asarray(disparity)
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    if isinstance(scale, bool) or not (isinstance(scale, (int, float)) and 0 < scale < np.inf):
        raise ValueError(f"scale must be a finite number > 0, got {scale!r}")
    with np.errstate(invalid="ignore", over="ignore"):
        scaled = np.round(disparity.astype(np.float64) * scale)
    valid = np.isfinite(scaled) & (disparity > 0) & (scaled <= np.iinfo(np.uint16).max)
    values = np.where(valid, scaled, 0).astype(np.uint16)
    with output_file(path, atomic=atomic) as tmp:
        iio.imwrite(tmp, values, extension=".png")
