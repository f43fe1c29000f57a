"""Middlebury's ``calib.txt`` (MiddEval3, ETH3D and the older sets): a rectified rig.

``read_calib`` parses the ``key=value`` lines (``ndisp`` for the data layouts);
``read_calibration`` turns the left camera of one into a
:class:`~sswjax.api.geometry.Calibration` for depth and point clouds;
``read_middlebury_calibration`` gives both cameras as a
:class:`~sswjax.api.geometry.StereoCalibration` (``rectified``: no distortion, no rotation, the
right camera ``baseline`` to the right; ``width`` and ``height`` its image size).

Every path reads the file through ``read_calib`` and its checks, so that one file gives one
rig or one refusal everywhere (``match --calib``, ``--rectify``, ``sswjax rectify``, the
evaluation layouts): a key given twice is refused (with both line numbers), and ``doffs``,
which the format defines as ``cam1``'s ``cx`` minus ``cam0``'s, must agree with the two cameras
within :data:`DOFFS_TOLERANCE`; a file without ``doffs`` takes it from them (without ``cam1``:
0, the file giving one camera for both).
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np

from sswjax._files import InputError, input_file
from sswjax.api.geometry import Calibration, StereoCalibration, check_calibration
from sswjax.data.calibration.common import checked, size_of

__all__ = ["DOFFS_TOLERANCE", "read_calib", "read_calibration", "read_middlebury_calibration"]

DOFFS_TOLERANCE = 0.01
"""Pixels a given ``doffs`` may differ from ``cam1``'s ``cx`` minus ``cam0``'s: the published
files round each of the three to 3 decimals (MiddEval3's Shelves: ``doffs=47.561``, the
cameras 47.562 apart), and 0.01 px of disparity is far below what a depth can tell."""


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
        If the file is missing, not a regular file or unreadable, a line is not
        ``key=value``, a key is given twice, ``ndisp`` is missing (with ``require_ndisp``) or
        not a positive integer, or ``doffs`` disagrees with ``cam0`` and ``cam1`` (then both
        must be ``[f 0 cx; 0 f cy; 0 0 1]``).

    Examples
    --------
    >>> read_calib("Motorcycle/calib.txt")["ndisp"]  # doctest: +SKIP
    70
    """
    path = input_file(path, "calibration file")
    try:
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read calibration file {path}: {exc}") from exc
    calib: dict[str, str | float] = {}
    lines: dict[str, int] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        key, sep, value = line.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key:
            raise InputError(
                f"calibration file {path} line {number} is not key=value: {line.strip()[:40]!r}"
            )
        if key in lines:
            raise InputError(f"calibration file {path} line {number}: {key} given twice "
                             f"(lines {lines[key]} and {number})")
        lines[key] = number
        try:
            calib[key] = float(value)
        except ValueError:
            calib[key] = value
    _doffs(path, calib)
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


def _doffs(path: Path, calib: dict) -> float:
    """``doffs`` of a parsed file: the given one, which must agree with ``cam1``'s ``cx`` minus
    ``cam0``'s when both are there; without it that difference (0 without ``cam1``)."""
    doffs = calib.get("doffs")
    if doffs is not None and not isinstance(doffs, float):
        raise InputError(f"calibration file {path}: doffs must be a number, got {doffs!r}")
    if doffs is not None and not math.isfinite(doffs):
        raise InputError(f"calibration file {path}: doffs must be finite, got {doffs}")
    if "cam0" not in calib or "cam1" not in calib:
        return 0.0 if doffs is None else doffs
    apart = _camera(path, calib, "cam1")[0][2] - _camera(path, calib, "cam0")[0][2]
    if doffs is None:
        return apart
    if not math.isclose(doffs, apart, rel_tol=0, abs_tol=DOFFS_TOLERANCE):
        raise InputError(f"calibration file {path}: doffs {doffs:g} is not cam1's cx minus "
                         f"cam0's ({apart:g})")
    return doffs


def _rig(path: Path) -> tuple[dict, Calibration]:
    """The parsed file (:func:`read_calib`) and its left camera (:func:`read_calibration`)."""
    calib = read_calib(path, require_ndisp=False)
    missing = [key for key in ("cam0", "baseline") if key not in calib]
    if missing:
        raise InputError(f"calibration file {path} lacks {' and '.join(missing)}")
    (fx, _, cx), (_, fy, cy), _ = _camera(path, calib, "cam0")
    if not math.isclose(fx, fy, rel_tol=1e-6):
        raise InputError(f"calibration file {path}: cam0 has two focal lengths {fx:g} and "
                         f"{fy:g}; only square pixels are supported")
    if not isinstance(calib["baseline"], float):
        raise InputError(f"calibration file {path}: baseline must be a number, "
                         f"got {calib['baseline']!r}")
    try:
        left = check_calibration(Calibration(fx, calib["baseline"], _doffs(path, calib),
                                             (cx, cy)))
    except ValueError as exc:
        raise InputError(f"calibration file {path}: {exc}") from exc
    return calib, left


def read_calibration(path: str | os.PathLike) -> Calibration:
    """The left camera of a Middlebury ``calib.txt``: ``cam0``, ``baseline`` and ``doffs``.

    ``cam0=[f 0 cx; 0 f cy; 0 0 1]`` gives the focal length and principal point (its two focal
    lengths must agree: the rectified rigs of Middlebury and ETH3D have square pixels);
    ``doffs``, the x-difference of the principal points, is ``cam1``'s ``cx`` minus ``cam0``'s
    when absent (0 without ``cam1``) and must agree with them when given (module docstring);
    ``ndisp`` and the other keys are not needed.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Calibration

    Raises
    ------
    InputError
        As :func:`read_calib`, and if the file lacks ``cam0`` or ``baseline``, has a malformed
        ``cam0`` or ``cam1`` or a non-positive focal length or baseline.

    Examples
    --------
    >>> read_calibration("trainingQ/Motorcycle/calib.txt")  # doctest: +SKIP
    Calibration(focal=999.421, baseline=193.001, doffs=32.778, principal=(294.182, 252.932))
    """
    return _rig(Path(path))[1]


def read_middlebury_calibration(path: str | os.PathLike) -> StereoCalibration:
    """Both cameras of a Middlebury ``calib.txt`` as a rectified
    :class:`~sswjax.api.geometry.StereoCalibration`.

    ``K1 = cam0``, ``K2 = cam1`` (without ``cam1``: ``cam0`` moved by ``doffs``), no
    distortion, ``R = I``, ``T = (-baseline, 0, 0)``; the image size from ``width`` and
    ``height`` when both are there. ``doffs``, when given, must be ``cam1``'s ``cx`` minus
    ``cam0``'s (within :data:`DOFFS_TOLERANCE`).

    Raises
    ------
    InputError
        As :func:`read_calibration`, and on a bad ``width`` or ``height`` (one line naming the
        file and the key).

    Examples
    --------
    >>> read_middlebury_calibration("trainingQ/Motorcycle/calib.txt").image_size  # doctest: +SKIP
    (741, 497)
    """
    path = Path(path)
    calib, left = _rig(path)
    cam0 = np.array(_camera(path, calib, "cam0"))
    if "cam1" in calib:
        cam1 = np.array(_camera(path, calib, "cam1"))
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
