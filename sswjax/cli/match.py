"""``sswjax match LEFT RIGHT --ndisp N -o OUT.pfm``: the disparity map of one rectified pair.

Two folders instead of two images match every pair of the same name
(:mod:`sswjax.cli.folders`). Before the images are read, every output is checked (none is an
input or another output, each can be written, in a format its option writes:
:func:`sswjax.cli.common.check_outputs`), the rig options are read and the pair's peak memory
is estimated from the image headers (:mod:`sswjax.cli.guard`: strips when the whole pair does
not fit). The map is written in the format of its extension (PFM, NumPy, TIFF or KITTI's
16-bit PNG), and as asked a colour PNG, KITTI's PNG, depth, a point cloud
(:mod:`sswjax.cli.geometry`), the confidence and the validity bits
(:mod:`sswjax.cli.confidence`): all of them or none (:func:`sswjax._files.atomic_outputs`).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from sswjax._files import atomic_outputs
from sswjax.api.match import match, match_with_confidence
from sswjax.cli.common import OUTPUT_FORMATS, check_outputs, disparity_writers, gigabytes
from sswjax.cli.confidence import (add_confidence_options, confidence_writers, invalid_as_inf,
                                   wants_confidence)
from sswjax.cli.folders import image_size, match_folders
from sswjax.cli.geometry import add_geometry_options, calibration, geometry_writers
from sswjax.cli.guard import guard_memory
from sswjax.cli.options import (add_parameter_options, add_plan_options, params_from_args,
                                plan_from_args)
from sswjax.config import Params
from sswjax.data.io import read_image
from sswjax.runtime.plan import ExecutionPlan

__all__ = ["MATCH_OUTPUTS", "add_match_command", "guard_pair", "run_match"]

MATCH_OUTPUTS = {"-o": "output", "--png": "png", "--kitti-png": "kitti_png", "--depth": "depth",
                 "--ply": "ply", "--confidence": "confidence", "--validity": "validity"}
"""The options of ``sswjax match`` that name an output file -> their attribute in the args."""


def add_match_command(commands) -> None:
    """Add the ``match`` sub-command to ``commands`` (argparse's sub-parsers)."""
    parser = commands.add_parser("match", help="disparity map of a rectified pair")
    parser.add_argument("left", type=Path, help="left (reference) image, or a folder of them")
    parser.add_argument("right", type=Path, help="right image, or a folder (pairs: same names)")
    parser.add_argument("--ndisp", type=int, required=True,
                        help="disparities searched: 0..N-1 (M..M+N-1 with --min-disp M)")
    parser.add_argument("-o", "--output", type=Path, required=True,
                        help="output disparity map, by its extension: .pfm, .npy, .tif or "
                             ".tiff (float32), or .png (16-bit, KITTI's scale: value = "
                             "round(d * 256), 0 = invalid); folders: the folder of <name>.pfm, "
                             "created")
    parser.add_argument("--max-memory", type=gigabytes, metavar="GB",
                        help="refuse to run if the estimated peak memory exceeds GB (the memory "
                             "available is always a limit)")
    parser.add_argument("--resume", action="store_true",
                        help="folders: keep the maps already in OUT_DIR, match the others")
    parser.add_argument("--bucket", action=argparse.BooleanOptionalAction, default=None,
                        help="folders: pad pairs to a few bucketed shapes (fewer compilations, "
                             "slightly different maps near the bottom and right borders); by "
                             "default only when the pairs come in more than 8 sizes")
    parser.add_argument("--png", type=Path, help="also write a colour-mapped PNG")
    add_confidence_options(parser)
    add_geometry_options(parser)
    add_parameter_options(parser, "the")
    add_plan_options(parser)
    parser.set_defaults(run=run_match)


def guard_pair(args: argparse.Namespace, params: Params, plan: ExecutionPlan) -> ExecutionPlan:
    """The checks of ``sswjax match LEFT RIGHT`` made before reading the images: ``--resume``
    is for folders; the pair (sizes from the headers) must fit in memory, in strips if it must.
    Returns the plan to match with."""
    if args.resume:
        raise ValueError("--resume is for folders (sswjax match LEFT_DIR RIGHT_DIR -o OUT_DIR)")
    left, right = image_size(args.left), image_size(args.right)
    if left[:2] == right[:2] and args.ndisp >= 1:  # else the matcher reports the problem
        return guard_memory([(*left[:2], max(left[2], right[2]))], args.ndisp, params=params,
                            plan=plan, limit_gb=args.max_memory, min_disp=args.min_disp)
    return plan


def run_match(args: argparse.Namespace) -> int:
    """``sswjax match``: one pair, or two folders; returns the exit status (0)."""
    if os.path.isdir(args.left) or os.path.isdir(args.right):  # never raises
        if wants_confidence(args):
            raise ValueError("--confidence, --validity and --invalid-as-inf take one pair, "
                             "not folders")
        return match_folders(args)
    outputs = {option: getattr(args, name) for option, name in MATCH_OUTPUTS.items()
               if getattr(args, name) is not None}
    check_outputs(outputs, {"LEFT": args.left, "RIGHT": args.right, "--calib": args.calib,
                            "--params": args.params}, formats=OUTPUT_FORMATS)
    calib = calibration(args)
    params, execution = params_from_args(args)
    plan = guard_pair(args, params, plan_from_args(args, execution))
    with atomic_outputs(outputs.values()) as files:  # each destination proven writable here
        left, right = read_image(args.left), read_image(args.right)
        options = dict(min_disp=args.min_disp, params=params, plan=plan,
                       check_memory=False)  # guard_pair checked it
        start = time.perf_counter()
        writers = {}
        if wants_confidence(args):
            matched = match_with_confidence(left, right, args.ndisp,
                                            low_confidence=args.low_confidence, **options)
            disparity = matched.disparity
            if args.invalid_as_inf:
                disparity = invalid_as_inf(disparity, matched.validity)
            writers.update(confidence_writers(matched, confidence=args.confidence,
                                              validity=args.validity))
        else:
            disparity = match(left, right, args.ndisp, **options)
        seconds = time.perf_counter() - start
        writers.update(disparity_writers(disparity, args.output, args.png, args.ndisp,
                                         min_disp=args.min_disp))
        writers.update(geometry_writers(args, disparity, left, calib))
        for path, write in writers.items():
            files.write(path, write)
    written = ", ".join(str(path) for path in outputs.values())
    print(f"wrote {written} ({disparity.shape[1]}x{disparity.shape[0]}, {seconds:.2f} s)")
    return 0
