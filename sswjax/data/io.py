"""Reading and writing images and disparity maps.

Array conventions
-----------------
* Images are ``(H, W)`` (gray) or ``(H, W, 3)`` (RGB) NumPy arrays, row 0 at the top.
  As read from disk they keep their file dtype (``uint8``, ``uint16`` or floating);
  :func:`sswjax.api.to_float_image` turns them into ``float32`` in ``[0, 1]``.
* Disparity maps are ``float32`` ``(H, W)`` arrays in pixels, row 0 at the top;
  ``inf`` marks unknown/invalid pixels. PFM files store rows bottom-to-top; the reader and
  writer flip them so that callers never see that order.
* Display images produced by :func:`disparity_to_rgb` are ``uint8`` ``(H, W, 3)``.

Every problem with a user-supplied file (missing, unreadable, corrupt, truncated, not
writable) raises :class:`InputError`, a ``ValueError`` with a one-line message naming the file.
All writers are atomic: the output either keeps its old content or gets the complete new one;
with ``atomic=False`` they write the path they are given, a temporary file of
:func:`sswjax._files.atomic_outputs` that writes several outputs all or nothing.
"""

from __future__ import annotations

import os
import struct
import warnings
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from sswjax._checks import check_floating, check_rank
from sswjax._files import (InputError, atomic_output, first_line, input_file, output_file,
                            reason)
from sswjax.data.orientation import apply_orientation, read_stored

__all__ = ["FLOAT_MAP_SUFFIXES", "InputError", "atomic_output", "disparity_to_rgb", "first_line",
           "read_image", "read_oriented", "read_pfm", "write_disparity_png", "write_float_map",
           "write_pfm"]

FLOAT_MAP_SUFFIXES = (".pfm", ".npy", ".tif", ".tiff")
"""The file name endings :func:`write_float_map` writes: PFM, NumPy's ``.npy``, float32 TIFF."""


# ----------------------------------------------------------------------------- images


