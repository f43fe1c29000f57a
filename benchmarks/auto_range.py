"""What ``--ndisp auto`` costs, beside what a range change that cuts nothing costs anyway.

For every scene of MiddEval3 trainingQ, KITTI 2012 (pairs 100-129) and Middlebury 2001, the
``accurate`` preset matches the pair over several ranges and each map is scored (bad 2.0)
against the same ground truth:

- ``true``: the scene's range ``0 .. ndisp - 1`` (``calib.txt``'s ``ndisp`` for MiddEval3, else
  the smallest multiple of 8 above the largest true disparity + 2), the reference;
- ``top +8``: ``0 .. ndisp + 7``, 8 more disparities at the top;
- ``bottom raised``: ``m .. ndisp - 1`` with ``m`` the lowest true disparity rounded down, at
  most 8 (scenes whose lowest is below 1 are left out);
- the ranges of :func:`sswjax.api.auto_range.range_from_coarse` from one coarse pass
  (:func:`~sswjax.api.auto_range.coarse_disparities`) under the candidate rules of
  :data:`RULES`, one of which is the library's default (marked in the report).

``top +8`` and ``bottom raised`` hold every true disparity: how much they move a scene is the
method's own sensitivity to a range change that cuts nothing, the floor under what any estimate
can promise per scene. Changes are in points of bad 2.0 against ``true`` (MiddEval3: the
official weights, nonocc and all; the others: mean over the scenes of all pixels with ground
truth); ``inner``: the same over the columns right of ``ndisp + 8`` only, where no searched
disparity points outside the right image. The rules are compared leaving one set out: the
rule with the smallest worst scene cost on two sets (ties: the smaller mean absolute change) is
scored on the third. Every run matches the pair at its own shape, as ``sswjax match`` does
for one pair (``--bucket`` pads to shape buckets of 64 pixels and 32 disparities instead, as a
folder of many sizes is run; the padding moves single scenes by itself, up to 2.3 points on
KITTI 000114), and the metrics clip to the true ``ndisp`` as every evaluation here does. The estimate's time
is the warm coarse pass (each coarse bucket compiles once, the first time).

    python benchmarks/auto_range.py [--data DIR] [--sets trainingQ KITTI2012 Middlebury2001]
                                    [--bucket]

writes ``benchmarks/results/auto_range.md`` (``auto_range_bucket.md`` with ``--bucket``; and
``.csv``, one row per scene and range).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from _report import write_report  # benchmarks/, on the path when run as a script

import sswjax
from sswjax.api.auto_range import (MARGIN_FRACTION, MARGIN_PIXELS, RAISE_FROM,
                                    coarse_disparities, range_from_coarse)
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.metrics import MIDDEVAL3_TRAINING_WEIGHTS, evaluate_disparity

SETS = {"trainingQ": "MiddEval3", "KITTI2012": "KITTI2012", "Middlebury2001": "Middlebury2001"}
RULES = {  # name -> keywords of range_from_coarse: whether min_disp leaves 0, and the margin
    "raised, 1.5 px": {"raise_from": 0.0, "margin_pixels": 1.5},
    "raised, 3 px": {"raise_from": 0.0, "margin_pixels": 3.0},
    "0 unless halving, 1.5 px": {"raise_from": 0.5, "margin_pixels": 1.5},
    "0 unless halving, 3 px": {"raise_from": 0.5, "margin_pixels": 3.0},
}
"""The candidate rules on one coarse pass: ``min_disp`` raised to the estimated lower end
(``raised``) or kept at 0 unless raising it at least halves the search (the lower end at least
half the upper one), and the margin in coarse pixels (1.5, or 3)."""
KEYS = ("set", "scene", "range", "true_ndisp", "gt_min", "gt_max", "min_disp", "ndisp", "cut",
        "all", "nonocc", "inner", "estimate_s")
THRESHOLD = 0.2
"""The goal's bound: a scene moving by more than this many points counts."""


