"""What the smoothing costs inside a preset's call: the whole call with the square window, with
the separable one (two and three passes) and without smoothing, alternating in one process.

Each variant is one ``sswjax.match`` of a MiddEval3 trainingQ pair at its exact shape, warmed
once, then run ``--repeats`` times in turns with the others; the best run of each is reported,
and the stage's cost is a variant's time minus the time without smoothing.

    python benchmarks/smoothing_time.py [--data ../shared/data] [--scenes Motorcycle Teddy]
                                        [--presets fast accurate] [--repeats 7]
                                        [-o benchmarks/results/smoothing/separable]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import sswjax
from sswjax.data.layouts import load_scenes

from _report import write_report  # benchmarks/, on the path when run as a script
from smoothing import _table


def variants(params: sswjax.Params) -> dict[str, sswjax.Params]:
    """The preset's smoothing as a square, separable with two and three passes, and none."""
    smoothing = params.smoothing
    return {"square, 2 passes": params.replace(
                smoothing=smoothing.replace(separable=False, iterations=2)),
            "separable, 2 passes": params.replace(
                smoothing=smoothing.replace(separable=True, iterations=2)),
            "separable, 3 passes": params.replace(
                smoothing=smoothing.replace(separable=True, iterations=3)),
            "none": params.replace(smoothing=None)}


def best_seconds(scene, runs: dict[str, sswjax.Params], repeats: int) -> dict[str, float]:
    """Best wall time of each variant's call on ``scene``, the variants taking turns."""
    for params in runs.values():  # compile and warm
        np.asarray(sswjax.match(scene.left, scene.right, scene.ndisp, params=params))
    times = {name: [] for name in runs}
    for _ in range(repeats):
        for name, params in runs.items():
            start = time.perf_counter()
            np.asarray(sswjax.match(scene.left, scene.right, scene.ndisp, params=params))
            times[name].append(time.perf_counter() - start)
    return {name: min(values) for name, values in times.items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data")
    parser.add_argument("--scenes", nargs="+", default=["Motorcycle", "Teddy"])
    parser.add_argument("--presets", nargs="+", default=["fast", "accurate"])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("-o", "--output", type=Path,
                        default=Path("benchmarks/results/smoothing/separable"))
    args = parser.parse_args(argv)
    scenes = [s for s in load_scenes(args.data / "MiddEval3") if s.name in args.scenes]
    if not scenes:
        parser.error(f"none of {args.scenes} under {args.data / 'MiddEval3'}")
    rows = []
    for preset in args.presets:
        runs = variants(sswjax.preset(preset))
        for scene in scenes:
            best = best_seconds(scene, runs, args.repeats)
            for name, seconds in best.items():
                rows.append({"preset": preset, "scene": scene.name, "smoothing": name,
                             "call ms": round(1000 * seconds),
                             "stage ms": round(1000 * (seconds - best["none"]))})
            print(preset, scene.name, best, file=sys.stderr, flush=True)
    write_report(args.output, "time", _table(rows), rows, list(rows[0]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
