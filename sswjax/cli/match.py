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

The range: ``--ndisp N [--min-disp M]``, ``--depth-range ZMIN ZMAX`` (from the rig), or
``--ndisp auto`` (:func:`sswjax.api.auto_range.estimate_range`, a note says what it chose).
Raw images of a calibrated rig: ``--rectify stereo.yaml`` rectifies them first
(:mod:`sswjax.cli.rectify`); the map, the confidence and the validity (bit 8: outside the
rectified view) are the rectified view's, depth and cloud the raw left camera's.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from sswjax._files import atomic_outputs
from sswjax.api.auto_range import estimate_range
from sswjax.api.match import match, match_with_confidence
from sswjax.api.rectify import rectification, rectified_calibration
from sswjax.cli.common import (OUTPUT_FORMATS, check_outputs, check_range_formats,
                               disparity_writers, gigabytes)
from sswjax.cli.confidence import (add_confidence_options, confidence_writers, invalid_as_inf,
                                   wants_confidence)
from sswjax.cli.distributed import cluster_plan
from sswjax.cli.folders import folder_pairs, image_size, match_folders
from sswjax.cli.geometry import (CLOUD_FORMATS, add_geometry_options, calibration,
                                 depth_formats, depth_range, geometry_writers)
from sswjax.cli.guard import guard_memory
from sswjax.cli.options import (add_parameter_options, add_plan_options, params_from_args,
                                plan_from_args)
from sswjax.cli.rectify import outside_bits, rectified, stereo_rig
from sswjax.config import Params
from sswjax.data.io import read_oriented
from sswjax.data.orientation import upright_pair
from sswjax.runtime.plan import ExecutionPlan

__all__ = ["AUTO", "MATCH_OUTPUTS", "add_match_command", "guard_pair", "ndisp_option",
           "run_match"]

MATCH_OUTPUTS = {"-o": "output", "--png": "png", "--kitti-png": "kitti_png", "--depth": "depth",
                 "--ply": "ply", "--confidence": "confidence", "--validity": "validity"}
"""The options of ``sswjax match`` that name an output file -> their attribute in the args."""

AUTO = "auto"
"""``--ndisp auto``: estimate the range."""


def ndisp_option(text: str) -> int | str:
    """argparse type of ``--ndisp``: an integer, or ``auto``."""
    if text.strip().lower() == AUTO:
        return AUTO
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid int value: {text!r} (a count of disparities, "
                                         "or auto)") from None


def add_match_command(commands) -> None:
    """Add the ``match`` sub-command to ``commands`` (argparse's sub-parsers)."""
    parser = commands.add_parser("match", help="disparity map of a rectified pair (a raw one "
                                               "with --rectify)")
    parser.add_argument("left", type=Path, help="left (reference) image, or a folder of them")
    parser.add_argument("right", type=Path, help="right image, or a folder (pairs: same names)")
    parser.add_argument("--ndisp", type=ndisp_option, metavar="N",
                        help="disparities searched: 0..N-1 (M..M+N-1 with --min-disp M), or auto "
                             "(estimated from a coarse pass); required unless --depth-range")
    parser.add_argument("-o", "--output", type=Path, required=True,
                        help="output disparity map, by its extension: .pfm, .npy, .tif or "
                             ".tiff (float32), or .png (16-bit, KITTI's scale: value = "
                             "round(d * 256), 0 = invalid); folders: the folder of <name>.pfm, "
                             "created")
    parser.add_argument("--max-memory", type=gigabytes, metavar="GB",
                        help="the memory a run may take: a pair whose estimated peak exceeds "
                             "GB is matched in strips or tiles that fit, refused only when even "
                             "those do not (the memory available is always a limit)")
    parser.add_argument("--resume", action="store_true",
                        help="folders: keep the maps already in OUT_DIR, match the others")
    parser.add_argument("--bucket", action=argparse.BooleanOptionalAction, default=None,
                        help="folders: pad pairs to a few bucketed shapes (fewer compilations, the "
                             "same maps, warm runs slower by the padding's work); by default "
                             "only when the pairs come in more than 8 sizes")
    parser.add_argument("--strict", action="store_true",
                        help="folders: refuse the whole run when a pair is bad (by default the "
                             "bad pairs are named and the others matched)")
    parser.add_argument("--png", type=Path, help="also write a colour-mapped PNG")
    add_confidence_options(parser)
    add_geometry_options(parser)
    add_parameter_options(parser, "the")
    add_plan_options(parser)
    parser.set_defaults(run=run_match)


