"""Middlebury's ``calib.txt`` (MiddEval3, ETH3D and the older sets): a rectified rig.

``read_calib`` parses the ``key=value`` lines (``ndisp`` for the data layouts);
``read_calibration`` turns the left camera of one into a
:class:`~sswjax.api.geometry.Calibration` for depth and point clouds;
``read_middlebury_calibration`` gives both cameras as a
:class:`~sswjax.api.geometry.StereoCalibration` (``rectified``: no distortion, no rotation, the
right camera ``baseline`` to the right; ``width`` and ``height`` its image size).
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np

from sswjax._files import InputError
from sswjax.api.geometry import Calibration, StereoCalibration, check_calibration
from sswjax.data.calibration.common import checked, size_of

__all__ = ["read_calib", "read_calibration", "read_middlebury_calibration"]


def read_calib(path: str | os.PathLike, *, require_ndisp: bool = True) -> dict[str, str | float]:
    """Parse a MiddEval3 ``calib.txt`` file of ``key=value`` lines.

    Parameters
    ----------
    path : str or os.PathLike
        Calibration file.
    require_ndisp : bool
        Refuse a file without ``ndisp`` (default; the depth tools of :mod:`sswjax.api.geometry`
        read calibrations without it). A present ``ndisp`` is always checked.

    Returns
    -------
    dict
        Key -> value; numbers become ``float`` (``ndisp`` an ``int``), anything else (such as
        the ``cam0`` matrix ``"[999.421 0 294.182; ...]"``) stays a ``str``.

    Raises
    ------
    InputError
        If the file is missing or unreadable, a line is not ``key=value``, or ``ndisp`` is
        missing (with ``require_ndisp``) or not a positive integer.

    Examples
    --------
    >>> read_calib("Motorcycle/calib.txt")["ndisp"]  # doctest: +SKIP
    70
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"calibration file not found: {path}")
    try:
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read calibration file {path}: {exc}") from exc
    calib: dict[str, str | float] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        key, sep, value = line.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key:
            raise InputError(
                f"calibration file {path} line {number} is not key=value: {line.strip()[:40]!r}"
            )
        try:
            calib[key] = float(value)
        except ValueError:
            calib[key] = value
    ndisp = calib.get("ndisp")
    if ndisp is None and not require_ndisp:
        return calib
    if not isinstance(ndisp, float) or not ndisp.is_integer() or ndisp < 1:
        raise InputError(f"calibration file {path} needs ndisp=<positive integer>, got {ndisp!r}")
    calib["ndisp"] = int(ndisp)
    return calib


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def _camera(path: Path, calib: dict, key: str) -> list[list[float]]:
    """The 3x3 matrix ``[f 0 cx; 0 f cy; 0 0 1]`` of ``cam0`` or ``cam1``, as rows."""
    text = str(calib[key])
    rows = [re.findall(_NUMBER, row) for row in text.strip().strip("[]").split(";")]
    if not (text.strip().startswith("[") and text.strip().endswith("]")) or \
            [len(row) for row in rows] != [3, 3, 3]:
        raise InputError(f"calibration file {path}: {key} must be [f 0 cx; 0 f cy; 0 0 1], "
                         f"got {text[:60]!r}")
    return [[float(v) for v in row] for row in rows]


def read_calibration(path: str | os.PathLike) -> Calibration:
    """The left camera of a Middlebury ``calib.txt``: ``cam0``, ``baseline`` and ``doffs``.

    ``cam0=[f 0 cx; 0 f cy; 0 0 1]`` gives the focal length and principal point (its two focal
    lengths must agree: the rectified rigs of Middlebury and ETH3D have square pixels);
    ``doffs`` defaults to 0 when absent; ``ndisp`` and the other keys are not needed.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Calibration

    Raises
    ------
    InputError
        If the file is missing or unreadable, lacks ``cam0`` or ``baseline``, has a malformed
        ``cam0`` or a non-positive focal length or baseline.

    Examples
    --------
    >>> read_calibration("trainingQ/Motorcycle/calib.txt")  # doctest: +SKIP
    Calibration(focal=999.421, baseline=193.001, doffs=32.778, principal=(294.182, 252.932))
    """
    path = Path(path)
    calib = read_calib(path, require_ndisp=False)
    missing = [key for key in ("cam0", "baseline") if key not in calib]
    if missing:
        raise InputError(f"calibration file {path} lacks {' and '.join(missing)}")
    (fx, _, cx), (_, fy, cy), _ = _camera(path, calib, "cam0")
    if not math.isclose(fx, fy, rel_tol=1e-6):
        raise InputError(f"calibration file {path}: cam0 has two focal lengths {fx:g} and "
                         f"{fy:g}; only square pixels are supported")
    for key in ("baseline", "doffs"):
        if not isinstance(calib.get(key, 0.0), float):
            raise InputError(f"calibration file {path}: {key} must be a number, "
                             f"got {calib[key]!r}")
    try:
        return check_calibration(Calibration(fx, calib["baseline"], calib.get("doffs", 0.0),
                                             (cx, cy)))
    except ValueError as exc:
        raise InputError(f"calibration file {path}: {exc}") from exc


def read_middlebury_calibration(path: str | os.PathLike) -> StereoCalibration:
    """Both cameras of a Middlebury ``calib.txt`` as a rectified
    :class:`~sswjax.api.geometry.StereoCalibration`.

    ``K1 = cam0``, ``K2 = cam1`` (without ``cam1``: ``cam0`` moved by ``doffs``), no
    distortion, ``R = I``, ``T = (-baseline, 0, 0)``; the image size from ``width`` and
    ``height`` when both are there. ``doffs``, when given, must be ``cam1``'s ``cx`` minus
    ``cam0``'s.

    Raises
    ------
    InputError
        As :func:`read_calibration`, and on a bad ``cam1``, ``width`` or ``height``, or a
        ``doffs`` that disagrees with the two cameras (one line naming the file and the key).

    Examples
    --------
    >>> read_middlebury_calibration("trainingQ/Motorcycle/calib.txt").image_size  # doctest: +SKIP
    (741, 497)
    """
    path = Path(path)
    left = read_calibration(path)
    calib = read_calib(path, require_ndisp=False)
    cam0 = np.array(_camera(path, calib, "cam0"))
    if "cam1" in calib:
        cam1 = np.array(_camera(path, calib, "cam1"))
        if "doffs" in calib and not math.isclose(cam1[0, 2] - cam0[0, 2], left.doffs,
                                                 abs_tol=1e-3):
            raise InputError(f"calibration file {path}: doffs {left.doffs:g} is not cam1's cx "
                             f"minus cam0's ({cam1[0, 2] - cam0[0, 2]:g})")
    else:
        cam1 = cam0.copy()
        cam1[0, 2] += left.doffs
    size = None
    if "width" in calib or "height" in calib:
        size = size_of(path, "width", calib.get("width"), "height", calib.get("height"))
    names = {"left_matrix": "cam0", "right_matrix": "cam1", "translation": "baseline",
             "image_size": "width, height"}
    return checked(path, StereoCalibration(cam0, np.zeros(0), cam1, np.zeros(0), np.eye(3),
                                           np.array([-left.baseline, 0.0, 0.0]), size,
                                           None, True), names)
