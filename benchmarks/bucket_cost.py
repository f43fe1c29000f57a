"""What shape buckets cost in warm time: each preset at the pair's exact shape and padded to
its bucket, as ratios to OpenCV SGBM 3-way in the same run (issue 25's protocol: the first
``--timed`` trainingQ pairs, each alternating with SGBM, best of three, median of the per-pair
ratios).

A bucket pads the pair to a multiple of ``--size-step`` pixels and its range to a multiple of
``--ndisp-step`` disparities, and the graph treats the padding as the world beyond the pair's
edge (``sswjax/graph/padding.py``): the maps are the exact shape's, the time is not.

    python benchmarks/bucket_cost.py [--presets accurate balanced fast] [--timed 5]
        [--size-step 64] [--ndisp-step 32] [--data ../shared/data] [-o benchmarks/results/buckets]
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path

import sswjax
from sswjax.data.layouts import load_scenes

from _report import write_report  # benchmarks/, on the path when run as a script
from band import time_ratio


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=["accurate", "balanced", "fast"],
                        choices=list(sswjax.PRESETS))
    parser.add_argument("--timed", type=int, default=5, help="trainingQ pairs timed")
    parser.add_argument("--size-step", type=int, default=64)
    parser.add_argument("--ndisp-step", type=int, default=32)
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data")
    parser.add_argument("-o", "--output", type=Path,
                        default=Path(__file__).resolve().parent / "results" / "buckets")
    args = parser.parse_args(argv)
    scenes = load_scenes(args.data / "MiddEval3")[:args.timed]
    buckets = sswjax.ShapeBuckets(size_step=args.size_step, ndisp_step=args.ndisp_step)
    rows = []
    for preset in args.presets:
        row = {"preset": preset}
        for shape, chosen in (("exact", None), ("bucketed", buckets)):
            run = functools.partial(sswjax.match, params=sswjax.preset(preset), buckets=chosen)
            row[f"{shape} x sgbm"] = round(time_ratio(run, scenes), 2)
            print(row, flush=True)
        rows.append(row)
    keys = ["preset", "exact x sgbm", "bucketed x sgbm"]
    table = "\n".join(
        [f"Warm time as a ratio to OpenCV SGBM 3-way, first {len(scenes)} trainingQ pairs, "
         f"buckets of {args.size_step} px and {args.ndisp_step} disparities",
         "", "| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
        + ["| " + " | ".join(str(row[key]) for key in keys) + " |" for row in rows])
    write_report(args.output, "cost", table, rows, keys)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
