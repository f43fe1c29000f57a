"""The full-resolution band (``params.band``): configurations scored on the three data sets at
bad 2.0, 1.0 and 0.5 and the average error, timed against SGBM, and the held-out choice.

Each configuration is written as for ``benchmarks/ablation.py`` (``NAME=BASE:JSON``, BASE a
preset or a parameter file). Every pair runs at its exact shape (``sswjax.match``, no buckets:
the band's precision is what is measured, and buckets change the borders). Time: on the first
``--timed`` pairs of trainingQ each configuration alternates with OpenCV SGBM 3-way, best of
three each, and the median of the per-pair ratios is reported (the protocol of issue 25).
Rows are in ``benchmarks/smoothing.py``'s CSV format; the held-out rule of
``benchmarks/held_out.py`` chooses on bad 2.0 and, separately, on the three thresholds.

    python benchmarks/band.py --config fast --config \\
        'band7=accurate:{"coarse": {"kind": "halving", "levels": 1}, "band": {"kind": "around-map"}}'
        [--data ../shared/data] [--timed 5] [-o benchmarks/results/band]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import sswjax
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.evaluation.peers import sgbm_disparity
from sswjax.evaluation.runner import SCORINGS, _average
from sswjax.runtime.compilation import enable_compilation_cache

from _report import write_report  # benchmarks/, on the path when run as a script
from ablation import parse_config
from smoothing import KEYS, SETS, _table, write_held_out


def _best_of(fn, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        np.asarray(fn())
        times.append(time.perf_counter() - start)
    return min(times)


def time_ratio(params, scenes) -> float:
    """Median over ``scenes`` of (best of three warm ``sswjax.match``) / (best of three SGBM),
    the two alternating pair by pair."""
    ratios = []
    for scene in scenes:
        args = (scene.left, scene.right, scene.ndisp)
        ours = lambda: sswjax.match(*args, params=params)  # noqa: E731
        ours()  # compilation
        sgbm_disparity(*args)
        times = {"ours": [], "sgbm": []}
        for _ in range(3):
            times["ours"].append(_best_of(ours, 1))
            times["sgbm"].append(_best_of(lambda: sgbm_disparity(*args), 1))
        ratios.append(min(times["ours"]) / min(times["sgbm"]))
    return float(np.median(ratios))


def score(params, set_name: str, data: Path) -> dict[str, float]:
    """The row's columns of one set: ``"{set} {key} {region}"`` -> its average."""
    folder, scoring_name, regions = SETS[set_name]
    scoring = SCORINGS[scoring_name]
    metrics = {}
    for scene in load_scenes(data / folder):
        disparity = sswjax.match(scene.left, scene.right, scene.ndisp, params=params)
        metrics[scene.name] = evaluate_disparity(disparity, scene.ground_truth, mask=scene.mask,
                                                 ndisp=scene.ndisp, thresholds=(2.0, 1.0, 0.5))
    return {f"{set_name} {key} {region}": _average(
        {s: m[region][key] for s, m in metrics.items() if region in m}, scoring)
        for region in regions for key in KEYS}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", action="append", required=True,
                        help="NAME=BASE:JSON (BASE a preset or a parameter file); repeatable")
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data")
    parser.add_argument("--timed", type=int, default=5,
                        help="trainingQ pairs timed against SGBM (0: no timing)")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results/band"))
    args = parser.parse_args(argv)
    enable_compilation_cache()
    configs = [parse_config(text) for text in args.config]
    timed = load_scenes(args.data / "MiddEval3")[:args.timed]
    rows = []
    for name, params in configs:
        row = {"config": name}
        for set_name in SETS:
            row.update(score(params, set_name, args.data))
            print(name, set_name, file=sys.stderr, flush=True)
        row["x SGBM"] = time_ratio(params, timed) if timed else float("nan")
        rows.append(row)
    write_report(args.output, "band", _table(rows), rows, list(rows[0]))
    if len(rows) > 1:
        write_held_out(args.output, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
