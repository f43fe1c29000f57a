"""``sswjax download middlebury|eth3d|kitti``: fetch and unpack a data set's archives.

MiddEval3 (``--resolution Q|H|F``) and ETH3D two-view are downloaded
(:mod:`sswjax.data.download`); KITTI needs a registration, so its command prints where to get
it and how to unpack it (exit status 2).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sswjax.data import download as datasets

__all__ = ["add_download_command", "run_download"]


def add_download_command(commands) -> None:
    """Add the ``download`` sub-command to ``commands`` (argparse's sub-parsers)."""
    parser = commands.add_parser("download", help="download a stereo dataset")
    parser.add_argument("dataset", choices=["middlebury", "eth3d", "kitti"],
                        help="middlebury (MiddEval3), eth3d (two-view training, needs py7zr); "
                             "kitti needs a registration: says where to get it")
    parser.add_argument("--resolution", choices=["Q", "H", "F"], default="Q")
    parser.add_argument("--dest", type=Path, default=Path("data"), help="folder to fill (data)")
    parser.add_argument("--keep-archives", action="store_true", help="keep the archives")
    parser.set_defaults(run=run_download)


def run_download(args: argparse.Namespace) -> int:
    """Download the data set asked for; returns the exit status (0).

    The downloaders are looked up on :mod:`sswjax.data.download` when called (tests replace
    them there).
    """
    if args.dataset == "kitti":
        raise ValueError(datasets.KITTI_HOWTO.replace("DIR", str(args.dest)))
    if args.dataset == "eth3d":
        root = datasets.download_eth3d(args.dest, keep_archives=args.keep_archives)
        print(f"ETH3D two-view ready in {root}; evaluate with: sswjax evaluate --data {root}")
        return 0
    root = datasets.download_middeval3(args.dest, resolution=args.resolution,
                                       keep_archives=args.keep_archives)
    print(f"MiddEval3 {args.resolution} ready in {root}; evaluate with: "
          f"sswjax evaluate --data {root}")
    return 0
