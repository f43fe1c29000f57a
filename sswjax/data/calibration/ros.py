"""ROS's stereo calibration: the two camera_info YAML files of ``camera_calibration``.

Each file (``left.yaml``, ``right.yaml``) holds one camera: ``image_width``, ``image_height``,
``camera_matrix`` (3x3), ``distortion_model`` (``plumb_bob`` or ``rational_polynomial``; the
fisheye ``equidistant`` is not OpenCV's pinhole model), ``distortion_coefficients``,
``rectification_matrix`` (the camera's ``R1`` or ``R2``) and ``projection_matrix`` (``P1`` or
``P2``: the right one's ``Tx = -fx' * baseline``). The pose of the right camera follows from
them: ``R = R2^T R1`` and ``T = R2^T (Tx / fx', Ty / fy', 0)``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from sswjax._files import InputError
from sswjax.api.geometry import Rectification, StereoCalibration, check_stereo_calibration
from sswjax.data.calibration.common import matrix, size_of
from sswjax.data.calibration.filestorage import read_filestorage

__all__ = ["MODELS", "read_camera_info", "read_ros_calibration"]

MODELS = ("plumb_bob", "rational_polynomial")
"""The ``distortion_model`` values read (OpenCV's pinhole model with 5 or 8 coefficients)."""

_KEYS = ("camera_matrix", "distortion_coefficients", "rectification_matrix", "projection_matrix")


def read_camera_info(path: str | os.PathLike) -> dict:
    """One camera_info YAML: ``{"K", "D", "R", "P", "size"}`` (float64 arrays, ``(w, h)``)."""
    path = Path(path)
    keys = read_filestorage(path)
    missing = [key for key in _KEYS + ("image_width", "image_height") if key not in keys]
    if missing:
        kind = "" if "camera_matrix" in keys else " (is it a ROS camera_info file?)"
        raise InputError(f"calibration file {path} lacks {', '.join(missing)}{kind}")
    model = keys.get("distortion_model", "plumb_bob")
    if model not in MODELS:
        raise InputError(f"calibration file {path}: distortion_model {model!r} is not supported "
                         f"(only {' or '.join(MODELS)}, OpenCV's pinhole model)")
    return {"K": matrix(path, "camera_matrix", keys["camera_matrix"], shape=(3, 3)),
            "D": matrix(path, "distortion_coefficients", keys["distortion_coefficients"]
                        ).reshape(-1),
            "R": matrix(path, "rectification_matrix", keys["rectification_matrix"], shape=(3, 3)),
            "P": matrix(path, "projection_matrix", keys["projection_matrix"], shape=(3, 4)),
            "size": size_of(path, "image_width", keys["image_width"], "image_height",
                            keys["image_height"])}


def _check_camera(path: Path, camera: dict, side: int) -> None:
    """The checks of one camera's fields, naming its file (through a rig of its own fields)."""
    eye = np.eye(3)
    other = np.hstack([eye, [[-1.0], [0.0], [0.0]]])
    p_left, p_right = (camera["P"], other) if side == 1 else (other, camera["P"])
    trial = StereoCalibration(camera["K"], camera["D"], eye, None, eye, [-1.0, 0, 0],
                              camera["size"],
                              Rectification(camera["R"], eye, p_left, p_right), False)
    names = {"left_matrix": "camera_matrix", "left_distortion": "distortion_coefficients",
             "r1": "rectification_matrix", "p1": "projection_matrix",
             "p2": "projection_matrix", "image_size": "image_width, image_height"}
    try:
        check_stereo_calibration(trial, names=names)
    except ValueError as exc:
        raise InputError(f"calibration file {path}: {exc}") from exc


def read_ros_calibration(left: str | os.PathLike, right: str | os.PathLike) -> StereoCalibration:
    """The stereo rig of ROS's two camera_info files (module docstring).

    Returns
    -------
    StereoCalibration
        With the files' rectification (``R1 R2 P1 P2``) and image size.

    Raises
    ------
    InputError
        One line naming the file and the key: a missing file or key, a wrong shape,
        non-finite values, a singular camera matrix, a rectification matrix that is not a
        rotation, a distortion model that is not OpenCV's pinhole one, the two cameras'
        image sizes that differ, a zero baseline (``Tx`` of the right projection matrix).

    Examples
    --------
    >>> read_ros_calibration("left.yaml", "right.yaml").rotation.shape  # doctest: +SKIP
    (3, 3)
    """
    left, right = Path(left), Path(right)
    cameras = read_camera_info(left), read_camera_info(right)
    for path, camera, side in ((left, cameras[0], 1), (right, cameras[1], 2)):
        _check_camera(path, camera, side)
    first, second = cameras
    if first["size"] != second["size"]:
        raise InputError(f"calibration file {right}: image_width x image_height "
                         f"{second['size'][0]}x{second['size'][1]} differs from the left "
                         f"camera's {first['size'][0]}x{first['size'][1]} ({left})")
    p1, p2 = first["P"], second["P"]
    offset = np.array([p2[0, 3] / p2[0, 0] - p1[0, 3] / p1[0, 0],
                       p2[1, 3] / p2[1, 1] - p1[1, 3] / p1[1, 1], 0.0])
    if not np.any(offset):
        raise InputError(f"calibration file {right}: projection_matrix has Tx = 0 (no baseline: "
                         "is it the right camera's file?)")
    rotation = second["R"].T @ first["R"]
    translation = second["R"].T @ offset
    calib = StereoCalibration(first["K"], first["D"], second["K"], second["D"], rotation,
                              translation, first["size"],
                              Rectification(first["R"], second["R"], p1, p2, None, first["size"]))
    try:
        return check_stereo_calibration(calib)
    except ValueError as exc:
        raise InputError(f"calibration files {left} and {right}: {exc}") from exc
