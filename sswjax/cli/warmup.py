"""``sswjax warmup --size 741x497 --ndisp 70``: compile now what later runs will need.

Every image shape compiles a graph of its own (seconds). ``sswjax warmup`` compiles, for each
shape named (``--size WxH``, or ``--like`` images whose headers give the size and whether they
are gray), the graph that ``sswjax match`` with the same range, parameters and plan options will
run, and keeps it in the persistent compilation cache with its trace
(:mod:`sswjax.runtime.stored`): a later ``sswjax match`` of that shape, in a new process, starts
without tracing or compiling. ``--confidence`` warms the graph of the runs that write
``--confidence``, ``--validity`` or ``--invalid-as-inf`` instead; ``--bucket`` the bucketed
shape of a folder run that pads its pairs (:class:`sswjax.ShapeBuckets`).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

from sswjax.api.warmup import warm_up
from sswjax.cli.common import gigabytes, raise_if_interrupted
from sswjax.cli.folders import IMAGE_SUFFIXES, image_size
from sswjax.cli.guard import guard_memory
from sswjax.cli.options import (add_parameter_options, add_plan_options, params_from_args,
                                plan_from_args)
from sswjax.runtime.buckets import ShapeBuckets

__all__ = ["add_warmup_command", "image_shape", "run_warmup"]

_SIZE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")


def image_shape(text: str) -> tuple[int, int]:
    """argparse type of ``--size``: ``WxH`` (width first, as image viewers say) -> ``(H, W)``.

    Examples
    --------
    >>> image_shape("741x497")
    (497, 741)
    """
    found = _SIZE.match(text)
    if found is None or min(int(found[1]), int(found[2])) < 1:
        raise argparse.ArgumentTypeError(f"a size is WIDTHxHEIGHT, e.g. 741x497, got {text!r}")
    return int(found[2]), int(found[1])


def add_warmup_command(commands) -> None:
    """Add the ``warmup`` sub-command to ``commands`` (argparse's sub-parsers)."""
    parser = commands.add_parser(
        "warmup", help="compile ahead of time, into the persistent cache, the graphs that "
                       "sswjax match will run on pairs of the sizes named")
    parser.add_argument("--size", type=image_shape, action="append", default=[],
                        metavar="WxH", help="an image size to compile for (repeat for more)")
    parser.add_argument("--like", type=Path, action="append", default=[], metavar="IMAGE",
                        help="compile for this image's size and colour (or every image of a "
                             "folder; repeat for more)")
    parser.add_argument("--gray", action="store_true",
                        help="the --size pairs are gray (one channel); default colour")
    parser.add_argument("--ndisp", type=int, required=True, metavar="N",
                        help="disparities searched, as sswjax match's --ndisp")
    parser.add_argument("--min-disp", type=int, default=0, metavar="M",
                        help="first disparity, as sswjax match's --min-disp (default 0)")
    parser.add_argument("--confidence", action="store_true",
                        help="warm the runs that write --confidence, --validity or "
                             "--invalid-as-inf (a graph of their own)")
    parser.add_argument("--bucket", action="store_true",
                        help="warm the bucketed shapes a folder run with --bucket pads to")
    parser.add_argument("--max-memory", type=gigabytes, metavar="GB",
                        help="as sswjax match's: the plan (strips, tiles) it leads to is warmed")
    add_parameter_options(parser, "the")
    add_plan_options(parser)
    parser.set_defaults(run=run_warmup)


def _shapes(args: argparse.Namespace) -> list[tuple[int, int, int]]:
    """Every ``(H, W, C)`` asked for, in order, each once."""
    channels = 1 if args.gray else 3
    shapes = [(height, width, channels) for height, width in args.size]
    for path in args.like:
        if path.is_dir():
            images = [p for p in sorted(path.iterdir()) if p.suffix.lower() in IMAGE_SUFFIXES]
            if not images:
                raise ValueError(f"--like {path}: no images in this folder")
            shapes.extend(image_size(image) for image in images)
        else:
            shapes.append(image_size(path))
    if not shapes:
        raise ValueError("name the sizes to compile for: --size WxH or --like IMAGE")
    return list(dict.fromkeys(shapes))


def run_warmup(args: argparse.Namespace) -> int:
    """``sswjax warmup``: compile for every shape asked; returns the exit status (0)."""
    if getattr(args, "no_cache", False):
        raise ValueError("warmup fills the persistent compilation cache: without it "
                         "(--no-cache) nothing would be kept")
    if args.workers is not None or args.scheduler is not None:
        raise ValueError("warmup compiles in this process: a cluster's workers share the "
                         "cache folder ($SSWJAX_CACHE_DIR), warm it from one machine")
    if args.ndisp < 1:
        raise ValueError(f"--ndisp must be >= 1, got {args.ndisp}")
    shapes = _shapes(args)
    params = params_from_args(args)
    buckets = ShapeBuckets() if args.bucket else None
    asked = plan_from_args(args, buckets=buckets)
    plans = [guard_memory([shape], args.ndisp, params=params, plan=asked,
                          limit_gb=args.max_memory, min_disp=args.min_disp) for shape in shapes]
    total = time.perf_counter()
    for shape, plan in zip(shapes, plans):  # every shape checked before the first compiles
        start = time.perf_counter()
        height, width, channels = shape
        warm_up((height, width, channels), args.ndisp, min_disp=args.min_disp, params=params,
                plan=plan, confidence=args.confidence, check_memory=False)
        print(f"warmed {width}x{height}{' gray' if channels == 1 else ''}, disparities "
              f"{args.min_disp}..{args.min_disp + args.ndisp - 1}: "
              f"{time.perf_counter() - start:.1f} s", file=sys.stderr)
        raise_if_interrupted()  # a Ctrl-C that JAX's gc callback dropped
    print(f"compiled {len(shapes)} shape{'s' if len(shapes) > 1 else ''} in "
          f"{time.perf_counter() - total:.1f} s")
    return 0
