"""The EXIF orientation of an image file: how its stored pixels are turned to stand upright.

Cameras and phones often store a photo as the sensor saw it and record in the EXIF tag
``Orientation`` (0x0112, values 1 to 8) how to turn it for display. A pair read as stored
would be matched sideways (a portrait pair's rows are then its columns), so
:func:`sswjax.data.io.read_image` applies the tag: every image it returns stands upright.
The tag is read where JPEG, PNG (an ``eXIf`` chunk before the pixels), WebP and TIFF files
keep it; values outside 1..8 are ignored, as image viewers ignore them.

Array conventions: images are ``(H, W)`` or ``(H, W, C)`` NumPy arrays, row 0 at the top.
"""

from __future__ import annotations

import os
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from imageio.plugins.pillow import PillowPlugin
from PIL import Image

from sswjax._files import InputError

__all__ = ["ORIENTATIONS", "TAG", "apply_orientation", "orientation_words", "read_stored",
           "upright_pair", "upright_size"]

TAG = 0x0112
"""The EXIF tag ``Orientation``."""

ORIENTATIONS = {
    1: "upright",
    2: "mirrored left to right",
    3: "rotated 180°",
    4: "mirrored top to bottom",
    5: "mirrored left to right, then rotated 90° counter-clockwise",
    6: "rotated 90° clockwise",
    7: "mirrored left to right, then rotated 90° clockwise",
    8: "rotated 90° counter-clockwise",
}
"""What each orientation does to the stored pixels to stand them upright."""

_TIFF_WIDTH, _TIFF_LENGTH = 256, 257


def orientation_words(orientation: int) -> str:
    """The orientation as the notes and errors say it.

    Examples
    --------
    >>> orientation_words(6)
    '6: rotated 90° clockwise'
    """
    return f"{orientation}: {ORIENTATIONS[orientation]}"


def _valid(value) -> int:
    """``value`` if it is an orientation 1..8, else 1 (no turn)."""
    return value if isinstance(value, int) and value in ORIENTATIONS else 1


def apply_orientation(image: np.ndarray, orientation: int) -> np.ndarray:
    """The stored pixels ``image`` (``(H, W)`` or ``(H, W, C)``) turned upright as EXIF
    ``orientation`` (1..8) says: ``(W, H[, C])`` for 5 to 8. A view where NumPy can give one.

    Examples
    --------
    >>> apply_orientation(np.array([[1, 2, 3]]), 6)
    array([[1],
           [2],
           [3]])
    """
    if orientation not in ORIENTATIONS:
        raise ValueError(f"orientation must be an integer in 1..8, got {orientation!r}")
    if orientation in (2, 7):
        image = image[:, ::-1]  # 7: mirrored, then turned as 6
    if orientation == 3:
        image = image[::-1, ::-1]
    elif orientation == 4:
        image = image[::-1]
    elif orientation == 5:
        image = image.swapaxes(0, 1)
    elif orientation in (6, 7):
        image = np.rot90(image, k=-1)
    elif orientation == 8:
        image = np.rot90(image, k=1)
    return image


def _header_orientation(image: Image.Image) -> int:
    """The orientation in the header of a Pillow image not yet decoded (1 without one).
    A PNG's tag is taken only from an ``eXIf`` chunk before the pixels: asking Pillow for a
    later one would decode the whole file."""
    if image.format == "PNG" and "exif" not in image.info:
        return 1
    return _valid(image.getexif().get(TAG))


def upright_size(image: Image.Image) -> tuple[int, int]:
    """``(height, width)`` of a Pillow image opened and not decoded, once its orientation is
    applied: the size :func:`sswjax.data.io.read_image` returns, from the header only."""
    width, height = image.size
    tags = getattr(image, "tag_v2", None)
    if image.format == "TIFF" and tags is not None and _TIFF_WIDTH in tags and _TIFF_LENGTH in tags:
        width, height = tags[_TIFF_WIDTH], tags[_TIFF_LENGTH]  # as stored (Pillow's size turns)
    if _header_orientation(image) in (5, 6, 7, 8):
        return width, height
    return height, width


def _file_orientation(path: Path) -> int:
    """The orientation in the header of the file at ``path``, for readers that keep the
    stored pixels (TIFF's); 1 when no reader finds one."""
    try:
        with Image.open(path) as image:
            return _header_orientation(image)
    except Exception:  # noqa: BLE001 - Pillow cannot open every TIFF: ask tifffile
        pass
    try:
        import tifffile

        with tifffile.TiffFile(path) as tiff:
            tag = tiff.pages[0].tags.get(TAG)
            return 1 if tag is None else _valid(int(tag.value))
    except Exception:  # noqa: BLE001 - not a TIFF, or no tifffile: nothing says to turn it
        return 1


def read_stored(path: str | os.PathLike) -> tuple[np.ndarray, int]:
    """The pixels of an image file as imageio decodes them, and the orientation that is still
    to be applied to them (1: none).

    Pillow applies a TIFF's tag itself and drops it, and keeps the others' tags; other
    readers (tifffile) give the stored pixels and the tag is read from the header. Raises what
    the readers raise (:mod:`sswjax.data.io` makes it one line).
    """
    with iio.imopen(path, "r", legacy_mode=False) as file:
        pixels = np.asarray(file.read())
        if isinstance(file, PillowPlugin):
            return pixels, _valid(file.metadata(exclude_applied=False).get("Orientation"))
    return pixels, _file_orientation(Path(path))


def upright_pair(left: tuple[np.ndarray, int], right: tuple[np.ndarray, int], *,
                 names: tuple[str, str] = ("LEFT", "RIGHT")
                 ) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Two images as :func:`sswjax.data.io.read_oriented` returns them (upright image,
    orientation applied), refused unless they have one size; with a note for each image that
    was turned.

    Parameters
    ----------
    left, right : (numpy.ndarray (H, W) or (H, W, C), int)
    names : (str, str)
        How the notes and the error call the two images.

    Returns
    -------
    (left image, right image, notes): the images as given; one line per turned image, e.g.
    ``"LEFT: applied its EXIF orientation (6: rotated 90° clockwise)"``.

    Raises
    ------
    InputError
        If the two sizes differ (one line; it names the orientations applied, if any).
    """
    turned = [(name, orientation) for name, (_, orientation) in zip(names, (left, right))
              if orientation != 1]
    (left, _), (right, _) = left, right
    if left.shape[:2] != right.shape[:2]:
        message = (f"left and right images differ in size: {left.shape[1]}x{left.shape[0]} and "
                   f"{right.shape[1]}x{right.shape[0]}")
        if len(turned) == 1:
            message += (f" once {turned[0][0]}'s EXIF orientation "
                        f"({orientation_words(turned[0][1])}) is applied")
        elif turned:
            message += (f" once the EXIF orientations of {names[0]} ({orientation_words(turned[0][1])})"
                        f" and {names[1]} ({orientation_words(turned[1][1])}) are applied")
        raise InputError(message)
    notes = tuple(f"{name}: applied its EXIF orientation ({orientation_words(orientation)})"
                  for name, orientation in turned)
    return left, right, notes
