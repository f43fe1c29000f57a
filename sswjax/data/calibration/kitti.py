"""KITTI's ``calib_cam_to_cam.txt``: the four cameras of the raw recordings.

Lines ``KEY: numbers``; for each camera ``xx`` (``00``, ``01`` gray, ``02``, ``03`` colour):
``S_xx`` (raw image size), ``K_xx``, ``D_xx`` (5 coefficients), ``R_xx`` and ``T_xx`` (the pose
of camera ``xx`` relative to camera ``00``: ``x_xx = R_xx x_00 + T_xx``, metres), and the
rectification KITTI computed, ``S_rect_xx``, ``R_rect_xx`` (the camera's rectifying rotation)
and ``P_rect_xx`` (3x4). A pair ``(a, b)`` gives ``R = R_b R_a^T`` and ``T = T_b - R T_a``.
Its images are the raw ones (``S_xx``); KITTI's rectified images (``image_0x`` of the stereo
benchmark, ``S_rect_xx``) are the rig of :func:`sswjax.api.rectify.as_rectified`.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from sswjax._files import InputError
from sswjax.api.geometry import Rectification, StereoCalibration
from sswjax.data.calibration.common import checked, matrix, read_text, size_of

__all__ = ["CAMERAS", "COLOUR", "GRAY", "read_kitti_calibration", "read_kitti_keys"]

CAMERAS = ("00", "01", "02", "03")
GRAY = ("00", "01")
"""The gray pair (KITTI's ``image_00``, ``image_01``), the default."""
COLOUR = ("02", "03")
"""The colour pair (``image_02``, ``image_03``)."""

_SHAPES = {"S": (2,), "K": (3, 3), "D": (5,), "R": (3, 3), "T": (3,), "S_rect": (2,),
           "R_rect": (3, 3), "P_rect": (3, 4)}


def read_kitti_keys(path: str | os.PathLike) -> dict[str, list[str]]:
    """Key -> its words, for each ``KEY: ...`` line of a ``calib_cam_to_cam.txt`` (a key given
    twice is refused, naming both lines)."""
    path = Path(path)
    keys, lines = {}, {}
    for number, line in enumerate(read_text(path).splitlines(), start=1):
        if not line.strip():
            continue
        key, sep, rest = line.partition(":")
        if not sep or not key.strip() or " " in key.strip():
            raise InputError(f"calibration file {path} line {number} is not KEY: values: "
                             f"{line.strip()[:40]!r}")
        key = key.strip()
        if key in lines:
            raise InputError(f"calibration file {path} line {number}: {key} given twice "
                             f"(lines {lines[key]} and {number})")
        keys[key], lines[key] = rest.split(), number
    return keys


def _camera(path: Path, keys: dict, camera: str) -> dict:
    values = {}
    for name, shape in _SHAPES.items():
        key = f"{name}_{camera}"
        if key not in keys:
            raise InputError(f"calibration file {path} lacks {key} (camera {camera})")
        try:
            numbers = [float(word) for word in keys[key]]
        except ValueError:
            raise InputError(f"calibration file {path}: {key} must be numbers, got "
                             f"{' '.join(keys[key])[:40]!r}") from None
        if len(numbers) != int(np.prod(shape)):
            raise InputError(f"calibration file {path}: {key} must hold {int(np.prod(shape))} "
                             f"numbers, got {len(numbers)}")
        values[name] = matrix(path, key, np.reshape(numbers, shape))
    for name in ("S", "S_rect"):
        key = f"{name}_{camera}"
        values[name] = size_of(path, f"{key}[0]", values[name][0], f"{key}[1]", values[name][1])
    return values


def read_kitti_calibration(path: str | os.PathLike, *, cameras: tuple[str, str] = GRAY
                           ) -> StereoCalibration:
    """The raw rig of two of KITTI's cameras (module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        ``calib_cam_to_cam.txt``.
    cameras : (str, str)
        The left and right cameras, of ``00 01 02 03``: :data:`GRAY` (default) or
        :data:`COLOUR`.

    Returns
    -------
    StereoCalibration
        The raw cameras (``S_a`` their size), with KITTI's rectification (``R_rect``,
        ``P_rect``, ``S_rect``).

    Raises
    ------
    InputError
        One line naming the file and the key: a missing file or key, a line that is not
        ``KEY: values``, a key given twice, a wrong count of numbers, non-finite values, a
        singular camera matrix, a rotation that is not one, cameras of different sizes.

    Examples
    --------
    >>> read_kitti_calibration("calib_cam_to_cam.txt", cameras=COLOUR).image_size  # doctest: +SKIP
    (1392, 512)
    """
    path = Path(path)
    cameras = tuple(str(camera) for camera in cameras)
    if len(cameras) != 2 or any(c not in CAMERAS for c in cameras) or cameras[0] == cameras[1]:
        raise ValueError(f"cameras must be two of {', '.join(CAMERAS)}, got {cameras!r}")
    keys = read_kitti_keys(path)
    a, b = (_camera(path, keys, camera) for camera in cameras)
    for name in ("S", "S_rect"):
        if a[name] != b[name]:
            raise InputError(f"calibration file {path}: {name}_{cameras[1]} {b[name][0]}x"
                             f"{b[name][1]} differs from {name}_{cameras[0]} {a[name][0]}x"
                             f"{a[name][1]}")
    rotation = b["R"] @ a["R"].T
    translation = b["T"] - rotation @ a["T"]
    first, second = cameras
    names = {"left_matrix": f"K_{first}", "left_distortion": f"D_{first}",
             "right_matrix": f"K_{second}", "right_distortion": f"D_{second}",
             "rotation": f"R_{first} and R_{second}", "translation": f"T_{first} and T_{second}",
             "image_size": f"S_{first}", "r1": f"R_rect_{first}", "r2": f"R_rect_{second}",
             "p1": f"P_rect_{first}", "p2": f"P_rect_{second}", "size": f"S_rect_{first}"}
    rect = Rectification(a["R_rect"], b["R_rect"], a["P_rect"], b["P_rect"], None, a["S_rect"])
    return checked(path, StereoCalibration(a["K"], a["D"], b["K"], b["D"], rotation,
                                           translation, a["S"], rect), names)