def _check_range_options(args: argparse.Namespace) -> None:
    """One of ``--ndisp N``, ``--ndisp auto`` and ``--depth-range``; ``--min-disp`` with a count."""
    if args.depth_range is not None and args.ndisp is not None:
        raise ValueError("--depth-range sets the range: give it or --ndisp, not both")
    if args.depth_range is None and args.ndisp is None:
        raise ValueError("the following arguments are required: --ndisp (or --depth-range)")
    if args.min_disp and (args.depth_range is not None or args.ndisp == AUTO):
        raise ValueError("--min-disp goes with --ndisp N: --depth-range and --ndisp auto set it")


def _check_range_outputs(outputs: dict, calib, min_disp: int, ndisp: int) -> None:
    """Fail before matching if an output cannot hold the searched range: a 16-bit PNG map
    (:func:`~sswjax.cli.common.check_range_formats`), or ``--depth`` / ``--ply`` when every
    disparity searched has ``d + doffs <= 0`` (no pixel would have a depth; ``calib`` None:
    not known yet)."""
    check_range_formats(outputs, min_disp, ndisp)
    high = min_disp + ndisp - 1
    if calib is None or ndisp < 1 or high + calib.doffs > 0:
        return
    for option in ("--depth", "--ply"):
        if outputs.get(option) is not None:
            raise ValueError(f"{option} {outputs[option]}: this run searches disparities "
                             f"{min_disp}..{high}, and depth baseline * f / (d + doffs) needs "
                             f"d + doffs > 0 (doffs {calib.doffs:g}): no pixel would have a "
                             "depth")


def guard_pair(args: argparse.Namespace, params: Params, plan: ExecutionPlan) -> ExecutionPlan:
    """The checks of ``sswjax match LEFT RIGHT`` made before reading the images: ``--resume``
    is for folders (``--bucket`` and ``--strict`` too: a note says each is ignored); the pair (sizes from the
    headers) must fit in memory, in strips if it must.
    Returns the plan to match with."""
    if args.resume:
        raise ValueError("--resume is for folders (sswjax match LEFT_DIR RIGHT_DIR -o OUT_DIR)")
    for flag, given in (("--bucket", args.bucket), ("--strict", args.strict)):
        if given:  # harmless for one pair (a script may pass it for both): said, not refused
            print(f"sswjax: note: {flag} applies to folder runs; ignored for one pair",
                  file=sys.stderr)
    if not isinstance(args.ndisp, int) or args.rectify is not None:
        return plan  # the range or the size comes from the images: guarded once they are read
    left, right = image_size(args.left), image_size(args.right)
    if left[:2] == right[:2] and 1 <= args.ndisp < left[1]:  # else the matcher reports it
        return guard_memory([(*left[:2], max(left[2], right[2]))], args.ndisp, params=params,
                            plan=plan, limit_gb=args.max_memory, min_disp=args.min_disp)
    return plan


def _folders(args: argparse.Namespace) -> int:
    if wants_confidence(args):
        raise ValueError("--confidence, --validity and --invalid-as-inf take one pair, "
                         "not folders")
    if args.ndisp == AUTO:
        raise ValueError("--ndisp auto takes one pair: with folders give --ndisp N or "
                         "--depth-range ZMIN ZMAX")
    if args.depth_range is not None and os.path.isdir(args.left) and os.path.isdir(args.right):
        pairs = folder_pairs(args.left, args.right)
        narrowest = min(pair.size[1] for pair in pairs)
        rig = calibration(args)
        if args.rectify is not None:
            stereo = stereo_rig(args.rectify, pairs[0].size, cameras=args.cameras, note=False)
            rect = rectification(stereo, alpha=args.alpha)
            rig, narrowest = rectified_calibration(rect), (rect.size or stereo.image_size)[0]
        args.min_disp, args.ndisp = depth_range(args, rig, narrowest)
    return match_folders(args)


def _search(args: argparse.Namespace, rig, left, right) -> tuple[int, int]:
    """``(min_disp, ndisp)`` of the run: given, from ``--depth-range``, or estimated."""
    width = left.shape[1]
    if args.depth_range is not None:
        found = depth_range(args, rig, width)
        print(f"sswjax: note: depths {args.depth_range[0]:g}..{args.depth_range[1]:g} are "
              f"disparities {found.min_disp}..{found.min_disp + found.ndisp - 1} "
              f"(--min-disp {found.min_disp} --ndisp {found.ndisp})", file=sys.stderr)
        return found
    if args.ndisp == AUTO:
        start = time.perf_counter()
        found = estimate_range(left, right)
        print(f"sswjax: note: --ndisp auto chose disparities {found.min_disp}.."
              f"{found.min_disp + found.ndisp - 1} (--min-disp {found.min_disp} --ndisp "
              f"{found.ndisp}; estimated in {time.perf_counter() - start:.1f} s)",
              file=sys.stderr)
        return found
    return args.min_disp, args.ndisp


