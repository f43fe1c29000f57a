"""``sswjax demo``: the Middlebury Motorcycle pair that scikit-image ships, scored against its
ground truth, the maps written as ``disp0SSW.pfm`` and ``disp0SSW.png`` in the ``-o`` folder
(created): both checked before the run (not the ``--params`` file, writable) and written
together, all or nothing."""

from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path

import numpy as np
import skimage.data

from sswjax._files import atomic_outputs, reason
from sswjax.api.match import match
from sswjax.cli.common import check_outputs, disparity_writers
from sswjax.cli.options import add_parameter_options, params_from_args, plan_from_args
from sswjax.evaluation.metrics import evaluate_disparity

__all__ = ["DEMO_NDISP", "add_demo_command", "run_demo"]

DEMO_NDISP = 70
"""Disparities of Middlebury Motorcycle at this resolution (MiddEval3 trainingQ calib.txt)."""


def add_demo_command(commands) -> None:
    """Add the ``demo`` sub-command to ``commands`` (argparse's sub-parsers)."""
    parser = commands.add_parser("demo", help="run on scikit-image's Middlebury Motorcycle pair")
    parser.add_argument("-o", "--output", type=Path, default=Path("sswjax-demo"),
                        help="output folder")
    add_parameter_options(parser, "the")
    parser.set_defaults(run=run_demo)


def run_demo(args: argparse.Namespace) -> int:
    """Match, score and write the demo pair; returns the exit status (0)."""
    out = args.output
    pfm, png = out / "disp0SSW.pfm", out / "disp0SSW.png"
    if out.exists() and not out.is_dir():
        raise ValueError(f"output {out} is a file: -o names the folder of the demo's maps")
    check_outputs({"the demo's map": pfm, "the demo's PNG": png} if out.is_dir() else {},
                  {"--params": args.params})
    params = params_from_args(args)
    plan = plan_from_args(args)
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create the output folder {out}: {reason(exc)}") from exc
    try:
        with atomic_outputs([pfm, png]) as files:  # destinations writable
            left, right, ground_truth = skimage.data.stereo_motorcycle()
            start = time.perf_counter()
            disparity = match(left, right, DEMO_NDISP, params=params, plan=plan)
            seconds = time.perf_counter() - start
            for path, write in disparity_writers(disparity, pfm, png, DEMO_NDISP).items():
                files.write(path, write)
    except BaseException:
        if created:  # the folder this run made goes with the maps it did not write
            with contextlib.suppress(OSError):
                out.rmdir()
        raise
    ground_truth = np.where(np.isfinite(ground_truth), ground_truth, np.inf).astype(np.float32)
    metrics = evaluate_disparity(disparity, ground_truth, ndisp=DEMO_NDISP)["all"]
    print(f"Motorcycle (scikit-image), {left.shape[1]}x{left.shape[0]}, ndisp {DEMO_NDISP}: "
          f"{seconds:.2f} s including compilation")
    print("bad-pixel error over pixels with known ground truth:")
    for threshold in ("2.0", "1.0", "0.5"):
        print(f"  bad {threshold}: {metrics['bad' + threshold]:6.2f} %")
    print(f"  avgerr  : {metrics['avgerr']:6.3f} px")
    print(f"wrote {out / 'disp0SSW.pfm'} and {out / 'disp0SSW.png'}")
    return 0