def _bad(disparity, scene, *, first_column: int = 0) -> dict[str, float]:
    """bad 2.0 of ``disparity``: all, nonocc (nan without a mask) and inner (all pixels from
    ``first_column`` on)."""
    scores = {}
    for name, start in (("full", 0), ("inner", first_column)):
        truth = scene.ground_truth.copy()
        truth[:, :start] = np.inf
        metrics = evaluate_disparity(disparity, truth, mask=scene.mask, ndisp=scene.ndisp,
                                     thresholds=(2.0,))
        scores[name] = {region: values["bad2.0"] for region, values in metrics.items()}
    return {"all": scores["full"]["all"], "nonocc": scores["full"].get("nonocc", math.nan),
            "inner": scores["inner"]["all"]}


def scene_ranges(scene, *, default_only: bool = False
                 ) -> tuple[dict[str, tuple[int, int]], float]:
    """``{range name: (min_disp, ndisp)}`` of one scene, and the warm coarse pass's seconds.
    ``default_only``: the true range and the library's default rule only."""
    known = scene.ground_truth[np.isfinite(scene.ground_truth)]
    ranges = {"true": (0, scene.ndisp)}
    if not default_only:
        ranges["top +8"] = (0, scene.ndisp + 8)
        lowest = min(8, math.floor(float(known.min())))
        if lowest >= 1:
            ranges["bottom raised"] = (lowest, scene.ndisp - lowest)
    coarse_disparities(scene.left, scene.right)  # compiled (once per coarse bucket) and warm
    start = time.perf_counter()
    coarse = coarse_disparities(scene.left, scene.right)
    seconds = time.perf_counter() - start
    rules = [default_rule()] if default_only else list(RULES)
    for name in rules:
        ranges[name] = tuple(range_from_coarse(coarse, **RULES[name]))
    return ranges, seconds


def run_scene(set_name: str, scene, params, buckets, *, default_only: bool = False
              ) -> list[dict]:
    """One row per range of the scene: the range, its cut and its bad 2.0."""
    ranges, seconds = scene_ranges(scene, default_only=default_only)
    known = scene.ground_truth[np.isfinite(scene.ground_truth)]
    scored = {}  # (min_disp, ndisp) -> scores: ranges that coincide are matched once
    rows = []
    for name, (first, count) in ranges.items():
        if (first, count) not in scored:
            disparity = sswjax.match(scene.left, scene.right, count, min_disp=first,
                                     params=params, buckets=buckets)
            scored[first, count] = _bad(disparity, scene, first_column=scene.ndisp + 8)
        last = first + count - 1
        rows.append({"set": set_name, "scene": scene.name, "range": name,
                     "true_ndisp": scene.ndisp, "gt_min": float(known.min()),
                     "gt_max": float(known.max()), "min_disp": first, "ndisp": count,
                     "cut": float(((known < first) | (known > last)).mean() * 100),
                     **scored[first, count],
                     "estimate_s": seconds if name in RULES else math.nan})
    return rows


def _average(rows: list[dict], key: str) -> float:
    if rows[0]["set"] == "trainingQ":
        weights = np.array([MIDDEVAL3_TRAINING_WEIGHTS[row["scene"]] for row in rows])
        return float(np.sum(weights * [row[key] for row in rows]) / weights.sum())
    return float(np.mean([row[key] for row in rows]))


def _changes(rows: list[dict], set_name: str, name: str, key: str = "all"):
    """The scenes' ``(true, other)`` rows of range ``name`` in ``set_name``."""
    true = {row["scene"]: row for row in rows if row["set"] == set_name and row["range"] == "true"}
    other = [row for row in rows if row["set"] == set_name and row["range"] == name]
    return [true[row["scene"]] for row in other], other


