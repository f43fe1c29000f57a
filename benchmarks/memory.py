"""Peak memory of SSW by preset, input scale and disparity chunk, each run in a fresh process.

A Q pair (MiddEval3 trainingQ, default Motorcycle) is upsampled by ``--scale`` (2 = H, 4 = the
full-resolution size, 2964 x 1988 with 280 disparities) and matched with
``disparity_chunk`` = 0 (whole volume) or K (default 4); the child's peak RSS and wall time are
reported, printed and written to ``benchmarks/results/memory.md``.

    python benchmarks/memory.py [--presets paper accurate] [--scene Motorcycle] [--scales 1 4]
                                [--chunks 0 4] [-o DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

CHILD = r"""
import json, resource, sys, time
import numpy as np
import sswjax
from sswjax.data.layouts import find_data_root, load_scenes
from sswjax.runtime.plan import ExecutionPlan

scene_name, scale, chunk, preset, strips = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], int(sys.argv[5])
scene = load_scenes(find_data_root(), scenes=[scene_name])[0]
left, right = (np.repeat(np.repeat(im, scale, axis=0), scale, axis=1) for im in (scene.left, scene.right))
plan = ExecutionPlan(strip_rows=strips, disparity_chunk=chunk)
start = time.perf_counter()
disparity = sswjax.match(left, right, scene.ndisp * scale, params=sswjax.preset(preset), plan=plan)
seconds = time.perf_counter() - start
print(json.dumps({"shape": list(disparity.shape), "ndisp": scene.ndisp * scale, "seconds": seconds,
                  "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=("paper",))
    parser.add_argument("--scene", default="Motorcycle")
    parser.add_argument("--strip-rows", type=int, default=0,
                        help="match in strips of this many rows (ExecutionPlan.strip_rows; 0: whole)")
    parser.add_argument("--scales", type=int, nargs="+", default=(1, 4))
    parser.add_argument("--chunks", type=int, nargs="+", default=(0, 4))
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    lines = []

    def emit(line):
        print(line, flush=True)
        lines.append(line)

    emit(f"strip_rows {args.strip_rows}")
    emit("| preset | scale | W x H x D | disparity_chunk | first call s (compile + run) | "
         "peak RSS GB |")
    emit("|---|---|---|---|---|---|")
    for preset in args.presets:
        for scale in args.scales:
            for chunk in args.chunks:
                if scale >= 4 and chunk == 0:
                    emit(f"| {preset} | {scale} | | 0 | skipped: the whole volume needs > 20 GB | |")
                    continue
                start = time.perf_counter()
                run = subprocess.run([sys.executable, "-c", CHILD, args.scene, str(scale), str(chunk),
                                      preset, str(args.strip_rows)], capture_output=True, text=True)
                if run.returncode != 0:
                    reason = (run.stderr.strip().splitlines() or [f"exit {run.returncode}"])[-1]
                    emit(f"| {preset} | {scale} | | {chunk} | failed: {reason} | |")
                    continue
                result = json.loads(run.stdout.strip().splitlines()[-1])
                h, w = result["shape"]
                emit(f"| {preset} | {scale} | {w} x {h} x {result['ndisp']} | {chunk} | "
                     f"{time.perf_counter() - start:.1f} | {result['peak_rss_gb']:.2f} |")
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "memory.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
