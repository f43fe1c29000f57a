"""What ``--ndisp auto`` costs: the estimated disparity range against the true one, on the sets.

For every scene of MiddEval3 trainingQ, KITTI 2012 (pairs 100-129) and Middlebury 2001, the
range of :func:`sswjax.api.auto_range.estimate_range` is compared with the scene's own
(``calib.txt``'s ``ndisp`` for MiddEval3, else the smallest multiple of 8 above the largest
true disparity + 2): how many pixels with ground truth it cuts (their true disparity outside
the estimate), how wide it is, and what bad 2.0 of the ``accurate`` preset becomes when
matching with it instead of with the true range (MiddEval3: the official weights, nonocc and
all; the others: mean over the scenes of all pixels with ground truth). Both runs pad the
images to the same shape buckets; the metrics clip to the true ``ndisp`` as every evaluation
here does. The estimate's time excludes its compilation (each coarse bucket compiles once,
the first time).

    python benchmarks/auto_range.py [--data DIR] [--sets trainingQ KITTI2012 Middlebury2001]

writes ``benchmarks/results/auto_range.md`` (and ``.csv``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from _report import write_report  # benchmarks/, on the path when run as a script

import sswjax
from sswjax.api.auto_range import estimate_range
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.metrics import MIDDEVAL3_TRAINING_WEIGHTS, evaluate_disparity

SETS = {"trainingQ": "MiddEval3", "KITTI2012": "KITTI2012", "Middlebury2001": "Middlebury2001"}
KEYS = ("set", "scene", "true_ndisp", "auto_min", "auto_ndisp", "gt_min", "gt_max", "cut",
        "estimate_s", "true_all", "auto_all", "true_nonocc", "auto_nonocc")


def _bad(disparity, scene) -> dict[str, float]:
    metrics = evaluate_disparity(disparity, scene.ground_truth, mask=scene.mask,
                                 ndisp=scene.ndisp, thresholds=(2.0,))
    return {region: values["bad2.0"] for region, values in metrics.items()}


def run_scene(set_name: str, scene, params, buckets) -> dict:
    """One row: the estimate, its cut, and bad 2.0 with the true and the estimated range."""
    estimate_range(scene.left, scene.right)  # compiled (once per coarse bucket) and warm
    start = time.perf_counter()
    found = estimate_range(scene.left, scene.right)
    seconds = time.perf_counter() - start
    known = scene.ground_truth[np.isfinite(scene.ground_truth)]
    last = found.min_disp + found.ndisp - 1
    cut = float(((known < found.min_disp) | (known > last)).mean() * 100)
    true = sswjax.match(scene.left, scene.right, scene.ndisp, params=params, buckets=buckets)
    auto = sswjax.match(scene.left, scene.right, found.ndisp, min_disp=found.min_disp,
                        params=params, buckets=buckets)
    true_bad, auto_bad = _bad(true, scene), _bad(auto, scene)
    return {"set": set_name, "scene": scene.name, "true_ndisp": scene.ndisp,
            "auto_min": found.min_disp, "auto_ndisp": found.ndisp,
            "gt_min": float(known.min()), "gt_max": float(known.max()), "cut": cut,
            "estimate_s": seconds, "true_all": true_bad["all"], "auto_all": auto_bad["all"],
            "true_nonocc": true_bad.get("nonocc", float("nan")),
            "auto_nonocc": auto_bad.get("nonocc", float("nan"))}


def _average(rows: list[dict], key: str) -> float:
    if rows[0]["set"] == "trainingQ":
        weights = np.array([MIDDEVAL3_TRAINING_WEIGHTS[row["scene"]] for row in rows])
        return float(np.sum(weights * [row[key] for row in rows]) / weights.sum())
    return float(np.mean([row[key] for row in rows]))


def table(rows: list[dict]) -> str:
    """The summary per set, then every scene."""
    lines = ["# `--ndisp auto` against the true disparity range", "",
             ("bad 2.0 % of the `accurate` preset with the true range and with the estimated one "
              "(trainingQ: official weights, nonocc / all; the others: mean over all pixels with "
              "ground truth); cut: % of the pixels with ground truth whose true disparity lies "
              "outside the estimate; width: estimated ndisp / true ndisp; time: the warm "
              "estimate."),
             "", ("| set | pairs | cutting | most cut % | width (mean, max) | bad 2.0 true | "
                  "bad 2.0 auto | change (points) | scene change (best, worst) | estimate s "
                  "(median) |"),
             "|---|---|---|---|---|---|---|---|---|---|"]
    for set_name in dict.fromkeys(row["set"] for row in rows):
        group = [row for row in rows if row["set"] == set_name]
        widths = [row["auto_ndisp"] / row["true_ndisp"] for row in group]
        cutting = sum(row["cut"] > 0 for row in group)
        most = max(group, key=lambda row: row["cut"])
        if set_name == "trainingQ":
            true = f"{_average(group, 'true_nonocc'):.2f} / {_average(group, 'true_all'):.2f}"
            auto = f"{_average(group, 'auto_nonocc'):.2f} / {_average(group, 'auto_all'):.2f}"
            change = (f"{_average(group, 'auto_nonocc') - _average(group, 'true_nonocc'):+.2f} / "
                      f"{_average(group, 'auto_all') - _average(group, 'true_all'):+.2f}")
        else:
            true, auto = f"{_average(group, 'true_all'):.2f}", f"{_average(group, 'auto_all'):.2f}"
            change = f"{_average(group, 'auto_all') - _average(group, 'true_all'):+.2f}"
        changes = [row["auto_all"] - row["true_all"] for row in group]
        lines.append(f"| {set_name} | {len(group)} | {cutting} | {most['cut']:.3f} "
                     f"({most['scene']}) | {np.mean(widths):.2f}, {max(widths):.2f} | {true} | "
                     f"{auto} | {change} | {min(changes):+.2f}, {max(changes):+.2f} | "
                     f"{np.median([r['estimate_s'] for r in group]):.2f} |")
    lines += ["", ("| set | scene | true range | estimate | true disparities | cut % | "
                   "bad 2.0 all true / auto |"), "|---|---|---|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['set']} | {row['scene']} | 0..{row['true_ndisp'] - 1} | "
                     f"{row['auto_min']}..{row['auto_min'] + row['auto_ndisp'] - 1} | "
                     f"{row['gt_min']:.1f}..{row['gt_max']:.1f} | {row['cut']:.3f} | "
                     f"{row['true_all']:.2f} / {row['auto_all']:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data", help="folder holding the data sets")
    parser.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    parser.add_argument("--preset", default="accurate", choices=list(sswjax.PRESETS))
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args(argv)
    params = sswjax.preset(args.preset)
    buckets = sswjax.ShapeBuckets(size_step=64, ndisp_step=32)
    rows = []
    for set_name in args.sets:
        for scene in load_scenes(args.data / SETS[set_name]):
            rows.append(run_scene(set_name, scene, params, buckets))
            row = rows[-1]
            print(f"{set_name} {scene.name}: {row['auto_min']}+{row['auto_ndisp']} (true "
                  f"{row['true_ndisp']}), cut {row['cut']:.3f} %, bad 2.0 {row['true_all']:.2f} "
                  f"-> {row['auto_all']:.2f}", file=sys.stderr, flush=True)
    write_report(args.output, "auto_range", table(rows), rows, KEYS)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
