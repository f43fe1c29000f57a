"""Configurations scored on the three shared data sets, and the held-out choice among them: how
every preset's values were chosen (the ablation, the band, the smoothing and refit grids, the
sub-pixel analysis).

Every subcommand scores its rows on MiddEval3 trainingQ (weighted, nonocc and all), the KITTI
2012 pairs and Middlebury 2001 (means over scenes) at bad 2.0, 1.0 and 0.5 and the average
error, one CSV row per configuration (``{set} {metric} {region}`` columns), and, with two rows
or more, writes the held-out choice of :mod:`sswjax.evaluation.selection` (each set left out in
turn, chosen on the other two): ``held_out.md`` on bad 2.0 (trainingQ's the mean of nonocc and
all) and ``held_out_thresholds.md`` on bad 2.0, 1.0 and 0.5 together.

``configs``
    whole configurations (``--config NAME=BASE:JSON``, BASE a preset or a parameter file; a
    preset's name alone is its own row) and peers (``--peer sgbm``), through ``sswjax.match``
    at each pair's exact shape (``--bucket-step N``: through shape buckets, a few compiles per
    set, the borders a little different); ``--timed N``: on the first N trainingQ pairs each
    row alternates with OpenCV SGBM 3-way, best of three each, and ``x SGBM`` is the median of
    the per-pair ratios (issue 25's protocol); ``--time-only`` skips the scoring.
``smoothing``
    the finished map's smoothing (:class:`sswjax.config.GatedBilateralSmoothing`): a preset's
    maps without it computed once per scene, then each ``--grid`` point applied to them (the
    graph's own stage, so the graph's maps with that smoothing: ``tests/test_graph.py``).
``refit``
    the coarse-to-fine map's refit window (``coarse.refit_radius``): a coarse-to-fine preset's
    maps without refit and smoothing, then each ``--radii`` value's refit
    (:func:`sswjax.graph.coarse.refit_on_cost`) and the preset's smoothing
    (``tests/test_coarse_to_fine.py`` checks they are the graph's maps).
``held-out``
    the choice again over CSV files of earlier runs (a configuration seen twice keeps its last
    row; rows without a set's columns are left out of the rules that need them).
``sub-pixel``
    where each configuration's error below one pixel sits on trainingQ's nonocc pixels: the
    fractional part of estimates within 0.5 px beside the truth's (pixel locking), the mean
    signed error by the estimate's tenth, and per scene bad 0.5 by the truth's local slope
    (plain means over pixels, not MiddEval3's weights). Writes ``sub_pixel.md``.

    python benchmarks/grid.py configs --config accurate \\
        --config 'no-sgm=accurate:{"optimizer": {"kind": "none"}}' [--peer sgbm] [--timed 5] \\
        [--bucket-step 64] [--sets trainingQ KITTI2012] [--scenes Teddy ArtL] [-o DIR]
    python benchmarks/grid.py smoothing --preset accurate [--grid '{"gate": 2.0}' ...] [-o DIR]
    python benchmarks/grid.py refit --preset fast [--radii 0 1 2 3 4] [-o DIR]
    python benchmarks/grid.py held-out benchmarks/results/band/band.csv other/band.csv [-o DIR]
    python benchmarks/grid.py sub-pixel --config accurate --config fast [-o DIR]

Every subcommand takes ``--data`` (the folder holding the three sets; default
``../shared/data``) and writes into ``-o`` (default ``benchmarks/results/grid/SUBCOMMAND``).
Scoring the three sets takes minutes per configuration on a 2-core machine; the compilation
cache is on, as on the command line.
"""

from __future__ import annotations

import argparse
import csv
import functools
import json
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import sswjax
from sswjax._files import atomic_output
from sswjax.api.images import prepare_pair
from sswjax.config import GatedBilateralSmoothing
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.methods import PEERS
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.evaluation.peers import sgbm_disparity
from sswjax.evaluation.runner import SCORINGS, scene_average
from sswjax.evaluation.selection import choose, held_out_choices
from sswjax.graph.coarse import refit_on_cost
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.runtime.compilation import enable_compilation_cache

from _report import SETS, parse_config, write_report  # benchmarks/: on the path as a script

KEYS = ("bad2.0", "bad1.0", "bad0.5", "avgerr")
"""The metrics of every row, per set and region."""