def _summary_line(rows: list[dict], set_name: str, name: str) -> str | None:
    """One row of the summary: range ``name`` against ``true`` on ``set_name``."""
    reference, group = _changes(rows, set_name, name)
    if not group:
        return None
    change = {key: _average(group, key) - _average(reference, key)
              for key in ("all", "nonocc", "inner")}
    per_scene = np.array([row["all"] - ref["all"] for row, ref in zip(group, reference)])
    inner = np.array([row["inner"] - ref["inner"] for row, ref in zip(group, reference)])
    worst, best = int(np.argmax(per_scene)), int(np.argmin(per_scene))
    cutting = sum(row["cut"] > 0 for row in group)
    widths = [row["ndisp"] / row["true_ndisp"] for row in group]
    total = (f"{change['nonocc']:+.2f} / {change['all']:+.2f}" if set_name == "trainingQ"
             else f"{change['all']:+.2f}")
    seconds = [row["estimate_s"] for row in group if np.isfinite(row["estimate_s"])]
    return (f"| {set_name} | {name} | {len(group)} | {cutting} | {np.mean(widths):.2f} | "
            f"{total} | {change['inner']:+.2f} | "
            f"{np.sum(np.abs(per_scene) > THRESHOLD)} | {np.mean(np.abs(per_scene)):.2f} | "
            f"{per_scene[best]:+.2f} ({group[best]['scene']}), "
            f"{per_scene[worst]:+.2f} ({group[worst]['scene']}) | "
            f"{np.sum(np.abs(inner) > THRESHOLD)} | "
            f"{f'{np.median(seconds):.2f}' if seconds else ''} |")


