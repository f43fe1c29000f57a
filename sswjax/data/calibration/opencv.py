"""OpenCV stereo calibrations: ``cv2.FileStorage`` YAML and XML, and NumPy ``.npz`` files.

The keys are those of ``cv2.stereoCalibrate`` as the common calibration scripts save them:
``K1 D1 K2 D2 R T`` (``M1``/``M2`` as OpenCV's ``stereo_calib.cpp`` sample writes, or
``cameraMatrix1``/``distCoeffs1``... as the function names them), optionally ``R1 R2 P1 P2 Q``
of ``cv2.stereoRectify`` (all four of ``R1 R2 P1 P2``, or none), and the image size as
``image_width`` and ``image_height``, ``imageSize`` or ``image_size`` (``[width, height]``).
The sample's two files (intrinsics and extrinsics) are read together.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from sswjax._files import InputError, input_file, reason
from sswjax.api.geometry import Rectification, StereoCalibration
from sswjax.data.calibration.common import checked, matrix, read_head, size_of
from sswjax.data.calibration.filestorage import read_filestorage

__all__ = ["KEYS", "read_npz", "read_opencv_calibration"]

KEYS = {"left_matrix": ("K1", "M1", "cameraMatrix1"), "left_distortion": ("D1", "distCoeffs1"),
        "right_matrix": ("K2", "M2", "cameraMatrix2"), "right_distortion": ("D2", "distCoeffs2"),
        "rotation": ("R",), "translation": ("T",)}
"""Field of :class:`~sswjax.api.geometry.StereoCalibration` -> the keys read for it, in order."""

_WHAT = {"left_matrix": "the left camera matrix", "left_distortion": "the left distortion",
         "right_matrix": "the right camera matrix", "right_distortion": "the right distortion",
         "rotation": "the rotation to the right camera", "translation": "its translation"}

_RECTIFICATION = ("R1", "R2", "P1", "P2")


def read_npz(path: str | os.PathLike) -> dict:
    """The arrays of a ``.npz`` file by name (no pickles); ``InputError`` if unreadable."""
    path = input_file(path, "calibration file")
    try:
        with np.load(path, allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"cannot read calibration file {path}: {reason(exc)}") from exc


def _read(path: Path) -> dict:
    path, magic = read_head(path, 4)
    if magic.startswith(b"PK") or path.suffix.lower() == ".npz":
        return read_npz(path)
    return read_filestorage(path)


def _size(path: Path, keys: dict) -> tuple[int, int] | None:
    for width, height in (("image_width", "image_height"), ("width", "height")):
        if width in keys or height in keys:
            return size_of(path, width, keys.get(width), height, keys.get(height))
    for key in ("imageSize", "image_size"):
        if key in keys:
            width, height = matrix(path, key, keys[key], shape=(2,))
            return size_of(path, f"{key}[0]", width, f"{key}[1]", height)
    return None


def read_opencv_calibration(path: str | os.PathLike, *,
                            extrinsics: str | os.PathLike | None = None) -> StereoCalibration:
    """A stereo calibration of OpenCV's (module docstring) from YAML, XML or ``.npz``.

    Parameters
    ----------
    path : str or os.PathLike
        FileStorage YAML (``%YAML:1.0``) or XML (``<opencv_storage>``), told from the text,
        or ``.npz`` (``np.savez(path, K1=..., D1=..., ...)``).
    extrinsics : str or os.PathLike, optional
        A second file whose keys join the first's (``stereo_calib.cpp``'s ``extrinsics.yml``
        beside its ``intrinsics.yml``).

    Returns
    -------
    StereoCalibration
        With the rectification when the file has ``R1 R2 P1 P2`` (and ``Q``).

    Raises
    ------
    InputError
        One line naming the file and the key: missing or unreadable file, a missing key, a
        wrong shape, non-finite values, a singular camera matrix, a rotation that is not one,
        a bad image size, half a rectification.

    Examples
    --------
    >>> read_opencv_calibration("stereo.yaml").image_size  # doctest: +SKIP
    (640, 480)
    """
    path = Path(path)
    keys = _read(path)
    where = str(path)
    if extrinsics is not None:
        keys = {**keys, **_read(Path(extrinsics))}
        where = f"{path} and {extrinsics}"
    values, names = {}, {}
    for field, aliases in KEYS.items():
        key = next((alias for alias in aliases if alias in keys), None)
        if key is None:
            also = f"; also read as {' or '.join(aliases[1:])}" if len(aliases) > 1 else ""
            raise InputError(f"calibration file {where} lacks {aliases[0]} ({_WHAT[field]}{also})")
        shape = (3,) if field == "translation" else None
        value = matrix(Path(where), key, keys[key], shape=shape)
        values[field] = value.reshape(-1) if field.endswith("distortion") else value
        names[field] = key
    present = [key for key in _RECTIFICATION if key in keys]
    rectification = None
    if present:
        missing = [key for key in _RECTIFICATION if key not in keys]
        if missing:
            raise InputError(f"calibration file {where} has {' '.join(present)} but lacks "
                             f"{' '.join(missing)}: give all of R1 R2 P1 P2 or none")
        r1, r2, p1, p2 = (matrix(Path(where), key, keys[key]) for key in _RECTIFICATION)
        q = matrix(Path(where), "Q", keys["Q"]) if "Q" in keys else None
        rectification = Rectification(r1, r2, p1, p2, q, None)
    size = _size(Path(where), keys)
    if rectification is not None:
        rectification = rectification._replace(size=size)
    return checked(Path(where), StereoCalibration(**values, image_size=size,
                                                  rectification=rectification), names)