SMOOTHING_GRID = ['null', '{"gate": 1.0}', '{"gate": 2.0}', '{"gate": 3.0}', '{"gate": 4.0}',
                  '{"gate": 2.0, "colour_scale": 0.05}', '{"gate": 2.0, "colour_scale": 0.2}',
                  '{"gate": 2.0, "radius": 2}', '{"gate": 2.0, "radius": 4}',
                  '{"gate": 2.0, "iterations": 2}']
TENTHS = np.linspace(0, 1, 11)
SLOPES = (0.0, 0.02, 0.05, 0.1, 0.15, 0.3, np.inf)
"""Bin edges of the truth's local slope (``sub-pixel``), px of disparity per px."""


def table(rows: list[dict]) -> str:
    """Markdown table of ``rows`` (the first row's keys as the header; floats to 3 decimals)."""
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(f"{row.get(k, ''):.3f}" if isinstance(row.get(k), float)
                                else str(row.get(k, "")) for k in keys) + " |" for row in rows]
    return "\n".join(lines)


# ---- scoring -----------------------------------------------------------------------------

def set_columns(metrics: dict, set_name: str) -> dict[str, float]:
    """A row's columns of one set from per-scene metrics (scene -> region -> key -> value):
    ``"{set} {key} {region}"`` -> the set's scoring's average."""
    _, scoring_name, columns = SETS[set_name]
    regions = dict.fromkeys(region for region, _ in columns)
    return {f"{set_name} {key} {region}": scene_average(
        {s: m[region][key] for s, m in metrics.items() if region in m}, SCORINGS[scoring_name])
        for region in regions for key in KEYS}


def score(run, scenes) -> dict:
    """Per-scene metrics (bad 2.0, 1.0, 0.5, avgerr) of ``run(left, right, ndisp)``."""
    return {scene.name: evaluate_disparity(np.asarray(run(scene.left, scene.right, scene.ndisp)),
                                           scene.ground_truth, mask=scene.mask,
                                           ndisp=scene.ndisp, thresholds=(2.0, 1.0, 0.5))
            for scene in scenes}


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


def last_step_rows(data: Path, params, apply: dict) -> list[dict]:
    """Rows of a grid of last steps: each scene's map computed once with ``params``
    (``sswjax.match`` at the exact shape), then each ``apply[config](map, left, right, ndisp)
    -> map`` (jnp float32 (H, W) map, the pair float32 (H, W, C) in [0, 1]) scored."""
    rows = {config: {"config": config} for config in apply}
    for set_name, (folder, _, _) in SETS.items():
        metrics = {config: {} for config in apply}
        for scene in load_scenes(data / folder):
            disparity = jnp.asarray(sswjax.match(scene.left, scene.right, scene.ndisp,
                                                 params=params))
            left, right = map(jnp.asarray, prepare_pair(scene.left, scene.right))
            for config, last in apply.items():
                metrics[config].update(score(
                    lambda *_: jax.device_get(last(disparity, left, right, scene.ndisp)),
                    [scene]))
            print(set_name, scene.name, file=sys.stderr, flush=True)
        for config in apply:
            rows[config].update(set_columns(metrics[config], set_name))
    return list(rows.values())


# ---- the held-out choice -----------------------------------------------------------------

def bad2_errors(rows: list[dict]) -> dict[str, dict[str, float]]:
    """Configuration -> {set: bad 2.0} (trainingQ's the mean of nonocc and all), for the rows
    that have every set's bad 2.0."""
    columns = {name: [f"{name} bad2.0 {region}" for region, key in SETS[name][2]
                      if key == "bad2.0"] for name in SETS}
    return _errors(rows, columns)


def _errors(rows: list[dict], columns: dict[str, list[str]]) -> dict[str, dict[str, float]]:
    """Configuration -> {criterion: the mean of its ``columns``}, for the rows that have them
    all."""
    errors = {}
    for row in rows:
        if all(row.get(c) not in (None, "") for cs in columns.values() for c in cs):
            errors[row["config"]] = {name: sum(float(row[c]) for c in cs) / len(cs)
                                     for name, cs in columns.items()}
    return errors


def threshold_errors(rows: list[dict]) -> dict[str, dict[str, float]]:
    """Configuration -> {"{set} {key}": error} for bad 2.0, 1.0 and 0.5 (a set's error the
    mean over its regions), for the rows that have them all."""
    return _errors(rows, {f"{name} {key}": [f"{name} {key} {region}" for region in
                                            dict.fromkeys(r for r, _ in SETS[name][2])]
                          for name in SETS for key in KEYS[:3]})