def table(rows: list[dict]) -> str:
    """The summary per set and range, then every scene."""
    names = list(dict.fromkeys(row["range"] for row in rows if row["range"] != "true"))
    sets = list(dict.fromkeys(row["set"] for row in rows))
    lines = ["# `--ndisp auto` against the true disparity range, and what a range change that "
             "cuts nothing costs", "",
             ("Change of bad 2.0 (points) of the `accurate` preset against matching over the "
              "true range `0..ndisp-1` (trainingQ: official weights, nonocc / all; the others: "
              "mean over all pixels with ground truth). `top +8`: `0..ndisp+7`; `bottom "
              "raised`: from the lowest true disparity rounded down, at most 8; both cut no "
              "true disparity. The others: rules of `--ndisp auto` on one coarse pass, "
              "`min_disp` raised to the estimated lower end or kept at 0 unless that halves "
              "the search, and the margin in coarse pixels; "
              f"`{default_rule()}` is the library's default. cutting: scenes whose range leaves out true "
              "disparities; width: ndisp / true ndisp (mean); inner: the same change over the "
              f"columns right of `ndisp + 8` only; > {THRESHOLD}: scenes moving by more than "
              f"{THRESHOLD} points (all pixels); mean \\|Δ\\|: mean absolute scene change; "
              "estimate s: the warm coarse pass (median)."),
             "", ("| set | range | scenes | cutting | width | change | inner change | "
                  f"scenes > {THRESHOLD} | mean \\|Δ\\| | scene change (best, worst) | "
                  f"inner scenes > {THRESHOLD} | estimate s |"),
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for set_name in sets:
        lines += [line for name in names if (line := _summary_line(rows, set_name, name))]
    lines += ["", ("Per scene: the true range and bad 2.0 (all pixels) with it, then each "
                   "range and its change in points (`-`: not run)."), "",
              "| set | scene | true disparities | true range: bad 2.0 | " +
              " | ".join(names) + " |", "|---|---|---|---|" + "---|" * len(names)]
    by_key = {(row["set"], row["scene"], row["range"]): row for row in rows}
    for set_name in sets:
        for scene in dict.fromkeys(row["scene"] for row in rows if row["set"] == set_name):
            true = by_key[set_name, scene, "true"]
            cells = []
            for name in names:
                row = by_key.get((set_name, scene, name))
                cells.append("-" if row is None else
                             f"{row['min_disp']}..{row['min_disp'] + row['ndisp'] - 1}: "
                             f"{row['all'] - true['all']:+.2f}")
            lines.append(f"| {set_name} | {scene} | {true['gt_min']:.1f}..{true['gt_max']:.1f} | "
                         f"0..{true['ndisp'] - 1}: {true['all']:.2f} | " + " | ".join(cells) + " |")
    return "\n".join(lines + ["", *held_out(rows)])


def default_rule() -> str:
    """The name of the rule of :data:`RULES` that :func:`range_from_coarse` applies by default."""
    defaults = {"raise_from": RAISE_FROM, "margin_pixels": MARGIN_PIXELS,
                "margin_fraction": MARGIN_FRACTION}
    for name, keywords in RULES.items():
        if {**defaults, **keywords} == defaults:
            return name
    return "none of these"


def _cost(rows: list[dict], name: str, sets) -> tuple[float, float]:
    """The worst scene change of rule ``name`` over ``sets``, and the mean absolute one."""
    changes = [row["all"] - ref["all"] for set_name in sets
               for ref, row in zip(*_changes(rows, set_name, name))]
    return max(changes), float(np.mean(np.abs(changes)))


def held_out(rows: list[dict]) -> list[str]:
    """The rules chosen leaving one set out (smallest worst scene change on the other sets,
    ties by mean absolute change), and what the choice costs on the set left out."""
    sets = list(dict.fromkeys(row["set"] for row in rows))
    names = [name for name in RULES if any(row["range"] == name for row in rows)]
    lines = [("Leave one set out: the rule with the smallest worst scene change on the other "
              "sets (ties: mean \\|Δ\\|), then its worst scene change and mean \\|Δ\\| on the "
              "set left out, beside the best rule there."), "",
             "| left out | chosen on the others | worst, mean \\|Δ\\| there | on the left-out set "
             "| best rule on the left-out set |", "|---|---|---|---|---|"]
    for held in [*(sets if len(sets) > 1 else []), None]:
        others = [name for name in sets if name != held]
        chosen = min(names, key=lambda name: _cost(rows, name, others))
        there = "{:+.2f}, {:.2f}".format(*_cost(rows, chosen, others))
        if held is None:
            lines.append(f"| none | {chosen} (on all) | {there} | | |")
            continue
        best = min(names, key=lambda name: _cost(rows, name, [held]))
        lines.append(f"| {held} | {chosen} | {there} | "
                     "{:+.2f}, {:.2f} | ".format(*_cost(rows, chosen, [held])) +
                     f"{best}: " + "{:+.2f}, {:.2f} |".format(*_cost(rows, best, [held])))
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data", help="folder holding the data sets")
    parser.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    parser.add_argument("--preset", default="accurate", choices=list(sswjax.PRESETS))
    parser.add_argument("--bucket", action="store_true",
                        help="pad every pair to shape buckets (64 pixels, 32 disparities)")
    parser.add_argument("--default-only", action="store_true",
                        help="the true range and the library's rule only (report "
                             "auto_range_default)")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args(argv)
    params = sswjax.preset(args.preset)
    buckets = sswjax.ShapeBuckets(size_step=64, ndisp_step=32) if args.bucket else None
    rows = []
    for set_name in args.sets:
        for scene in load_scenes(args.data / SETS[set_name]):
            scene_rows = run_scene(set_name, scene, params, buckets,
                                   default_only=args.default_only)
            rows += scene_rows
            print(f"{set_name} {scene.name}: true {scene_rows[0]['all']:.2f}, " + ", ".join(
                f"{row['range']} {row['min_disp']}+{row['ndisp']} "
                f"{row['all'] - scene_rows[0]['all']:+.2f}" for row in scene_rows[1:]),
                file=sys.stderr, flush=True)
    name = "auto_range" + ("_bucket" if args.bucket else "") + (
        "_default" if args.default_only else "")
    write_report(args.output, name, table(rows), rows, KEYS)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
