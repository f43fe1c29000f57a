"""Peak memory of SSW by preset, input scale and disparity chunk, each run in a fresh process.

A Q pair (MiddEval3 trainingQ, default Motorcycle) is upsampled by ``--scale`` (2 = H, 4 = the
full-resolution size, 2964 x 1988) and matched with ``disparity_chunk`` = 0 (whole volume) or K
(default 4), over the scene's disparities times the scale (Motorcycle at 4: 760) or
``--ndisp``; ``--max-memory GB`` lets the planner choose strips or tiles within that bound, as
``sswjax match --max-memory`` does. The child's peak RSS, wall time and rows per strip are
reported, printed and written to ``memory.md`` in ``-o`` (default ``benchmarks/results``).

    python benchmarks/memory.py [--data DIR] [--presets paper accurate] [--scene Motorcycle]
                                [--scales 1 4] [--chunks 0 4] [--ndisp N] [--max-memory GB]
                                [--strip-rows R] [-o DIR]

Issue 25's full-resolution shape (2964 x 1988 x 280, within 6 GB):
``python benchmarks/memory.py --presets accurate fast --scales 4 --chunks 4 --ndisp 280
--max-memory 6``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

CHILD = r"""
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(os.environ.get(
        "SSWJAX_DATA", Path(__file__).resolve().parents[2] / "shared" / "data")),
        help="the data folder holding MiddEval3/trainingQ (default: SSWJAX_DATA, ../shared/data)")
    parser.add_argument("--presets", nargs="+", default=("paper",))
    parser.add_argument("--scene", default="Motorcycle")
    parser.add_argument("--strip-rows", type=int, default=0,
                        help="match in strips of this many rows (ExecutionPlan.strip_rows; 0: whole)")
    parser.add_argument("--scales", type=int, nargs="+", default=(1, 4))
    parser.add_argument("--chunks", type=int, nargs="+", default=(0, 4))
    parser.add_argument("--ndisp", type=int, default=0,
                        help="disparities of the scaled pair (0: the scene's times the scale)")
    parser.add_argument("--max-memory", type=float, default=0.0, metavar="GB",
                        help="strips or tiles chosen by the planner within this bound (0: none)")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
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
                run = subprocess.run([sys.executable, "-c", CHILD, args.scene, str(scale), str(chunk),
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


if __name__ == "__main__":
    main()