def held_out_tables(rows: list[dict]) -> dict[str, list[dict]]:
    """``{"held_out": rows, "held_out_thresholds": rows}``: the choice leaving each set out,
    on bad 2.0 and on the three thresholds; a rule with fewer than two configurations scored
    on every set is left out."""
    out = {}
    errors = bad2_errors(rows)
    if len(errors) >= 2:
        folds = [{"held out": fold.held_out, "chosen on the other two": fold.chosen,
                  "held-out error": f"{fold.errors[fold.held_out]:.2f}",
                  "best possible": f"{fold.best_errors[fold.held_out]:.2f} ({fold.best})"}
                 for fold in held_out_choices(errors, {name: [name] for name in SETS})]
        folds.append({"held out": "none", "chosen on the other two":
                      f"{choose(errors, list(SETS))} (on all three)", "held-out error": "",
                      "best possible": ""})
        out["held_out"] = folds
    errors = threshold_errors(rows)
    if len(errors) >= 2:
        groups = {name: [f"{name} {key}" for key in KEYS[:3]] for name in SETS}
        folds = [{"held out": fold.held_out, "chosen": fold.chosen,
                  "held-out bad 2.0 / 1.0 / 0.5": " / ".join(f"{v:.2f}"
                                                             for v in fold.errors.values())}
                 for fold in held_out_choices(errors, groups)]
        folds.append({"held out": "none (chosen on all three)",
                      "chosen": choose(errors, [c for cs in groups.values() for c in cs]),
                      "held-out bad 2.0 / 1.0 / 0.5": ""})
        out["held_out_thresholds"] = folds
    return out


def write_held_out(output: Path, rows: list[dict]) -> int:
    """Write :func:`held_out_tables` of ``rows`` into ``output``; the number of tables."""
    tables = held_out_tables(rows)
    for stem, folds in tables.items():
        write_report(output, stem, table(folds), folds, list(folds[0]))
    return len(tables)


def read_rows(paths) -> list[dict]:
    """The rows of grid CSV files (older ``ablation.csv`` and ``band.csv`` too), the last row
    of a configuration seen twice kept."""
    rows = {}
    for path in paths:
        with open(path, newline="") as handle:
            for row in csv.DictReader(handle):
                rows[row["config"]] = row
    return list(rows.values())


# ---- subcommands -------------------------------------------------------------------------

def run_configs(args) -> int:
    buckets = ShapeBuckets(size_step=args.bucket_step, ndisp_step=32) if args.bucket_step else None
    runs = {name: functools.partial(sswjax.match, params=params, buckets=buckets)
            for name, params in map(parse_config, args.config)}
    runs.update({name: PEERS[name].fn for name in args.peer})
    timed = load_scenes(args.data / "MiddEval3")[:args.timed] if args.timed else []
    rows = []
    for name, run in runs.items():
        row = {"config": name}
        for set_name in () if args.time_only else args.sets:
            scenes = [s for s in load_scenes(args.data / SETS[set_name][0])
                      if not args.scenes or s.name in args.scenes]
            if scenes:
                row.update(set_columns(score(run, scenes), set_name))
                print(name, set_name, file=sys.stderr, flush=True)
        if timed:
            row["x SGBM"] = time_ratio(run, timed)
        rows.append(row)
        # after every configuration: a run stopped halfway keeps what it measured
        write_report(args.output, "times" if args.time_only else "configs", table(rows), rows,
                     list(rows[0]))
    if not args.time_only:
        write_held_out(args.output, rows)
    return 0


def run_smoothing(args) -> int:
    smooth = jax.jit(lambda smoothing, d, left, limit: smoothing.smooth(d, left, limit))
    params = sswjax.preset(args.preset).replace(smoothing=None)
    apply = {}
    for text in args.grid:
        options = json.loads(text)
        apply[f"{args.preset} smoothing {text}"] = (
            (lambda d, left, right, ndisp: d) if options is None else
            functools.partial(lambda s, d, left, right, ndisp: smooth(s, d, left, ndisp),
                              GatedBilateralSmoothing(**options)))
    rows = last_step_rows(args.data, params, apply)
    write_report(args.output, "smoothing", table(rows), rows, list(rows[0]))
    write_held_out(args.output, rows)
    return 0


