"""What the calibration readers share: reading the file, numbers and matrices out of parsed
values, and the final check that names the file and the field.

Every problem is an :class:`~sswjax._files.InputError` of one line naming the file and the
field (the key the format uses).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from sswjax._files import InputError, input_file, reason
from sswjax.api.geometry import StereoCalibration, check_stereo_calibration, checked_array

__all__ = ["checked", "matrix", "read_head", "read_text", "size_of"]


def read_head(path: str | os.PathLike, size: int) -> tuple[Path, bytes]:
    """The checked path of a calibration file and its first ``size`` bytes (to tell its format);
    ``InputError`` as :func:`read_text`."""
    path = input_file(path, "calibration file")
    try:
        with open(path, "rb") as handle:
            return path, handle.read(size)
    except OSError as exc:
        raise InputError(f"cannot read calibration file {path}: {reason(exc)}") from exc


def read_text(path: str | os.PathLike) -> str:
    """The text of a calibration file (UTF-8); ``InputError`` if missing, not a regular file
    (never opened: a FIFO's open would wait) or unreadable."""
    path = input_file(path, "calibration file")
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read calibration file {path}: {reason(exc)}") from exc


def matrix(path: Path, key: str, value, *, shape: tuple[int, ...] | None = None
           ) -> np.ndarray:
    """float64 array of a parsed value (a number, a list, an ``opencv-matrix`` mapping
    ``{rows, cols, dt, data}`` or a ROS ``{rows, cols, data}``), reshaped to ``shape`` when
    given (any shape with as many numbers for vectors: pass ``(n,)``)."""
    if isinstance(value, Mapping):
        if "data" not in value:
            raise InputError(f"calibration file {path}: {key} has no data")
        rows, cols = value.get("rows"), value.get("cols")
        data = matrix(path, key, value["data"])
        if isinstance(rows, (int, float)) and isinstance(cols, (int, float)):
            if data.size != rows * cols:
                raise InputError(f"calibration file {path}: {key} is {rows:g}x{cols:g} but holds "
                                 f"{data.size} numbers")
            data = data.reshape(int(rows), int(cols))
        value = data
    try:
        return checked_array(value, key, shape=shape)
    except ValueError as exc:
        raise InputError(f"calibration file {path}: {exc}") from None


def size_of(path: Path, width_key: str, width, height_key: str, height) -> tuple[int, int]:
    """``(width, height)`` of two parsed numbers; ``InputError`` unless positive integers."""
    values = []
    for key, value in ((width_key, width), (height_key, height)):
        if value is None:
            raise InputError(f"calibration file {path} lacks {key}")
        number = matrix(path, key, value, shape=(1,))[0]
        if not number.is_integer() or number < 1:
            raise InputError(f"calibration file {path}: {key} must be a positive integer, "
                             f"got {number:g}")
        values.append(int(number))
    return values[0], values[1]


def checked(path: Path, calib: StereoCalibration, names: Mapping[str, str]) -> StereoCalibration:
    """:func:`~sswjax.api.geometry.check_stereo_calibration` with the format's key names, its
    ``ValueError`` an ``InputError`` naming ``path``."""
    try:
        return check_stereo_calibration(calib, names=names)
    except ValueError as exc:
        raise InputError(f"calibration file {path}: {exc}") from exc
