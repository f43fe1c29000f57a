"""Score parameter sets on the three data sets at once: the README's ablation table.

Each configuration is a preset (``sswjax.preset``) or a parameter file, with changes on top,
run over MiddEval3 trainingQ (weighted bad 2.0 / 1.0 / 0.5, nonocc and all), the KITTI 2012 pairs
(mean bad 2.0 and 3.0) and Middlebury 2001 (mean bad 2.0), with the median warm time per pair.
Pairs run through shape buckets (``--bucket-step``), so every data set compiles a few times
only; the bucketed maps differ from exact-shape ones only near the bottom and right borders.

    python benchmarks/ablation.py --config accurate --config 'no-sgm=accurate:{"optimizer": "none"}'
    python benchmarks/ablation.py --config paper --sets trainingQ --scenes Teddy ArtL

``--config NAME=BASE:JSON`` (or just a preset name) names a row; ``BASE`` is a preset name or
a parameter file. Writes Markdown and CSV (``-o``, default ``benchmarks/results/ablation``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

import sswjax
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.evaluation.runner import SCORINGS, _average

from _report import write_report  # benchmarks/, on the path when run as a script

SETS = {  # name -> (folder under the data root, scoring, reported columns)
    "trainingQ": ("MiddEval3", "middeval3",
                  [("nonocc", "bad2.0"), ("all", "bad2.0"), ("nonocc", "bad1.0"), ("all", "bad1.0"),
                   ("nonocc", "bad0.5"), ("all", "bad0.5")]),
    "KITTI2012": ("KITTI2012", "kitti", [("all", "bad2.0"), ("all", "bad3.0")]),
    "Middlebury2001": ("Middlebury2001", "mean", [("all", "bad2.0")]),
}


def parse_config(text: str) -> tuple[str, sswjax.Params]:
    """``NAME=BASE:JSON``, ``NAME=BASE`` or ``BASE`` -> (row name, parameters)."""
    name, _, spec = text.partition("=") if "=" in text else (text, "", text)
    base, _, changes = spec.partition(":")
    params = sswjax.preset(base) if base in sswjax.PRESETS else sswjax.load_params(base)
    return name, params.replace(**json.loads(changes)) if changes else params


def run_set(params, scenes, buckets, scoring, *, warm=True):
    """Per-scene metrics and the median time per pair: warm (each pair run twice, the second
    timed) or, with ``warm=False``, of the only run (compilation included)."""
    metrics, times = {}, []
    for scene in scenes:
        if warm:
            sswjax.match(scene.left, scene.right, scene.ndisp, params=params, buckets=buckets)
        start = time.perf_counter()
        disparity = sswjax.match(scene.left, scene.right, scene.ndisp, params=params,
                                 buckets=buckets)
        times.append(time.perf_counter() - start)
        metrics[scene.name] = evaluate_disparity(
            disparity, scene.ground_truth, mask=scene.mask, ndisp=scene.ndisp,
            thresholds=scoring.thresholds)
    return metrics, float(np.median(times))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", action="append", required=True,
                        help="NAME=BASE:JSON (BASE a preset or a parameter file); repeatable")
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data", help="folder holding the three data sets")
    parser.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    parser.add_argument("--scenes", nargs="+", help="only these scenes (of every set)")
    parser.add_argument("--bucket-step", type=int, default=64,
                        help="image sizes rounded up to this multiple (disparities to 32)")
    parser.add_argument("--cold", action="store_true",
                        help="run each pair once (faster; times then include compilation)")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results/ablation"))
    args = parser.parse_args(argv)
    configs = [parse_config(text) for text in args.config]
    buckets = ShapeBuckets(size_step=args.bucket_step, ndisp_step=32)
    rows = []
    for set_name in args.sets:
        folder, scoring_name, _ = SETS[set_name]
        scoring = SCORINGS[scoring_name]
        scenes = [s for s in load_scenes(args.data / folder)
                  if not args.scenes or s.name in args.scenes]
        if not scenes:
            continue
        for k, (name, params) in enumerate(configs):
            metrics, seconds = run_set(params, scenes, buckets, scoring, warm=not args.cold)
            if len(rows) <= k:
                rows.append({"config": name})
            for region, key in SETS[set_name][2]:
                values = {s: m[region][key] for s, m in metrics.items() if region in m}
                rows[k][f"{set_name} {key} {region}"] = _average(values, scoring)
            rows[k][f"{set_name} s/pair"] = seconds
            print(name, set_name, {k2: round(v, 2) for k2, v in rows[k].items() if k2 != "config"
                                   and k2.startswith(set_name)}, file=sys.stderr, flush=True)
    keys = ["config"] + [k for k in rows[0] if k != "config"]
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for row in rows:
        lines.append("| " + " | ".join(row[k] if k == "config" else f"{row[k]:.2f}" for k in keys)
                     + " |")
    write_report(args.output, "ablation", "\n".join(lines), rows, keys)
    return 0


if __name__ == "__main__":
    sys.exit(main())
