"""Peak memory of ``sswjax.match`` in fresh processes: by preset, input scale and disparity
chunk, and over many sizes to fit the memory guard's model.

``peaks`` (the default when no subcommand is named)
    A Q pair (MiddEval3 trainingQ, default Motorcycle) is upsampled by ``--scale`` (2 = H, 4 =
    the full-resolution size, 2964 x 1988) and matched with ``disparity_chunk`` = 0 (whole
    volume) or K (default 4), over the scene's disparities times the scale (Motorcycle at 4:
    760) or ``--ndisp``; ``--max-memory GB`` lets the planner choose strips or tiles within
    that bound, as ``sswjax match --max-memory`` does. The child's peak RSS, wall time and
    rows per strip are printed and written to ``memory.md`` in ``-o``.
``fit``
    Each configuration of :data:`CONFIGS` (size, disparities, preset, parameter changes) runs
    in a fresh process that reads trainingQ's Motorcycle (tiled or cropped to the size, uint8
    RGB as ``sswjax match`` reads it) and matches it; its peak RSS (``ru_maxrss``) is
    recorded. The fit is non-negative least squares of the peaks on the terms of
    :func:`sswjax.runtime.memory.memory_terms`, weighted by 1 / peak (relative errors); the
    coefficients, with the margin that puts every estimate above its measurement, are printed
    for ``sswjax/runtime/memory.py``. A configuration's changes are stages and dotted options
    (``segments``, ``optimizer.dtype``) or execution-plan fields (``strip_rows``,
    ``disparity_chunk``). Writes
    ``memory_model.{md,csv}``; ``--measured CSV`` refits earlier measurements.

    python benchmarks/memory.py [peaks] [--data DIR] [--presets paper accurate]
        [--scene Motorcycle] [--scales 1 4] [--chunks 0 4] [--ndisp N] [--max-memory GB]
        [--strip-rows R] [-o benchmarks/results]
    python benchmarks/memory.py fit [--only-fit --measured benchmarks/results/memory_model.csv]
        [-o benchmarks/results]

Issue 25's full-resolution shape (2964 x 1988 x 280, within 6 GB):
``python benchmarks/memory.py --presets accurate fast --scales 4 --chunks 4 --ndisp 280
--max-memory 6``. The fit measures for about ten minutes on a 2-core machine.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import sswjax
from sswjax.runtime import memory
from sswjax.runtime.memory import COEFFICIENTS, memory_terms
from sswjax.runtime.plan import split_settings

from _report import write_report  # benchmarks/: on the path as a script

COMMANDS = ("peaks", "fit")

PEAKS_CHILD = r"""
import json, resource, sys, time
import numpy as np
import sswjax
from sswjax.data.layouts import find_data_root, load_scenes
from sswjax.runtime.memory import plan_for_memory
from sswjax.runtime.plan import ExecutionPlan

scene_name, scale, chunk, preset, strips, data, ndisp, bound = sys.argv[1:]
scale, chunk, strips, ndisp, bound = int(scale), int(chunk), int(strips), int(ndisp), float(bound)
scene = load_scenes(find_data_root(data=data), scenes=[scene_name])[0]
left, right = (np.repeat(np.repeat(im, scale, axis=0), scale, axis=1) for im in (scene.left, scene.right))
ndisp = ndisp or scene.ndisp * scale
params = sswjax.preset(preset)
plan = ExecutionPlan(strip_rows=strips, disparity_chunk=chunk)
if bound:
    plan = plan_for_memory(*left.shape[:2], ndisp, params=params, plan=plan, limit=bound * 1e9)