def run_match(args: argparse.Namespace) -> int:
    """``sswjax match``: one pair, or two folders; returns the exit status (0)."""
    _check_range_options(args)
    if os.path.isdir(args.left) or os.path.isdir(args.right):  # never raises
        return _folders(args)
    outputs = {option: getattr(args, name) for option, name in MATCH_OUTPUTS.items()
               if getattr(args, name) is not None}
    inputs = {"LEFT": args.left, "RIGHT": args.right, "--calib": args.calib,
              "--params": args.params}
    inputs.update({f"--rectify {i + 1}": path for i, path in enumerate(args.rectify or [])})
    check_outputs(outputs, inputs, formats={**OUTPUT_FORMATS, **CLOUD_FORMATS,
                                                      **depth_formats(args)})
    calib = calibration(args)
    if isinstance(args.ndisp, int):  # the range is known: refused before anything runs
        _check_range_outputs(outputs, calib, args.min_disp, args.ndisp)
    params = params_from_args(args)
    plan = guard_pair(args, params, plan_from_args(args))
    plan = cluster_plan(args, plan)  # --workers / --scheduler: the tiles are tasks
    stereo = None
    if args.rectify is not None:
        stereo = stereo_rig(args.rectify, image_size(args.left), cameras=args.cameras)
    elif args.alpha is not None or args.cameras is not None:
        raise ValueError(f"{'--alpha' if args.alpha is not None else '--cameras'} goes with "
                         "--rectify STEREO_CALIB")
    with atomic_outputs(outputs.values()) as files:  # destinations writable
        raw_left, raw_right, notes = upright_pair(read_oriented(args.left),
                                                  read_oriented(args.right))
        for note in notes:  # a photo stored turned, turned upright (its EXIF tag)
            print(f"sswjax: note: {note}", file=sys.stderr)
        left, right, pair = raw_left, raw_right, None
        if stereo is not None:
            pair, calib = rectified(stereo, raw_left, raw_right, alpha=args.alpha)
            left, right = pair.left, pair.right
        min_disp, ndisp = _search(args, calib, left, right)
        if not isinstance(args.ndisp, int) or stereo is not None:  # known now, before matching
            _check_range_outputs(outputs, calib, min_disp, ndisp)
        if not isinstance(args.ndisp, int) or stereo is not None:
            plan = guard_memory([(*left.shape[:2], 1 if left.ndim == 2 else 3)], ndisp,
                                params=params, plan=plan, limit_gb=args.max_memory,
                                min_disp=min_disp)
        options = {"min_disp": min_disp, "params": params, "plan": plan,
                   "check_memory": False}  # guarded above
        start = time.perf_counter()
        writers = {}
        if wants_confidence(args):
            matched = match_with_confidence(left, right, ndisp,
                                            low_confidence=args.low_confidence, **options)
            disparity, validity = matched.disparity, matched.validity
            if pair is not None:
                validity = validity | outside_bits(pair, disparity)
                matched = matched._replace(validity=validity)
            if args.invalid_as_inf:
                disparity = invalid_as_inf(disparity, validity)
            writers.update(confidence_writers(matched, confidence=args.confidence,
                                              validity=args.validity))
        else:
            disparity = match(left, right, ndisp, **options)
        seconds = time.perf_counter() - start
        writers.update(disparity_writers(disparity, args.output, args.png, ndisp,
                                         min_disp=min_disp))
        if pair is None:
            writers.update(geometry_writers(args, disparity, left, calib))
        else:
            kept = np.where(outside_bits(pair, disparity) > 0, np.float32(np.inf), disparity)
            writers.update(geometry_writers(args, kept, raw_left, calib, stereo=stereo,
                                            rectification=pair.rectification))
        for path, write in writers.items():
            files.write(path, write)
    written = ", ".join(str(path) for path in outputs.values())
    print(f"wrote {written} ({disparity.shape[1]}x{disparity.shape[0]}, {seconds:.2f} s)")
    return 0
