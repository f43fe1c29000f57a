"""The user's images at the front door: checked and converted to what the graph takes.

Array conventions (whole module): user images are NumPy-like ``(H, W)`` or ``(H, W, 1|3|4)``
arrays of uint8, uint16 or floats in [0, 1]; they are converted to float32 ``(H, W, C)`` in
[0, 1], C in {1, 3}, for :mod:`sswjax.graph`.
"""

from __future__ import annotations

import os

import numpy as np

from sswjax.config import Params
from sswjax.stages.color import rgb_to_gray

__all__ = ["check_image_size", "checked_images", "checked_pair", "prepare_pair",
           "to_float_image"]


def to_float_image(image, *, name: str = "image") -> np.ndarray:
    """The one conversion of a user's image to the pipeline's float32 ``(H, W, C)`` in [0, 1].

    Parameters
    ----------
    image : array (H, W) or (H, W, 1|3|4)
        A NumPy or JAX array: uint8 (divided by 255), uint16 (divided by 65535) or floating
        (used as given: values in [0, 1], finite in float32). Alpha is dropped.
    name : str
        How error messages call the image (``"left"``, ``"right"``).

    Returns
    -------
    numpy.ndarray float32 (H, W, C), C in {1, 3} (a new array)

    Raises
    ------
    ValueError
        On a path or a list instead of an array, a bad shape, an empty image, another dtype
        (bool, int32, ...), non-finite values, values beyond float32, or floats outside
        [0, 1] (such as 0-255 values in a float array, or a disparity map).

    Examples
    --------
    >>> to_float_image(np.array([[0, 255]], dtype=np.uint8))[..., 0]
    array([[0., 1.]], dtype=float32)
    """
    if isinstance(image, (str, os.PathLike)):
        raise ValueError(f"{name} image is a path ({os.fspath(image)!r}), not an array: read it "
                         "first, e.g. sswjax.data.io.read_image(path)")
    if not hasattr(image, "shape") or not hasattr(image, "dtype"):
        raise ValueError(f"{name} image must be a NumPy or JAX array, got "
                         f"{type(image).__name__}")
    image = np.asarray(image)
    if image.ndim == 2:
        image = image[..., None]
    if image.ndim != 3 or image.shape[-1] not in (1, 3, 4):
        raise ValueError(f"{name} image must be HxW, HxWx1, HxWx3 or HxWx4, got shape {image.shape}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"{name} image is empty, got shape {image.shape}")
    image = image[..., :3]
    if image.dtype == np.uint8:
        return image.astype(np.float32) / np.float32(255)
    if image.dtype == np.uint16:
        return image.astype(np.float32) / np.float32(65535)
    if not np.issubdtype(image.dtype, np.floating):
        raise ValueError(f"{name} image must be uint8, uint16 or float, got {image.dtype}")
    if not np.isfinite(image).all():
        raise ValueError(f"{name} image contains NaN or infinite values")
    with np.errstate(over="ignore", invalid="ignore"):
        single = image.astype(np.float32)
    if not np.isfinite(single).all():
        raise ValueError(f"{name} image has values beyond float32's range (largest magnitude "
                         f"{float(np.abs(image).max()):.3g})")
    low, high = float(single.min()), float(single.max())
    if low < 0 or high > 1:
        raise ValueError(f"{name} image is floating with values in [{low:.4g}, {high:.4g}]: "
                         "floating images must be in [0, 1] (divide 8-bit values by 255; a "
                         "disparity map is not an image)")
    return single


def prepare_pair(left, right) -> tuple[np.ndarray, np.ndarray]:
    """Validate a user's pair and convert it to float32 ``(H, W, C)`` in [0, 1].

    Each image goes through :func:`to_float_image`. If one image is gray and the other colour,
    both are used as gray (BT.601 luma of the colour one).

    Returns
    -------
    (float32 (H, W, C), float32 (H, W, C)) with C in {1, 3}
    """
    left, right = to_float_image(left, name="left"), to_float_image(right, name="right")
    if left.shape[:2] != right.shape[:2]:
        raise ValueError(
            f"left and right images differ in size: {left.shape[1]}x{left.shape[0]} "
            f"and {right.shape[1]}x{right.shape[0]}"
        )
    if left.shape[-1] != right.shape[-1]:
        left, right = (
            np.asarray(rgb_to_gray(im))[..., None] if im.shape[-1] == 3 else im
            for im in (left, right)
        )
    return left, right


def check_image_size(width: int, height: int, params: Params, *, where: str = "") -> None:
    """Refuse images of ``width`` x ``height`` pixels smaller than the census window of
    ``params``: the first check on a pair's size, before its range (an image 1 pixel wide
    leaves no disparity to search, and this says why) and before any memory estimate.

    ``where`` starts the message (e.g. ``"pair a.png: "``).

    Raises
    ------
    ValueError
        With a one-line message.

    Examples
    --------
    >>> from sswjax.config import default_params
    >>> check_image_size(1, 24, default_params())
    Traceback (most recent call last):
    ...
    ValueError: images of 1x24 are smaller than the census window 9x7: both sides must be at least 9 pixels
    """
    census = (params.cost.census_width, params.cost.census_height)
    if min(width, height) < max(census):
        raise ValueError(
            f"{where}images of {width}x{height} are smaller than the census window "
            f"{census[0]}x{census[1]}: both sides must be at least {max(census)} pixels"
        )


def checked_images(left, right, params: Params) -> tuple[np.ndarray, np.ndarray]:
    """:func:`prepare_pair` and :func:`check_image_size`: the checks of a pair that need no
    range (those made before :func:`sswjax.api.auto_range.estimate_range` looks for one).

    Returns
    -------
    (float32 (H, W, C), float32 (H, W, C)) with C in {1, 3}
    """
    left, right = prepare_pair(left, right)
    check_image_size(left.shape[1], left.shape[0], params)
    return left, right


def checked_pair(left, right, ndisp, params: Params) -> tuple[np.ndarray, np.ndarray]:
    """:func:`checked_images` plus the checks of :func:`match` on ``ndisp``: the size is
    checked first, so that an image too small for the census window is refused as such, not
    with an empty range ``[1, 0]``.

    Returns
    -------
    (float32 (H, W, C), float32 (H, W, C)) with C in {1, 3}
    """
    if isinstance(ndisp, bool) or not isinstance(ndisp, (int, np.integer)):
        raise ValueError(f"ndisp must be an integer, got {ndisp!r}")
    left, right = checked_images(left, right, params)
    if not 1 <= ndisp < left.shape[1]:
        raise ValueError(f"ndisp must be in [1, {left.shape[1] - 1}] for this width, got {ndisp}")
    return left, right
