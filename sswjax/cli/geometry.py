"""``sswjax match`` options for the outputs beyond the map: depth, point cloud, KITTI's PNG.

``--kitti-png`` writes KITTI's 16-bit PNG (disparity x 256); ``--depth`` the depth
``baseline * f / (d + doffs)`` (by its extension: ``.pfm``, ``.npy``, ``.tif``, ``.tiff``) and
``--ply`` the point cloud of the pixels of finite positive depth, both from the rig of
``--calib calib.txt`` or of ``--focal F --baseline B [--doffs D] [--principal CX CY]``
(:mod:`sswjax.api.geometry`). :func:`geometry_writers` gives their writers, for the match
command to write with its other outputs, all or nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from sswjax.api.geometry import Calibration, check_calibration, depth_from_disparity, point_cloud
from sswjax.cli.common import Writer
from sswjax.data.calibration import read_calibration
from sswjax.data.io import write_float_map
from sswjax.data.ply import write_ply
from sswjax.data.scaled import write_scaled_disparity

__all__ = ["add_geometry_options", "calibration", "geometry_writers"]


def add_geometry_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--min-disp``, ``--kitti-png``, ``--depth``, ``--ply`` and the rig's options."""
    parser.add_argument("--min-disp", type=int, default=0, metavar="M",
                        help="first disparity searched, may be negative: M..M+N-1 (default 0)")
    parser.add_argument("--kitti-png", type=Path, metavar="OUT.png",
                        help="also write KITTI's 16-bit PNG (disparity x 256, 0 = invalid)")
    parser.add_argument("--depth", type=Path, metavar="DEPTH.pfm",
                        help="also write the depth baseline * f / (d + doffs) as .pfm, .npy, "
                             ".tif or .tiff (float32, inf where d + doffs <= 0); needs --calib "
                             "or --focal and --baseline")
    parser.add_argument("--ply", type=Path, metavar="CLOUD.ply",
                        help="also write the pixels of finite positive depth as a binary PLY "
                             "point cloud with the left image's colours")
    rig = parser.add_mutually_exclusive_group()
    rig.add_argument("--calib", type=Path, metavar="calib.txt",
                     help="Middlebury calibration: cam0 (focal length, principal point), "
                          "baseline, doffs")
    rig.add_argument("--focal", type=float, metavar="F", help="focal length in pixels")
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
        if args.depth is not None or args.ply is not None:
            raise ValueError("--depth and --ply need --calib FILE or --focal F --baseline B")
        return None
    if args.baseline is None:
        raise ValueError("--focal needs --baseline")
    principal = None if args.principal is None else tuple(args.principal)
    return check_calibration(Calibration(args.focal, args.baseline, args.doffs or 0.0,
                                         principal))


def geometry_writers(args: argparse.Namespace, disparity: np.ndarray, left: np.ndarray,
                     calib: Calibration | None) -> dict[Path, Writer]:
    """The writers of ``--kitti-png``, ``--depth`` and ``--ply`` (those asked for), for
    :func:`sswjax._files.atomic_outputs`.

    Parameters
    ----------
    disparity : float32 (H, W)
    left : (H, W) or (H, W, C) image as read, for the point cloud's colours
    calib : Calibration, needed by ``--depth`` and ``--ply`` (:func:`calibration`)
    """
    writers: dict[Path, Writer] = {}
    if args.kitti_png is not None:
        writers[args.kitti_png] = lambda tmp: write_scaled_disparity(tmp, disparity, scale=256,
                                                                     atomic=False)
    if args.depth is not None:
        depth = depth_from_disparity(disparity, focal=calib.focal, baseline=calib.baseline,
                                     doffs=calib.doffs)
        writers[args.depth] = lambda tmp: write_float_map(tmp, depth, suffix=args.depth.suffix,
                                                          atomic=False)
    if args.ply is not None:
        cloud = point_cloud(disparity, left, calib)
        writers[args.ply] = lambda tmp: write_ply(tmp, *cloud, atomic=False)
    return writers