start = time.perf_counter()
disparity = sswjax.match(left, right, ndisp, params=params, plan=plan)
seconds = time.perf_counter() - start
print(json.dumps({"shape": list(disparity.shape), "ndisp": ndisp, "seconds": seconds,
                  "strip_rows": plan.strip_rows, "tile": plan.tile,
                  "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6}))
"""

FIT_CHILD = r"""
import json, resource, sys
import numpy as np
import sswjax
from sswjax.data.io import read_image
from sswjax.data.layouts import find_data_root
from sswjax.runtime.plan import split_settings

height, width, ndisp, preset, changes = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], json.loads(sys.argv[5])
scene = find_data_root() / "trainingQ" / "Motorcycle"
left, right = (read_image(scene / name) for name in ("im0.png", "im1.png"))
left, right = (np.resize(im, (height, width, 3)) if im.shape[:2] != (height, width) else im for im in (left, right))
params, plan = split_settings(sswjax.preset(preset), changes)
sswjax.match(left, right, ndisp, params=params, plan=plan)
print(json.dumps({"peak": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}))
"""

# (height, width, ndisp, preset, parameter changes): Motorcycle Q, Vintage Q's size, the H and
# full-resolution sizes, tiny sizes (the constant), chunks, strips, the int16 storage, 8 paths,
# no SLIC, the band, the window of a tile of 1024 with 256 disparities (1216 x 1728), and fast
# (coarse-to-fine: its full-resolution stages are the window term).
CONFIGS = [
    (64, 96, 16, "paper", {}),
    (64, 96, 16, "accurate", {}),
    (497, 741, 70, "paper", {}),
    (480, 722, 190, "paper", {}),
    (497, 741, 70, "paper", {"disparity_chunk": 16}),
    (497, 741, 70, "paper", {"disparity_chunk": 0}),
    (497, 741, 70, "paper", {"segments": None}),
    (994, 1482, 140, "paper", {}),
    (994, 1482, 140, "paper", {"strip_rows": 128}),
    (497, 741, 70, "accurate", {}),
    (480, 722, 190, "accurate", {}),
    (497, 741, 140, "accurate", {}),
    (497, 741, 70, "accurate", {"optimizer.dtype": "int16"}),
    (480, 722, 190, "accurate", {"optimizer.dtype": "int16"}),
    (994, 1482, 140, "accurate", {"optimizer.dtype": "int16"}),
    (497, 741, 70, "accurate", {"optimizer.paths": 8}),
    (497, 741, 70, "accurate", {"disparity_chunk": 0}),
    (480, 722, 190, "accurate", {"strip_rows": 160}),
    (994, 1482, 140, "accurate", {"strip_rows": 64}),
    (994, 1482, 140, "accurate", {}),
    (1988, 2964, 280, "paper", {}),
    (1988, 2964, 280, "accurate", {"strip_rows": 64}),
    (497, 741, 70, "balanced", {}),
    (480, 722, 190, "balanced", {}),
    (994, 1482, 140, "balanced", {}),
    (1216, 1728, 256, "accurate", {}),
    (994, 1482, 280, "accurate", {}),
    (64, 96, 16, "fast", {}),
    (497, 741, 70, "fast", {}),
    (480, 722, 190, "fast", {}),
    (994, 1482, 140, "fast", {}),
    (1216, 1728, 256, "fast", {}),
    (1988, 2964, 280, "fast", {}),
]

TINY = 10_000  # pixels: pairs this small measure the compile floor, not the terms
KEYS = ("height", "width", "ndisp", "preset", "changes", "peak")


def measure(height, width, ndisp, preset, changes) -> int:
    """Peak RSS in bytes of a fresh process matching one pair of this size."""
    run = subprocess.run([sys.executable, "-c", FIT_CHILD, str(height), str(width), str(ndisp), preset,
                          json.dumps(changes)], capture_output=True, text=True, check=True)
    return int(json.loads(run.stdout.strip().splitlines()[-1])["peak"])


def fit(rows):
    """Non-negative least squares of the peaks on the model's terms, relative errors."""
    from scipy.optimize import nnls

    names = list(COEFFICIENTS)
    design, peaks = [], []
    for row in rows:
        if row["height"] * row["width"] < TINY:
            continue
        params, plan = split_settings(sswjax.preset(row["preset"]), row["changes"])
        terms = memory_terms(row["height"], row["width"], row["ndisp"], params=params, plan=plan)
        design.append([terms[n] for n in names])
        peaks.append(row["peak"])
    design, peaks = np.array(design), np.array(peaks, float)
    coefficients, _ = nnls(design / peaks[:, None], np.ones(len(peaks)))
    return dict(zip(names, coefficients))


def peaks(args) -> int:
    """The ``peaks`` subcommand."""
    lines = []

    def emit(line):
        print(line, flush=True)
        lines.append(line)

    emit(f"strip_rows {args.strip_rows}, max memory {args.max_memory or 'none'} GB")
    emit("| preset | scale | W x H x D | disparity_chunk | rows per strip / tile | "
         "first call s (compile + run) | peak RSS GB |")
    emit("|---|---|---|---|---|---|---|")
    for preset in args.presets:
        for scale in args.scales:
            for chunk in args.chunks:
                if scale >= 4 and chunk == 0:
                    emit(f"| {preset} | {scale} | | 0 | | skipped: the whole volume needs > 20 GB | |")
                    continue
                start = time.perf_counter()
                run = subprocess.run([sys.executable, "-c", PEAKS_CHILD, args.scene, str(scale), str(chunk),
                                      preset, str(args.strip_rows),
                                      str(args.data / "MiddEval3" / "trainingQ"),
                                      str(args.ndisp), str(args.max_memory)],
                                     capture_output=True, text=True)
                if run.returncode != 0:
                    reason = (run.stderr.strip().splitlines() or [f"exit {run.returncode}"])[-1]
                    emit(f"| {preset} | {scale} | | {chunk} | | failed: {reason} | |")
                    continue
                result = json.loads(run.stdout.strip().splitlines()[-1])
                h, w = result["shape"]
                cut = (f"{result['strip_rows']} rows" if result["strip_rows"] else
                       f"{result['tile']} px tiles" if result["tile"] else "whole")
                emit(f"| {preset} | {scale} | {w} x {h} x {result['ndisp']} | {chunk} | {cut} | "
                     f"{time.perf_counter() - start:.1f} | {result['peak_rss_gb']:.2f} |")
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "memory.md").write_text("\n".join(lines) + "\n")
    return 0


def fit_model(args) -> int:
    """The ``fit`` subcommand."""
    rows = []
    if args.measured is not None:
        with open(args.measured) as handle:
            for row in csv.DictReader(handle):
                rows.append({"height": int(row["height"]), "width": int(row["width"]),
                             "ndisp": int(row["ndisp"]), "preset": row["preset"],
                             "changes": json.loads(row["changes"]), "peak": int(row["peak"])})
    if not args.only_fit:
        for height, width, ndisp, preset, changes in CONFIGS:
            try:
                peak = measure(height, width, ndisp, preset, changes)
            except subprocess.CalledProcessError as error:
                print(f"{width} x {height} x {ndisp} {preset} {changes}: failed: "
                      f"{(error.stderr.strip().splitlines() or ['?'])[-1]}", flush=True)
                continue
            print(f"{width} x {height} x {ndisp} {preset} {changes}: {peak / 1e9:.2f} GB", flush=True)
            rows.append({"height": height, "width": width, "ndisp": ndisp, "preset": preset,
                         "changes": changes, "peak": peak})
    memory.COEFFICIENTS.update(fit(rows))
    floor = {"none": 0.0, "sgm": 0.0}
    for row in rows:
        if row["height"] * row["width"] < TINY:
            key = "none" if sswjax.preset(row["preset"]).optimizer is None else "sgm"
            floor[key] = max(floor[key], row["peak"])
    memory.COMPILE_FLOOR.update(floor)
    memory.MARGIN, memory.SLACK = 1.0, 0
    fitted = np.array([memory.estimate_peak_bytes(
        r["height"], r["width"], r["ndisp"],
        **dict(zip(("params", "plan"), split_settings(sswjax.preset(r["preset"]), r["changes"]))))
        for r in rows], float)
    ratios = np.array([row["peak"] for row in rows]) / fitted
    print("COEFFICIENTS =", {k: float(f"{v:.4g}") for k, v in memory.COEFFICIENTS.items()})
    print("COMPILE_FLOOR =", floor)
    print(f"measured / fitted: {ratios.min():.3f} .. {ratios.max():.3f} (MARGIN >= the largest)")
    table = ["| W x H x D | preset | changes | measured GB | fitted GB |", "|---|---|---|---|---|"]
    table += [f"| {r['width']} x {r['height']} x {r['ndisp']} | {r['preset']} | "
              f"{json.dumps(r['changes'])} | {r['peak'] / 1e9:.2f} | {f / 1e9:.2f} |"
              for r, f in zip(rows, fitted)]
    write_report(args.output, "memory_model", "\n".join(table),
                 [{**r, "changes": json.dumps(r["changes"])} for r in rows], KEYS)
    return 0


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in (*COMMANDS, "-h", "--help"):
        argv = ["peaks", *argv]  # the table by scale, as this script ran before it fitted
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    sub = commands.add_parser("peaks", help="peak memory by preset, scale and chunk")
    sub.add_argument("--data", type=Path, default=Path(os.environ.get(
        "SSWJAX_DATA", Path(__file__).resolve().parents[2] / "shared" / "data")),
        help="the data folder holding MiddEval3/trainingQ (default: SSWJAX_DATA, ../shared/data)")
    sub.add_argument("--presets", nargs="+", default=("paper",))
    sub.add_argument("--scene", default="Motorcycle")
    sub.add_argument("--strip-rows", type=int, default=0,
                        help="match in strips of this many rows (ExecutionPlan.strip_rows; 0: whole)")
    sub.add_argument("--scales", type=int, nargs="+", default=(1, 4))
    sub.add_argument("--chunks", type=int, nargs="+", default=(0, 4))
    sub.add_argument("--ndisp", type=int, default=0,
                        help="disparities of the scaled pair (0: the scene's times the scale)")
    sub.add_argument("--max-memory", type=float, default=0.0, metavar="GB",
                        help="strips or tiles chosen by the planner within this bound (0: none)")
    sub.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    sub = commands.add_parser("fit", help="peaks over many sizes, and the guard's model fitted")
    sub.add_argument("--measured", type=Path, help="CSV of earlier measurements to refit")
    sub.add_argument("--only-fit", action="store_true", help="no new measurement")
    sub.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args(argv)
    return peaks(args) if args.command == "peaks" else fit_model(args)


if __name__ == "__main__":
    sys.exit(main())