def run_refit(args, parser) -> int:
    @functools.partial(jax.jit, static_argnums=(4,))
    def refit_and_smooth(params, disparity, left, right, ndisp):
        """The graph's last two steps: the refit (``coarse.refit_radius`` > 0), then the
        smoothing (when the preset has one)."""
        if params.coarse.refit_radius > 0:
            disparity = refit_on_cost(left, right, params, disparity, limit=ndisp)
        if params.smoothing is not None:
            disparity = params.smoothing.smooth(disparity, left, ndisp)
        return disparity

    preset = sswjax.preset(args.preset)
    if preset.coarse is None:
        parser.error(f"preset {args.preset} does not run coarse-to-fine")
    bare = preset.replace(**{"coarse.refit_radius": 0}, smoothing=None)
    rows = last_step_rows(args.data, bare, {
        f"{args.preset} refit_radius {radius}": functools.partial(
            refit_and_smooth, preset.replace(**{"coarse.refit_radius": radius}))
        for radius in args.radii})
    write_report(args.output, "refit", table(rows), rows, list(rows[0]))
    write_held_out(args.output, rows)
    return 0


def run_held_out(args, parser) -> int:
    for path in args.csv:
        if not path.is_file():
            parser.error(f"no such file: {path}")
    if not write_held_out(args.output, read_rows(args.csv)):
        parser.error("need at least two configurations scored on all three sets")
    return 0


def _fraction(values: np.ndarray) -> np.ndarray:
    return values - np.floor(values)


def _percent(counts: np.ndarray) -> str:
    return " | ".join(f"{v:.1f}" for v in 100 * counts / max(counts.sum(), 1))


def sub_pixel_rows(name: str, params, scenes) -> tuple[list[str], np.ndarray, np.ndarray, list]:
    """Per-scene table rows, the two fraction histograms and the errors by the estimate's
    tenth, for one configuration."""
    rows, locked, truth = [], np.zeros(10), np.zeros(10)
    by_tenth: list[list[np.ndarray]] = [[] for _ in range(10)]
    for scene in scenes:
        estimate = np.asarray(sswjax.match(scene.left, scene.right, scene.ndisp, params=params))
        gt = scene.ground_truth
        ok = np.isfinite(gt) & (gt > 0)
        if scene.mask is not None:
            ok &= scene.mask == 255
        error = (estimate - gt)[ok]
        near = np.abs(error) < 0.5
        locked += np.histogram(_fraction(estimate[ok][near]), TENTHS)[0]
        truth += np.histogram(_fraction(gt[ok][near]), TENTHS)[0]
        tenth = np.minimum((_fraction(estimate[ok]) * 10).astype(int), 9)
        for k in range(10):
            by_tenth[k].append(error[(tenth == k) & (np.abs(error) < 1)])
        grad_y, grad_x = np.gradient(np.where(ok, gt, 0.0))
        slope_bin = np.digitize(np.hypot(grad_x, grad_y)[ok], SLOPES) - 1
        cells = []
        for k in range(len(SLOPES) - 1):
            inside = slope_bin == k
            cells.append(f"{100 * np.mean(np.abs(error[inside]) > 0.5):.1f} "
                         f"({100 * inside.mean():.0f} %)" if inside.any() else "")
        bad = np.abs(error) > 0.5
        rows.append(f"| {name} | {scene.name} | {100 * bad.mean():.1f} | "
                    f"{100 * (bad & (np.abs(error) <= 1)).mean():.1f} | "
                    f"{np.median(error[np.abs(error) < 2]):+.3f} | " + " | ".join(cells) + " |")
    return rows, locked, truth, by_tenth


