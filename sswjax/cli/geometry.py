"""``sswjax match`` options for the rig and the outputs beyond the map: depth, point cloud,
KITTI's PNG.

``--kitti-png`` writes KITTI's 16-bit PNG (disparity x 256); ``--depth`` the depth
``baseline * f / (d + doffs)`` (by its extension: ``.pfm``, ``.npy``, ``.tif``, ``.tiff``, or
``.png``, 16 bits of ``round(depth * --depth-scale)``) and
``--ply`` the point cloud of the pixels of finite positive depth (by its extension: ``.ply``
or ``.npz``), both from the rig of ``--calib calib.txt``, of ``--focal F --baseline B
[--doffs D] [--principal CX CY]`` (:mod:`sswjax.api.geometry`), or of a raw camera's
calibration, ``--rectify stereo.yaml`` (:mod:`sswjax.cli.rectify`: then in the raw left
camera's frame and pixels). ``--depth-range ZMIN ZMAX`` sets the disparity range from the
rig. :func:`geometry_writers` gives the writers, for the match command to write with its
other outputs, all or nothing.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from sswjax.api.auto_range import DisparityRange, range_for_depths
from sswjax.api.geometry import (Calibration, Rectification, StereoCalibration, check_calibration,
                                 depth_from_disparity, point_cloud)
from sswjax.api.raw_frame import raw_depth, raw_point_cloud
from sswjax.cli.common import Writer
from sswjax.data.calibration import read_calibration
from sswjax.data.io import FLOAT_MAP_SUFFIXES, write_float_map
from sswjax.data.ply import CLOUD_SUFFIXES, write_cloud
from sswjax.data.scaled import write_scaled_disparity

__all__ = ["CLOUD_FORMATS", "add_geometry_options", "alpha_option", "calibration", "depth_formats",
           "depth_range", "geometry_writers", "positive_number"]

CLOUD_FORMATS = {"--ply": (CLOUD_SUFFIXES,
                           ".ply (binary PLY point cloud) or .npz (xyz float32, rgb uint8)")}
"""The endings ``--ply`` writes, for :func:`sswjax.cli.common.check_outputs`."""


def depth_formats(args: argparse.Namespace) -> dict[str, tuple[tuple[str, ...], str]]:
    """The endings ``--depth`` writes, for :func:`sswjax.cli.common.check_outputs`: the float
    maps, and ``.png`` with ``--depth-scale``."""
    floats = ".pfm, .npy, .tif or .tiff (float32)"
    if getattr(args, "depth_scale", None) is None:
        return {"--depth": (FLOAT_MAP_SUFFIXES,
                            f"{floats}, or .png with --depth-scale S (16-bit, round(depth * S))")}
    return {"--depth": (FLOAT_MAP_SUFFIXES + (".png",),
                        f"{floats}, or .png (16-bit, round(depth * --depth-scale), 0 = unknown)")}


def _number(text: str) -> float:
    """``text`` as a float, NaN if it is none."""
    try:
        return float(text)
    except ValueError:
        return math.nan


def positive_number(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = _number(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def alpha_option(text: str) -> float:
    """``--alpha``: a number in [0, 1]."""
    value = _number(text)
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in [0, 1], got {text!r}")
    return value


def add_geometry_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--min-disp``, ``--kitti-png``, ``--depth``, ``--ply`` and the rig's options."""
    parser.add_argument("--min-disp", type=int, default=0, metavar="M",
                        help="first disparity searched, may be negative: M..M+N-1 (default 0)")
    parser.add_argument("--kitti-png", type=Path, metavar="OUT.png",
                        help="also write KITTI's 16-bit PNG (disparity x 256, 0 = invalid)")
    parser.add_argument("--depth", type=Path, metavar="DEPTH.pfm",
                        help="also write the depth baseline * f / (d + doffs) as .pfm, .npy, "
                             ".tif or .tiff (float32, inf where d + doffs <= 0), or .png "
                             "(16-bit, round(depth * --depth-scale), 0 = unknown); needs "
                             "--calib, --focal and --baseline, or --rectify")
    parser.add_argument("--depth-scale", type=positive_number, metavar="S",
                        help="with --depth DEPTH.png: file value per unit of depth (1000 writes "
                             "millimetres of a rig calibrated in metres; depths beyond 65535 / S "
                             "are written 0)")
    parser.add_argument("--ply", type=Path, metavar="CLOUD.ply",
                        help="also write the cloud: the pixels of finite positive depth with the "
                             "left image's colours, by its extension: .ply (binary PLY) or .npz "
                             "(xyz float32, rgb uint8)")
    parser.add_argument("--depth-range", type=float, nargs=2, metavar=("ZMIN", "ZMAX"),
                        help="search the disparities of depths ZMIN..ZMAX (the rig's unit; ZMAX "
                             "may be inf) instead of --ndisp and --min-disp; needs the rig")
    rig = parser.add_mutually_exclusive_group()
    rig.add_argument("--calib", type=Path, metavar="calib.txt",
                     help="Middlebury calibration: cam0 (focal length, principal point), "
                          "baseline, doffs (left out: cam1's cx minus cam0's; one that "
                          "disagrees with them, or a key given twice, is refused)")
    rig.add_argument("--focal", type=float, metavar="F", help="focal length in pixels")
    rig.add_argument("--rectify", type=Path, nargs="+", metavar="STEREO_CALIB",
                     help="raw images of a calibrated rig: rectify them first with this "
                          "calibration (OpenCV YAML, XML or .npz; ROS's left.yaml right.yaml; "
                          "KITTI's calib_cam_to_cam.txt; Middlebury's calib.txt); -o is then "
                          "the rectified view's, --depth and --ply the raw left camera's")
    parser.add_argument("--alpha", type=alpha_option, metavar="A",
                        help="with --rectify: 0 crops to valid pixels, 1 keeps every raw pixel "
                             "(default: the calibration's own rectification, else 0)")
    parser.add_argument("--cameras", nargs=2, metavar=("LEFT", "RIGHT"),
                        help="with a KITTI calib_cam_to_cam.txt: the two cameras (default 00 01 "
                             "for gray images, 02 03 for colour)")
    parser.add_argument("--baseline", type=float, metavar="B",
                        help="with --focal: camera distance (depth comes out in its unit)")
    parser.add_argument("--doffs", type=float, metavar="D",
                        help="with --focal: x-difference of the principal points (default 0)")
    parser.add_argument("--principal", type=float, nargs=2, metavar=("CX", "CY"),
                        help="with --focal: principal point (default: the image centre)")