def _decode_failure(path: Path, exc: BaseException) -> str:
    """A specific one-line reason for an image file that cannot be decoded."""
    text = reason(exc)
    try:
        if path.is_file() and path.stat().st_size == 0:
            return "the file is empty"
    except OSError:
        pass
    if isinstance(exc, OSError) and exc.errno is not None:  # the system's reason, e.g.
        return text  # "Permission denied", "Is a directory" (Pillow's own OSErrors have none)
    if "could not find a backend" in text.lower():
        return "not an image file (unknown format or corrupt header)"
    if isinstance(exc, struct.error) or "truncat" in text.lower():
        return "the file is truncated"
    return f"the file is corrupt ({text})"


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _read_png_16bit_colour(path: Path) -> np.ndarray | None:
    """Full-precision ``uint16`` pixels of a 16-bit colour (or gray+alpha) PNG, else ``None``.

    Pillow decodes such files at 8 bits; OpenCV, when installed, keeps all 16. Returns
    ``None`` for every other file, or when OpenCV is missing or fails.
    """
    try:
        with open(path, "rb") as handle:
            head = handle.read(26)
    except OSError:
        return None
    # IHDR: bytes 24 and 25 are the bit depth and the colour type (2 RGB, 4 gray+alpha, 6 RGBA).
    if len(head) < 26 or head[:8] != _PNG_SIGNATURE or head[12:16] != b"IHDR":
        return None
    if head[24] != 16 or head[25] not in (2, 4, 6):
        return None
    try:
        import cv2
    except ImportError:
        return None
    try:
        decoded = cv2.imdecode(np.fromfile(path, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    except Exception:  # noqa: BLE001 - Pillow already decoded the file; keep its result
        return None
    if decoded is None or decoded.dtype != np.uint16 or decoded.ndim != 3:
        return None
    if head[25] == 4:  # gray+alpha: OpenCV replicates the gray into B, G and R
        return decoded[:, :, 0]
    return decoded[:, :, 2::-1]  # BGR(A) -> RGB


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file (PNG, JPEG, ...) as gray or RGB, upright.

    Alpha channels are dropped (RGBA -> RGB, gray+alpha -> gray); a single channel
    ``(H, W, 1)`` becomes ``(H, W)``; 1-bit images become ``uint8`` 0/255. 16-bit PNGs keep
    16 bits (colour ones need OpenCV, else they are read at 8 bits). The file's EXIF
    orientation is applied (:mod:`sswjax.data.orientation`; :func:`read_oriented` says which).

    Parameters
    ----------
    path : str or os.PathLike
        Image file.

    Returns
    -------
    numpy.ndarray
        ``(H, W)`` or ``(H, W, 3)`` array in the file's dtype (``uint8``, ``uint16``, ...).

    Raises
    ------
    InputError
        If the file is missing, empty, not an image, truncated, corrupt, or not a single
        gray/RGB(A) image.

    Examples
    --------
    >>> left = read_image("Motorcycle/im0.png")  # doctest: +SKIP
    >>> left.shape, left.dtype  # doctest: +SKIP
    ((497, 741, 3), dtype('uint8'))
    """
    return read_oriented(path)[0]


def read_oriented(path: str | os.PathLike) -> tuple[np.ndarray, int]:
    """:func:`read_image`'s upright image and the EXIF orientation it applied (1: none)."""
    path = input_file(path, "image")  # a FIFO is refused, not opened (its open would wait)
    try:
        with warnings.catch_warnings():
            # imageio's search for a plugin that can read an unknown file imports legacy
            # plugins, which warn about their own deprecation: noise for the user.
            warnings.simplefilter("ignore", DeprecationWarning)
            image, orientation = read_stored(path)
    except Exception as exc:  # imageio/Pillow raise many types for corrupt files
        raise InputError(f"cannot read image {path}: {_decode_failure(path, exc)}") from exc
    if image.ndim not in (2, 3) or image.size == 0:
        raise InputError(f"image {path} must be a single gray or RGB(A) image, got array shape {image.shape}")
    wide = _read_png_16bit_colour(path)
    if wide is not None and wide.shape[:2] == image.shape[:2]:
        image = wide
    if image.ndim == 3 and image.shape[2] in (1, 2):
        image = image[:, :, 0]
    elif image.ndim == 3 and image.shape[2] == 4:
        image = image[:, :, :3]
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise InputError(f"image {path} must be gray or RGB(A), got array shape {image.shape}")
    if image.dtype == bool:
        image = image.astype(np.uint8) * np.uint8(255)
    return np.ascontiguousarray(apply_orientation(image, orientation)), orientation


# ----------------------------------------------------------------------------- PFM


def _read_bytes(path: Path, what: str) -> bytes:
    input_file(path, what)
    try:
        return path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {reason(exc)}") from exc


def _pfm_header(data: bytes, path: Path) -> tuple[list[bytes], int]:
    """Split the 4 header tokens off ``data``; return them and the offset of the pixels."""
    tokens: list[bytes] = []
    pos, n = 0, len(data)
    while len(tokens) < 4:
        while pos < n and data[pos : pos + 1].isspace():
            pos += 1
        start = pos
        while pos < n and pos - start <= 64 and not data[pos : pos + 1].isspace():
            pos += 1
        if pos == start or pos - start > 64 or pos >= n:
            raise InputError(f"PFM file {path} has a truncated or malformed header")
        tokens.append(data[start:pos])
    # Exactly one whitespace byte (or CR LF) separates the header from the pixels.
    pos += 2 if data[pos : pos + 2] == b"\r\n" else 1
    return tokens, pos


def read_pfm(path: str | os.PathLike) -> np.ndarray:
    """Read a PFM disparity file (Middlebury conventions).

    Header ``Pf`` (gray) or ``PF`` (colour), then width and height, then a scale whose sign
    gives the byte order (negative: little endian); tokens may be separated by any
    whitespace. Rows are stored bottom-to-top and flipped here. ``inf`` values are kept.

    Parameters
    ----------
    path : str or os.PathLike
        PFM file.

    Returns
    -------
    numpy.ndarray
        ``float32`` ``(H, W)`` for ``Pf`` files, ``(H, W, 3)`` for ``PF`` files.

    Raises
    ------
    InputError
        If the file is missing, unreadable, truncated or has a bad header.

    Examples
    --------
    >>> gt = read_pfm("Motorcycle/disp0GT.pfm")  # doctest: +SKIP
    >>> gt.shape, gt.dtype  # doctest: +SKIP
    ((497, 741), dtype('float32'))
    """
    path = Path(path)
    data = _read_bytes(path, "PFM file")
    tokens, offset = _pfm_header(data, path)
    magic, width, height, scale = tokens
    if magic not in (b"Pf", b"PF"):
        raise InputError(f"PFM file {path} has bad magic {magic[:8]!r}, expected b'Pf' or b'PF'")
    if not (width.isdigit() and height.isdigit() and int(width) > 0 and int(height) > 0):
        raise InputError(f"PFM file {path} has bad size {width[:16]!r} x {height[:16]!r}")
    try:
        scale_value = float(scale.decode("ascii"))
    except (UnicodeDecodeError, ValueError):
        scale_value = float("nan")
    if not np.isfinite(scale_value) or scale_value == 0:
        raise InputError(f"PFM file {path} has bad scale {scale[:16]!r}, expected a nonzero number")
    channels = 3 if magic == b"PF" else 1
    shape = (int(height), int(width)) + ((3,) if channels == 3 else ())
    nbytes = 4 * channels * int(height) * int(width)
    if len(data) - offset < nbytes:
        raise InputError(
            f"PFM file {path} is truncated: {max(len(data) - offset, 0)} of {nbytes} data bytes"
        )
    dtype = "<f4" if scale_value < 0 else ">f4"
    pixels = np.frombuffer(data, dtype=dtype, count=nbytes // 4, offset=offset).reshape(shape)
    return np.ascontiguousarray(pixels[::-1], dtype=np.float32)


def write_pfm(path: str | os.PathLike, array: np.ndarray, *, atomic: bool = True) -> None:
    """Atomically write a PFM file (little endian, rows bottom-to-top).

    Parameters
    ----------
    path : str or os.PathLike
        Output file; replaced only once the new content is complete.
    array : numpy.ndarray
        Floating ``(H, W)`` (written as ``Pf``) or ``(H, W, 3)`` (written as ``PF``); stored
        as ``float32``. ``inf`` is allowed.
    atomic : bool
        False: write ``path`` itself (a temporary file already).

    Raises
    ------
    ValueError, TypeError
        On a bad shape or a non-floating dtype.
    InputError
        If the file cannot be written.

    Examples
    --------
    >>> write_pfm("disp0.pfm", np.zeros((4, 6), np.float32))  # doctest: +SKIP
    """
    array = np.asarray(array)
    check_rank("array", array, (2, 3))
    check_floating("array", array)
    if array.ndim == 3 and array.shape[2] != 3:
        raise ValueError(f"array must be (H, W) or (H, W, 3), got shape {array.shape}")
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise ValueError(f"array must not be empty, got shape {array.shape}")
    height, width = array.shape[:2]
    magic = "PF" if array.ndim == 3 else "Pf"
    with np.errstate(over="ignore"):
        body = np.ascontiguousarray(array[::-1], dtype="<f4").tobytes()
    with output_file(path, atomic=atomic) as tmp, open(tmp, "wb") as f:
        f.write(f"{magic}\n{width} {height}\n-1.0\n".encode("ascii"))
        f.write(body)


def write_float_map(path: str | os.PathLike, array: np.ndarray, *, suffix: str | None = None,
                    atomic: bool = True) -> None:
    """Atomically write a floating map in the format its name ends with: ``.pfm``
    (:func:`write_pfm`), ``.npy`` (``np.save`` of the float32 array) or ``.tif`` / ``.tiff``
    (float32 TIFF); ``suffix`` overrides the name's (for a temporary file).

    ``array`` is floating ``(H, W)`` or ``(H, W, 3)``, stored as float32 (``inf`` allowed);
    ``atomic=False`` writes ``path`` itself (a temporary file already). Raises ``ValueError``
    for another ending or a bad shape (``TypeError``: dtype), :class:`InputError` if the file
    cannot be written.

    Examples
    --------
    >>> write_float_map("depth.npy", np.zeros((4, 6), np.float32))  # doctest: +SKIP
    """
    suffix = (Path(path).suffix if suffix is None else suffix).lower()
    if suffix not in FLOAT_MAP_SUFFIXES:
        raise ValueError(f"cannot write {path}: a map is written as "
                         f"{', '.join(FLOAT_MAP_SUFFIXES)}, not {suffix or 'without extension'}")
    if suffix == ".pfm":
        return write_pfm(path, array, atomic=atomic)
    array = np.asarray(array)
    check_rank("array", array, (2, 3))
    check_floating("array", array)
    with np.errstate(over="ignore"):
        array = np.ascontiguousarray(array, dtype=np.float32)
    with output_file(path, atomic=atomic) as tmp:
        if suffix == ".npy":
            with open(tmp, "wb") as f:  # a file object: np.save would add .npy to a name
                np.save(f, array)
        else:
            iio.imwrite(tmp, array, extension=suffix)


# ----------------------------------------------------------------------------- display

# Anchor colours (RGB in [0, 1]) at evenly spaced positions: dark blue -> blue -> cyan ->
# yellow -> red. Lightness rises monotonically up to yellow, so near/far reads at a glance.
_COLOUR_ANCHORS = np.array([[0.08, 0.04, 0.40], [0.10, 0.35, 0.85], [0.15, 0.80, 0.85],
                            [0.98, 0.90, 0.20], [0.85, 0.12, 0.08]])


def disparity_to_rgb(
    disparity: np.ndarray, *, vmin: float | None = None, vmax: float | None = None
) -> np.ndarray:
    """Colour a disparity map for display.

    Values are normalised to ``[0, 1]`` by ``vmin``/``vmax`` (clipped outside) and mapped
    through a dark-blue/cyan/yellow/red colour map; non-finite pixels are black.

    Parameters
    ----------
    disparity : numpy.ndarray
        Floating ``(H, W)`` disparity map.
    vmin, vmax : float, optional
        Range mapped to the ends of the colour map; defaults to the finite min/max.

    Returns
    -------
    numpy.ndarray
        ``uint8`` ``(H, W, 3)`` RGB image.

    Raises
    ------
    ValueError, TypeError
        On a bad shape or dtype, or non-finite / inverted ``vmin``/``vmax``.

    Examples
    --------
    >>> disparity_to_rgb(np.array([[0.0, 1.0, np.inf]], np.float32))[0, 2]
    array([0, 0, 0], dtype=uint8)
    """
    disparity = np.asarray(disparity)
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    finite = np.isfinite(disparity)
    values = disparity[finite].astype(np.float64)
    lo = float(vmin) if vmin is not None else (float(values.min()) if values.size else 0.0)
    hi = float(vmax) if vmax is not None else (float(values.max()) if values.size else lo)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ValueError(f"vmin and vmax must be finite, got {lo} and {hi}")
    if vmin is not None and vmax is not None and lo >= hi:
        raise ValueError(f"vmin must be < vmax, got {lo} and {hi}")
    t = np.zeros(disparity.shape)
    if hi > lo:
        t[finite] = np.clip((values - lo) / (hi - lo), 0.0, 1.0)
    positions = np.linspace(0.0, 1.0, len(_COLOUR_ANCHORS))
    rgb = np.stack([np.interp(t, positions, _COLOUR_ANCHORS[:, c]) for c in range(3)], axis=-1)
    rgb[~finite] = 0.0
    return np.round(rgb * 255).astype(np.uint8)


def write_disparity_png(path: str | os.PathLike, disparity: np.ndarray, *,
                        vmin: float | None = None, vmax: float | None = None,
                        atomic: bool = True) -> None:
    """Atomically write a colour-mapped disparity map as a PNG file (``atomic=False``: write
    ``path`` itself, a temporary file already).

    Parameters
    ----------
    path : str or os.PathLike
        Output PNG file; replaced only once the new content is complete.
    disparity : numpy.ndarray
        Floating ``(H, W)`` disparity map.
    vmin, vmax : float, optional
        Colour range, see :func:`disparity_to_rgb`.

    Raises
    ------
    InputError
        If the file cannot be written.

    Examples
    --------
    >>> write_disparity_png("disp0.png", np.zeros((4, 6), np.float32))  # doctest: +SKIP
    """
    rgb = disparity_to_rgb(disparity, vmin=vmin, vmax=vmax)
    with output_file(path, atomic=atomic) as tmp:
        iio.imwrite(tmp, rgb, extension=".png")
