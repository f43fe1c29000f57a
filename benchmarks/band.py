"""The full-resolution band (``params.band``): configurations scored on the three data sets at
bad 2.0, 1.0 and 0.5 and the average error, timed against SGBM, and the held-out choice.

Each configuration is written as for ``benchmarks/ablation.py`` (``NAME=BASE:JSON``, BASE a
preset or a parameter file); ``--peer`` adds another project's matcher (OpenCV SGBM, Pandora). Every pair runs at its exact shape (``sswjax.match``, no buckets:
the band's precision is what is measured, and buckets change the borders). Time: on the first
``--timed`` pairs of trainingQ each configuration alternates with OpenCV SGBM 3-way, best of
three each, and the median of the per-pair ratios is reported (the protocol of issue 25).
Rows are in ``benchmarks/smoothing.py``'s CSV format; the held-out rule of
``benchmarks/held_out.py`` chooses on bad 2.0 and, separately, on the three thresholds.

    python benchmarks/band.py --config fast --config \\
        'band7=accurate:{"coarse": {"kind": "halving", "levels": 1}, "band": {"kind": "around-map"}}'
        [--data ../shared/data] [--timed 5] [--time-only] [-o benchmarks/results/band]
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path

import numpy as np

import sswjax
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.methods import PEERS
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.evaluation.peers import sgbm_disparity
from sswjax.evaluation.runner import SCORINGS, _average
from sswjax.runtime.compilation import enable_compilation_cache

from _report import write_report  # benchmarks/, on the path when run as a script
from ablation import parse_config
from smoothing import KEYS, SETS, _table, write_held_out


def _seconds(fn) -> float:
    start = time.perf_counter()
    np.asarray(fn())
    return time.perf_counter() - start


def time_ratio(run, scenes) -> float:
    """Median over ``scenes`` of (best of three warm ``run(left, right, ndisp)``) / (best of
    three SGBM), the two alternating pair by pair."""
    ratios = []
    for scene in scenes:
        args = (scene.left, scene.right, scene.ndisp)
        run(*args)  # compilation
        sgbm_disparity(*args)
        times = {"ours": [], "sgbm": []}
        for _ in range(3):
            times["ours"].append(_seconds(lambda: run(*args)))
            times["sgbm"].append(_seconds(lambda: sgbm_disparity(*args)))
        ratios.append(min(times["ours"]) / min(times["sgbm"]))
    return float(np.median(ratios))


def score(run, set_name: str, data: Path) -> dict[str, float]:
    """The row's columns of one set for the matcher ``run(left, right, ndisp)``:
    ``"{set} {key} {region}"`` -> its average."""
    folder, scoring_name, regions = SETS[set_name]
    scoring = SCORINGS[scoring_name]
    metrics = {}
    for scene in load_scenes(data / folder):
        disparity = np.asarray(run(scene.left, scene.right, scene.ndisp))
        metrics[scene.name] = evaluate_disparity(disparity, scene.ground_truth, mask=scene.mask,
                                                 ndisp=scene.ndisp, thresholds=(2.0, 1.0, 0.5))
    return {f"{set_name} {key} {region}": _average(
        {s: m[region][key] for s, m in metrics.items() if region in m}, scoring)
        for region in regions for key in KEYS}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", action="append", default=[],
                        help="NAME=BASE:JSON (BASE a preset or a parameter file); repeatable")
    parser.add_argument("--peer", action="append", default=[], choices=list(PEERS),
                        help="a peer scored and timed the same way (sgbm, pandora, ...)")
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data")
    parser.add_argument("--timed", type=int, default=5,
                        help="trainingQ pairs timed against SGBM (0: no timing)")
    parser.add_argument("--time-only", action="store_true",
                        help="only the timing against SGBM, no scoring (report times.md)")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results/band"))
    args = parser.parse_args(argv)
    enable_compilation_cache()
    runs = {name: functools.partial(sswjax.match, params=params)
            for name, params in map(parse_config, args.config)}
    runs.update({name: PEERS[name].fn for name in args.peer})
    if not runs:
        parser.error("give at least one --config or --peer")
    timed = load_scenes(args.data / "MiddEval3")[:args.timed]
    rows = []
    for name, run in runs.items():
        row = {"config": name}
        for set_name in () if args.time_only else SETS:
            row.update(score(run, set_name, args.data))
            print(name, set_name, file=sys.stderr, flush=True)
        row["x SGBM"] = time_ratio(run, timed) if timed else float("nan")
        rows.append(row)
        # after every configuration: a run stopped halfway keeps what it measured
        write_report(args.output, "times" if args.time_only else "band", _table(rows), rows,
                     list(rows[0]))
    if len(rows) > 1 and not args.time_only:
        write_held_out(args.output, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