def calibration(args: argparse.Namespace) -> Calibration | None:
    """The rig of ``--calib`` or ``--focal/--baseline/...`` (None when neither is given).

    Raises ``ValueError`` (one line) for options that do not go together, or that
    ``--depth`` / ``--ply`` lack.
    """
    png = args.depth is not None and args.depth.suffix.lower() == ".png"  # with a scale
    if not png and getattr(args, "depth_scale", None) is not None:  # (depth_formats)
        raise ValueError("--depth-scale goes with --depth DEPTH.png")
    by_hand = [f"--{name}" for name in ("baseline", "doffs", "principal")
               if getattr(args, name) is not None]
    options, one = ", ".join(by_hand), len(by_hand) == 1
    if args.calib is not None:
        if by_hand:
            raise ValueError(f"{options} {'goes' if one else 'go'} with --focal, not --calib "
                             "(the file gives it)")
        return read_calibration(args.calib)
    if args.focal is None:
        if by_hand:
            raise ValueError(f"{options} {'needs' if one else 'need'} --focal")
        if getattr(args, "rectify", None) is None and (
                args.depth is not None or args.ply is not None):
            raise ValueError("--depth and --ply need --calib FILE, --focal F --baseline B or "
                             "--rectify STEREO_CALIB")
        return None
    if args.baseline is None:
        raise ValueError("--focal needs --baseline")
    principal = None if args.principal is None else tuple(args.principal)
    return check_calibration(Calibration(args.focal, args.baseline, args.doffs or 0.0,
                                         principal))


def depth_range(args: argparse.Namespace, rig: Calibration | None, width: int
                ) -> DisparityRange | None:
    """The range of ``--depth-range`` for the rig (None without the option).

    Raises ``ValueError`` (one line) without a rig, or on depths that are not ``0 < ZMIN <
    ZMAX``."""
    if getattr(args, "depth_range", None) is None:
        return None
    if rig is None:
        raise ValueError("--depth-range needs the rig: --calib FILE, --focal F --baseline B or "
                         "--rectify STEREO_CALIB")
    low, high = args.depth_range
    try:
        return range_for_depths(rig, low, high, width=width)
    except ValueError as exc:
        raise ValueError(f"--depth-range {low:g} {high:g}: {exc}") from None


def geometry_writers(args: argparse.Namespace, disparity: np.ndarray, left: np.ndarray,
                     calib: Calibration | None, *, stereo: StereoCalibration | None = None,
                     rectification: Rectification | None = None) -> dict[Path, Writer]:
    """The writers of ``--kitti-png``, ``--depth`` and ``--ply`` (those asked for), for
    :func:`sswjax._files.atomic_outputs`.

    Parameters
    ----------
    disparity : float32 (H, W)
    left : (H, W) or (H, W, C) image as read, for the point cloud's colours (the raw left
        image with ``stereo``)
    calib : Calibration, needed by ``--depth`` and ``--ply`` (:func:`calibration`)
    stereo, rectification : with ``--rectify``: depth and cloud in the raw left camera's frame
        and pixels (:func:`sswjax.api.rectify.raw_depth`); ``disparity`` is the rectified
        view's, ``inf`` where it is to be left out
    """
    writers: dict[Path, Writer] = {}
    if args.kitti_png is not None:
        writers[args.kitti_png] = lambda tmp: write_scaled_disparity(tmp, disparity, scale=256,
                                                                     atomic=False)
    if args.depth is not None:
        if stereo is not None:
            depth = raw_depth(disparity, stereo, rectification)
        else:
            depth = depth_from_disparity(disparity, focal=calib.focal, baseline=calib.baseline,
                                         doffs=calib.doffs)
        if args.depth.suffix.lower() == ".png":
            writers[args.depth] = lambda tmp: write_scaled_disparity(
                tmp, depth, scale=args.depth_scale, atomic=False)
        else:
            writers[args.depth] = lambda tmp: write_float_map(
                tmp, depth, suffix=args.depth.suffix, atomic=False)
    if args.ply is not None:
        cloud = (raw_point_cloud(disparity, left, stereo, rectification) if stereo is not None
                 else point_cloud(disparity, left, calib))
        writers[args.ply] = lambda tmp: write_cloud(tmp, *cloud, suffix=args.ply.suffix,
                                                    atomic=False)
    return writers