def run_sub_pixel(args) -> int:
    scenes = load_scenes(args.data / "MiddEval3" / "trainingQ")
    tenths = " | ".join(f"{t:.1f}" for t in TENTHS[:-1])
    lines = ["Fractional part by tenths (%), nonocc pixels within 0.5 px of the truth", "",
             f"| config | of | {tenths} |", "|---|---|" + "---|" * 10]
    bias = [f"| config | | {tenths} |", "|---|---|" + "---|" * 10]
    slopes = " | ".join(f"{a:g}-{b:g}" for a, b in zip(SLOPES[:-1], SLOPES[1:]))
    scenes_table = [f"| config | scene | bad 0.5 | 0.5-1.0 | median error (within 2 px) | "
                    f"bad 0.5 by slope {slopes} |", "|---|---|---|---|---|" + "---|" * 6]
    for name, params in map(parse_config, args.config):
        rows, locked, truth, by_tenth = sub_pixel_rows(name, params, scenes)
        lines += [f"| {name} | estimate | {_percent(locked)} |",
                  f"| {name} | truth | {_percent(truth)} |"]
        errors = [np.concatenate(e) for e in by_tenth]
        bias += [f"| {name} | mean error, px | " +
                 " | ".join(f"{e.mean():+.3f}" for e in errors) + " |",
                 f"| {name} | beyond 0.5 px, % | " +
                 " | ".join(f"{100 * np.mean(np.abs(e) > 0.5):.1f}" for e in errors) + " |"]
        scenes_table += rows
    text = "\n".join(lines + ["", "By the estimate's fractional part, nonocc pixels within 1 px",
                              ""] + bias + ["", "By scene, nonocc", ""] + scenes_table) + "\n"
    print(text)
    args.output.mkdir(parents=True, exist_ok=True)
    with atomic_output(args.output / "sub_pixel.md") as path:
        Path(path).write_text(text)
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    default_data = Path(__file__).resolve().parents[2] / "shared" / "data"
    config_help = "NAME=BASE:JSON (BASE a preset or a parameter file) or a preset; repeatable"

    def command(name, help_text):
        sub = commands.add_parser(name, help=help_text, description=help_text)
        sub.add_argument("--data", type=Path, default=default_data,
                         help="the folder holding the three data sets (../shared/data)")
        sub.add_argument("-o", "--output", type=Path,
                         help=f"the results' folder (benchmarks/results/grid/{name})")
        return sub

    sub = command("configs", "whole configurations and peers scored, and timed against SGBM")
    sub.add_argument("--config", action="append", default=[], help=config_help)
    sub.add_argument("--peer", action="append", default=[],
                     help="another project's matcher scored and timed the same way (sgbm, ...)")
    sub.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    sub.add_argument("--scenes", nargs="+", help="only these scenes (of every set)")
    sub.add_argument("--bucket-step", type=int, default=0,
                     help="run through shape buckets of this size step (0: exact shapes)")
    sub.add_argument("--timed", type=int, default=0,
                     help="trainingQ pairs timed against SGBM (0: no timing)")
    sub.add_argument("--time-only", action="store_true",
                     help="only the timing against SGBM, no scoring (times.md)")
    sub = command("smoothing", "a grid of the finished map's smoothing")
    sub.add_argument("--preset", default="accurate", help="the maps smoothed (without their own)")
    sub.add_argument("--grid", nargs="+", default=SMOOTHING_GRID,
                     help="options of the smoothing as JSON, 'null' for none")
    sub = command("refit", "a grid of the coarse-to-fine map's refit window")
    sub.add_argument("--preset", default="fast", help="a coarse-to-fine preset")
    sub.add_argument("--radii", type=int, nargs="+", default=[0, 1, 2, 3, 4],
                     help="coarse.refit_radius values, 0 for none")
    sub = command("held-out", "the held-out choice over the CSV files of earlier runs")
    sub.add_argument("csv", nargs="+", type=Path, help="CSV files of this script's rows")
    sub = command("sub-pixel", "where the error below one pixel sits, on trainingQ")
    sub.add_argument("--config", action="append", default=[], help=config_help)
    args = parser.parse_args(argv)
    args.output = args.output or Path("benchmarks/results/grid") / args.command
    this = commands.choices[args.command]
    if args.command == "held-out":
        return run_held_out(args, this)
    if args.command in ("configs", "sub-pixel"):
        for peer in getattr(args, "peer", []):
            if peer not in PEERS:
                this.error(f"--peer {peer}: not one of {', '.join(PEERS)}")
        if not args.config and not getattr(args, "peer", None):
            this.error("give at least one --config" + " or --peer" * (args.command == "configs"))
    enable_compilation_cache()  # as the command line does: a second run compiles nothing
    run = {"configs": run_configs, "smoothing": run_smoothing,
           "refit": functools.partial(run_refit, parser=this), "sub-pixel": run_sub_pixel}
    return run[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
