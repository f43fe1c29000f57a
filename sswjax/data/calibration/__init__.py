"""Calibration files: the rigs people have, one module per format, one type for all of them.

================  ==================================================================================
``middlebury``    Middlebury's ``calib.txt`` (MiddEval3, ETH3D): ``read_calib`` (its keys),
                  ``read_calibration`` (the left camera), ``read_middlebury_calibration`` (the rig)
``opencv``        ``cv2.FileStorage`` YAML / XML and ``.npz`` with ``K1 D1 K2 D2 R T``
                  (``R1 R2 P1 P2 Q``, the image size): ``read_opencv_calibration``
``ros``           ROS's pair of camera_info YAML files: ``read_ros_calibration``
``kitti``         KITTI's ``calib_cam_to_cam.txt``: ``read_kitti_calibration``
``filestorage``   the plain YAML and XML reader (no OpenCV needed)
``common``        what the readers share: numbers, matrices, messages naming file and field
================  ==================================================================================

Every reader returns a :class:`~sswjax.api.geometry.StereoCalibration` (K, D of both cameras,
the right camera's ``R`` and ``T``, the image size, the rectification when the file has one,
``rectified`` for rigs rectified already) and raises a one-line
:class:`~sswjax._files.InputError` naming the file and the field. :func:`read_stereo_calibration`
tells the format from the file.
"""

from __future__ import annotations

import os
from pathlib import Path

from sswjax._files import InputError
from sswjax.api.geometry import StereoCalibration
from sswjax.data.calibration.common import read_head
from sswjax.data.calibration.kitti import COLOUR, GRAY, read_kitti_calibration
from sswjax.data.calibration.middlebury import (read_calib, read_calibration,
                                                read_middlebury_calibration)
from sswjax.data.calibration.opencv import read_opencv_calibration
from sswjax.data.calibration.ros import read_ros_calibration

__all__ = ["COLOUR", "FORMATS", "GRAY", "calibration_format", "read_calib", "read_calibration",
           "read_kitti_calibration", "read_middlebury_calibration", "read_opencv_calibration",
           "read_ros_calibration", "read_stereo_calibration"]

FORMATS = ("opencv-yaml", "opencv-xml", "npz", "ros", "kitti", "middlebury")
"""What :func:`calibration_format` tells apart."""


def calibration_format(path: str | os.PathLike) -> str:
    """The format of a calibration file (one of :data:`FORMATS`), from its first bytes.

    Raises ``InputError`` if the file is missing, not a regular file (a FIFO is never opened),
    unreadable or none of them.

    Examples
    --------
    >>> calibration_format("Motorcycle/calib.txt")  # doctest: +SKIP
    'middlebury'
    """
    path, head = read_head(path, 4096)
    if head.startswith(b"PK"):
        return "npz"
    text = head.decode("utf-8", "replace").lstrip("\ufeff \t\r\n")
    if text.startswith("<"):
        return "opencv-xml"
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    if any(line.startswith(("cam0=", "cam0 =")) for line in lines):
        return "middlebury"
    if any(line.startswith(("calib_time:", "S_00:", "K_00:", "P_rect_00:")) for line in lines):
        return "kitti"
    if any(line.startswith(("camera_matrix:", "projection_matrix:")) for line in lines):
        return "ros"
    if text.startswith("%YAML") or any(":" in line for line in lines[:3]):
        return "opencv-yaml"
    raise InputError(f"calibration file {path}: not a format sswjax reads (OpenCV YAML or XML, "
                     ".npz, ROS camera_info, KITTI calib_cam_to_cam.txt, Middlebury calib.txt)")


def read_stereo_calibration(path: str | os.PathLike, *, right: str | os.PathLike | None = None,
                            cameras: tuple[str, str] | None = None) -> StereoCalibration:
    """A stereo calibration in any format read here, told from the file.

    Parameters
    ----------
    path : str or os.PathLike
        The calibration: OpenCV YAML / XML / ``.npz``, KITTI's ``calib_cam_to_cam.txt``,
        Middlebury's ``calib.txt``, or the left camera's ROS camera_info YAML.
    right : str or os.PathLike, optional
        The second file of a pair: the right camera's camera_info (ROS), or the extrinsics
        file beside OpenCV intrinsics (``stereo_calib.cpp``'s two).
    cameras : (str, str), optional
        KITTI: the two cameras (default :data:`GRAY`, ``("00", "01")``; :data:`COLOUR` is
        ``("02", "03")``).

    Returns
    -------
    StereoCalibration

    Raises
    ------
    InputError
        One line naming the file and the field (see each reader); ``right`` with a format
        that has no second file, a ROS file without its pair, ``cameras`` for a file that is
        not KITTI's.

    Examples
    --------
    >>> read_stereo_calibration("left.yaml", right="right.yaml")  # doctest: +SKIP
    """
    path = Path(path)
    kind = calibration_format(path)
    if cameras is not None and kind != "kitti":
        raise InputError(f"calibration file {path}: cameras {' '.join(cameras)} are for KITTI's "
                         "calib_cam_to_cam.txt")
    if kind == "ros":
        if right is None:
            raise InputError(f"calibration file {path} is one camera's ROS camera_info: give the "
                             "right camera's file too")
        return read_ros_calibration(path, right)
    if right is not None:
        if kind in ("opencv-yaml", "opencv-xml", "npz"):
            if calibration_format(right) == "ros":
                raise InputError(f"calibration file {right} is a ROS camera_info but {path} is "
                                 "not: give both cameras' camera_info files")
            return read_opencv_calibration(path, extrinsics=right)
        raise InputError(f"calibration file {path} is {kind}'s: it takes no second file "
                         f"({right})")
    if kind == "kitti":
        return read_kitti_calibration(path, cameras=cameras or GRAY)
    if kind == "middlebury":
        return read_middlebury_calibration(path)
    return read_opencv_calibration(path)
