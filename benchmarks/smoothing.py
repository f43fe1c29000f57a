"""The smoothing of the finished map, a grid of its options on the three data sets, and the
held-out choice among them.

The smoothing is the graph's last stage and reads only the map and the left image, so each
preset's maps are computed once per scene (``sswjax.match`` at exact shapes) and every grid
point applies the stage itself (:meth:`sswjax.config.GatedBilateralSmoothing.smooth`) to them:
the same maps the graph gives with that smoothing (``tests/test_graph.py`` checks it). Rows are
written in ``benchmarks/ablation.py``'s CSV format, with bad 1.0 and 0.5 and the average error
beside bad 2.0, and ``benchmarks/held_out.py``'s rule chooses among them.

    python benchmarks/smoothing.py --preset accurate [--data ../shared/data]
        [--grid '{"gate": 2.0}' '{"gate": 1.0}' ...] [-o benchmarks/results/smoothing/PRESET]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp

import sswjax
from sswjax.api.images import prepare_pair
from sswjax.config import GatedBilateralSmoothing
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.evaluation.runner import SCORINGS, _average
from sswjax.runtime.compilation import enable_compilation_cache

from _report import write_report  # benchmarks/, on the path when run as a script
from held_out import choose, held_out_rows

SETS = {  # name -> (folder, scoring, regions)
    "trainingQ": ("MiddEval3", "middeval3", ("nonocc", "all")),
    "KITTI2012": ("KITTI2012", "kitti", ("all",)),
    "Middlebury2001": ("Middlebury2001", "mean", ("all",)),
}
KEYS = ("bad2.0", "bad1.0", "bad0.5", "avgerr")
GRID = ['null', '{"gate": 1.0}', '{"gate": 2.0}', '{"gate": 3.0}', '{"gate": 4.0}',
        '{"gate": 2.0, "colour_scale": 0.05}', '{"gate": 2.0, "colour_scale": 0.2}',
        '{"gate": 2.0, "radius": 2}', '{"gate": 2.0, "radius": 4}',
        '{"gate": 2.0, "iterations": 2}']


def _table(rows: list[dict]) -> str:
    """Markdown table of ``rows`` (their keys as the header; floats to 3 decimals)."""
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(f"{row[k]:.3f}" if isinstance(row[k], float) else str(row[k])
                                for k in keys) + " |" for row in rows]
    return "\n".join(lines)


@jax.jit
def _smooth(smoothing, disparity, left, limit):
    return smoothing.smooth(disparity, left, limit)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="accurate", help="the maps smoothed (without their "
                        "own smoothing)")
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data")
    parser.add_argument("--grid", nargs="+", default=GRID,
                        help="options of the smoothing as JSON, 'null' for none")
    parser.add_argument("-o", "--output", type=Path,
                        help="default benchmarks/results/smoothing/PRESET")
    args = parser.parse_args(argv)
    args.output = args.output or Path("benchmarks/results/smoothing") / args.preset
    enable_compilation_cache()  # as the command line does: a second run compiles nothing
    params = sswjax.preset(args.preset).replace(smoothing=None)
    grid = {text: (None if json.loads(text) is None else
                   GatedBilateralSmoothing(**json.loads(text))) for text in args.grid}
    apply = {f"{args.preset} smoothing {text}": (
        (lambda d, left, right, ndisp: d) if smoothing is None else
        (lambda d, left, right, ndisp, s=smoothing: _smooth(s, d, left, ndisp)))
        for text, smoothing in grid.items()}
    rows = grid_rows(args.data, params, apply)
    write_report(args.output, "smoothing", _table(rows), rows, list(rows[0]))
    write_held_out(args.output, rows)
    return 0


def grid_rows(data: Path, params, apply: dict) -> list[dict]:
    """The rows of a grid of last steps over the three sets (this module's CSV format).

    Each scene's map is computed once with ``params`` (``sswjax.match`` at exact shapes), then
    each ``apply[config](map, left, right, ndisp) -> map`` (jnp float32 (H, W) map, the pair
    float32 (H, W, C) in [0, 1]) is scored at bad 2.0, 1.0 and 0.5 and the average error, and
    averaged per set by its scoring; a row per config, ``config`` its first column.
    """
    rows = {config: {"config": config} for config in apply}
    for set_name, (folder, scoring_name, regions) in SETS.items():
        metrics = {config: {} for config in apply}
        for scene in load_scenes(data / folder):
            disparity = jnp.asarray(sswjax.match(scene.left, scene.right, scene.ndisp,
                                                 params=params))
            left, right = map(jnp.asarray, prepare_pair(scene.left, scene.right))
            for config, last in apply.items():
                metrics[config][scene.name] = evaluate_disparity(
                    jax.device_get(last(disparity, left, right, scene.ndisp)),
                    scene.ground_truth, mask=scene.mask, ndisp=scene.ndisp,
                    thresholds=(2.0, 1.0, 0.5))
            print(set_name, scene.name, file=sys.stderr, flush=True)
        for config in apply:
            rows[config].update({f"{set_name} {key} {region}": _average(
                {s: m[region][key] for s, m in metrics[config].items() if region in m},
                SCORINGS[scoring_name]) for region in regions for key in KEYS})
    return list(rows.values())


def write_held_out(output: Path, rows: list[dict]) -> None:
    """``held_out.md`` (the rule on bad 2.0) and ``held_out_thresholds.md`` (on 2.0, 1.0 and
    0.5) of ``rows`` (this module's CSV format), with their CSV files, into ``output``."""
    errors = {row["config"]: {
        "trainingQ": (row["trainingQ bad2.0 nonocc"] + row["trainingQ bad2.0 all"]) / 2,
        "KITTI2012": row["KITTI2012 bad2.0 all"],
        "Middlebury2001": row["Middlebury2001 bad2.0 all"]} for row in rows}
    for stem, folds in (("held_out", held_out_rows(errors)),
                        ("held_out_thresholds", thresholds_folds(rows))):
        write_report(output, stem, _table(folds), folds, list(folds[0]))


def thresholds_folds(rows: list[dict]) -> list[dict]:
    """``held_out.py``'s rule with each set's bad 2.0, 1.0 and 0.5 as three errors (trainingQ's
    the mean of nonocc and all): the choice for a stage whose purpose is sub-pixel precision."""
    def error(row, name, key):
        regions = SETS[name][2]
        return sum(row[f"{name} {key} {region}"] for region in regions) / len(regions)

    errors = {row["config"]: {f"{name} {key}": error(row, name, key) for name in SETS
                              for key in KEYS[:3]} for row in rows}
    folds = []
    for held in [*SETS, None]:
        chosen = choose(errors, [column for column in next(iter(errors.values()))
                                 if not column.startswith(f"{held} ")])
        folds.append({"held out": held or "none (chosen on all three)", "chosen": chosen,
                      "held-out bad 2.0 / 1.0 / 0.5": "" if held is None else " / ".join(
                          f"{errors[chosen][f'{held} {key}']:.2f}" for key in KEYS[:3])})
    return folds


if __name__ == "__main__":
    sys.exit(main())
