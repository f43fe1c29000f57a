"""The speed/accuracy front: every preset and every peer, timed and scored in one run.

For each data set (MiddEval3 trainingQ, the KITTI 2012 pairs, Middlebury 2001) and each pair,
every method runs once to warm up (compilation for the presets), then each method in turn
``--repeats`` times alternating with SGBM (the protocol of issue 25): a method's time on a pair
is its best run, its ratio the best run over the best of the SGBM runs it alternated with, so
that the two share the machine's state, and its "x sgbm" the median of those ratios.
Reported per method and set: the median time per pair, the median over pairs of its ratio to
OpenCV SGBM 3-way on the same pair, and the errors (trainingQ: weighted bad 2.0 /
1.0 / 0.5, nonocc and all; KITTI: mean bad 2.0, 1.0, 0.5 and 3.0; Middlebury 2001: mean bad
2.0, 1.0 and 0.5), and whether the method is ahead (lower bad 2.0, "all") of every peer at
least as fast. Presets run at each pair's exact shape on
trainingQ (the timed set of the speed goals) and through 64-pixel shape buckets on the others
(their pairs differ in ndisp: one compilation per bucket).

Methods: the presets of :data:`sswjax.PRESETS` and the peers of :data:`sswjax.evaluation.methods.PEERS`
that are installed (OpenCV StereoBM, SGBM 3-way, SGBM HH; CNES Pandora); ``--methods`` narrows.
Writes ``front.md``, ``front.csv``, ``front.json`` (the run's date, machine and command) and
``front.png`` (time per pair against bad 2.0, log time axis, one panel per set) into ``-o``.
``--page docs/results.md`` also writes the user's results page (:func:`results_page`) from the
run; with ``--from FOLDER`` it writes the page from an earlier run's ``front.csv``, running
nothing: the page is generated, never edited by hand.

    python benchmarks/front.py [--data DIR] [--sets trainingQ KITTI2012] [--repeats 3] [-o benchmarks/results/front] [--page docs/results.md]
    python benchmarks/front.py --page docs/results.md --from benchmarks/results/front
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import os
import platform
import shlex
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import jax
import numpy as np

import sswjax
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.evaluation.runner import SCORINGS, scene_average
from sswjax.evaluation.methods import PEERS

from _report import SETS, write_report  # benchmarks/: on the path as a script

REFERENCE = "sgbm"  # the peer every time is divided by
COLUMNS = {  # set -> the (region, threshold) columns of the front, 2.0 first (the plot's axis)
    "trainingQ": SETS["trainingQ"][2],
    "KITTI2012": [("all", "bad2.0"), ("all", "bad1.0"), ("all", "bad0.5"), ("all", "bad3.0")],
    "Middlebury2001": [("all", "bad2.0"), ("all", "bad1.0"), ("all", "bad0.5")],
}


def _method_runners(names, bucket_step: int) -> dict[str, dict]:
    """Name -> {set kind: callable(left, right, ndisp)}; peers that are not installed are left
    out (with a note on stderr)."""
    buckets = ShapeBuckets(size_step=bucket_step, ndisp_step=32)
    runners = {}
    for name in names:
        if name in sswjax.PRESETS:
            params = sswjax.preset(name)
            runners[name] = {
                "exact": lambda l, r, n, p=params: sswjax.match(l, r, n, params=p),
                "bucket": lambda l, r, n, p=params: sswjax.match(l, r, n, params=p, buckets=buckets),
            }
            continue
        fn = PEERS[name].fn
        try:
            probe = np.zeros((32, 64), np.uint8)
            fn(probe, probe, 16)
        except (ValueError, ImportError) as error:
            print(f"front: skipping {name}: {error}", file=sys.stderr)
            continue
        runners[name] = {"exact": fn, "bucket": fn}
    return runners


def _seconds(run, args) -> float:
    start = time.perf_counter()
    np.asarray(run(*args))
    return time.perf_counter() - start


def time_set(runners: dict, scenes, kind: str, repeats: int):
    """Per method: per-scene seconds (best of ``repeats``), per-scene ratios to SGBM and the
    disparity maps.

    On each pair every method runs once (compilation), then each method in turn runs
    ``repeats`` times alternating with SGBM: its ratio on the pair is its best time over the
    best of the SGBM runs it alternated with, so that what ran before (a large graph, Pandora)
    weighs on both sides alike. SGBM's own seconds are the best of all its runs on the pair.
    Returns ``(seconds, ratios, maps)``, each ``{method: {scene: value}}``.
    """
    seconds = {name: {} for name in runners}
    ratios = {name: {} for name in runners}
    maps = {name: {} for name in runners}
    reference = runners[REFERENCE][kind]
    for scene in scenes:
        args = (scene.left, scene.right, scene.ndisp)
        for name, run in runners.items():
            maps[name][scene.name] = np.asarray(run[kind](*args))  # warm-up (compilation)
        references = []
        for name, run in runners.items():
            if name == REFERENCE:
                continue
            ours, theirs = [], []
            for _ in range(repeats):
                ours.append(_seconds(run[kind], args))
                theirs.append(_seconds(reference, args))
            seconds[name][scene.name] = min(ours)
            ratios[name][scene.name] = min(ours) / min(theirs)
            references += theirs
        seconds[REFERENCE][scene.name], ratios[REFERENCE][scene.name] = min(references), 1.0
        print(f"  {scene.name}: " + ", ".join(f"{n} {seconds[n][scene.name]:.3f} s "
                                              f"({ratios[n][scene.name]:.2f}x)" for n in runners),
              file=sys.stderr, flush=True)
    return seconds, ratios, maps


def score(maps: dict, scenes, set_name: str) -> dict[str, float]:
    """Averaged errors of one method's maps, keyed like the ablation table's columns."""
    scoring = SCORINGS[SETS[set_name][1]]
    metrics = {s.name: evaluate_disparity(maps[s.name], s.ground_truth, mask=s.mask,
                                          ndisp=s.ndisp, thresholds=scoring.thresholds)
               for s in scenes}
    out = {}
    for region, key in COLUMNS[set_name]:
        values = {name: m[region][key] for name, m in metrics.items() if region in m}
        out[f"{key} {region}"] = scene_average(values, scoring)
    return out


def ahead_of_faster_peers(rows: list[dict], set_name: str) -> None:
    """Mark each preset row: ahead (lower bad 2.0 all) of every peer at least as fast?"""
    key, time_key = f"{set_name} bad2.0 all", f"{set_name} s/pair"
    peers = [r for r in rows if r["kind"] == "peer" and key in r]
    for row in rows:
        if row["kind"] != "preset" or key not in row:
            continue
        faster = [p for p in peers if p[time_key] <= row[time_key]]
        row[f"{set_name} ahead"] = all(row[key] < p[key] for p in faster)


_PLACES = ((4.0, 4.0, "left"), (4.0, -12.0, "left"), (-4.0, 4.0, "right"),
           (-4.0, -12.0, "right"), (4.0, 13.0, "left"), (4.0, -21.0, "left"))
"""Where a label may go beside its marker, in order: its offset in points and alignment."""


def _label_box(x: float, y: float, label: str, place) -> tuple[float, float, float, float]:
    """``(left, right, bottom, top)`` in points of ``label`` at ``place`` (one of
    :data:`_PLACES`) beside a marker at ``(x, y)``: 8-point text, about 6 points per
    character, 9 high."""
    dx, dy, align = place
    width = 6.0 * len(label)
    left = x + dx if align == "left" else x + dx - width
    return left, left + width, y + dy, y + dy + 9.0


def _overlap(one, other) -> bool:
    """Whether two :func:`_label_box` boxes overlap."""
    return one[0] < other[1] and other[0] < one[1] and one[2] < other[3] and other[2] < one[3]


def _label_places(anchors, labels: list[str]) -> list[tuple[float, float, str]]:
    """Each label's place beside its marker (``anchors``: the markers in points, (N, 2)): the
    first of :data:`_PLACES` whose :func:`_label_box` overlaps no label placed before it,
    else the first."""
    boxes, places = [], []
    for (x, y), label in zip(anchors, labels):
        free = [place for place in _PLACES
                if not any(_overlap(_label_box(x, y, label, place), box) for box in boxes)]
        chosen = (free or _PLACES)[0]
        boxes.append(_label_box(x, y, label, chosen))
        places.append(chosen)
    return places


def _annotate(axis, rows: list[dict], set_name: str, dpi: float) -> list:
    """The methods' names beside their markers on ``axis`` (:func:`_label_places`)."""
    shown = [row for row in rows if f"{set_name} s/pair" in row]
    points = [(row[f"{set_name} s/pair"], row[f"{set_name} bad2.0 all"]) for row in shown]
    axis.autoscale_view()  # the limits the markers ask for, before they map to points
    anchors = axis.transData.transform(points) * 72.0 / dpi if points else []
    return [axis.annotate(row["method"], point, textcoords="offset points", xytext=(dx, dy),
                          ha=align, fontsize=8)
            for row, point, (dx, dy, align) in zip(
                shown, points, _label_places(anchors, [r["method"] for r in shown]))]


def plot(rows: list[dict], sets: list[str], path: Path) -> None:
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(sets), figsize=(5 * len(sets), 4), squeeze=False)
    for axis, set_name in zip(axes[0], sets):
        for row in rows:
            if f"{set_name} s/pair" in row:
                marker = "o" if row["kind"] == "preset" else "s"
                axis.scatter([row[f"{set_name} s/pair"]], [row[f"{set_name} bad2.0 all"]],
                             marker=marker, s=40)
        axis.set_xscale("log")
        axis.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        axis.set_xlabel("median time per pair (s, log)")
        axis.set_ylabel("bad 2.0, all pixels with ground truth (%)")
        axis.set_title(set_name)
        axis.grid(True, which="both", alpha=0.3)
    figure.suptitle("sswjax presets (circles) and peers (squares): lower left is better")
    # Labels placed where the axes end up: the layout makes room for them, so they are
    # placed, the layout made, and placed again on the final axes.
    labels = []
    for _ in range(2):
        figure.tight_layout()
        for label in labels:
            label.remove()
        labels = [label for axis, set_name in zip(axes[0], sets)
                  for label in _annotate(axis, rows, set_name, figure.dpi)]
    figure.savefig(path, dpi=120)
    plt.close(figure)


SET_TITLES = {  # set -> (heading, what its errors are)
    "trainingQ": ("MiddEval3 trainingQ",
                  "weighted means over the pairs, nonocc / all pixels with ground truth; "
                  "presets at each pair's exact shape"),
    "KITTI2012": ("KITTI 2012", "means over the pairs, all pixels with ground truth; presets "
                                "through 64-pixel shape buckets"),
    "Middlebury2001": ("Middlebury 2001", "means over the scenes, all pixels with ground truth; "
                                          "presets through 64-pixel shape buckets"),
}
"""How the results page names each set and its errors."""

PROTOCOL = (
    "Each pair is run once by every method (the presets compile), then each method in turn "
    "{repeats} times alternating with OpenCV SGBM 3-way: a method's time on a pair is its best "
    "run, its ratio the best run over the best of the SGBM runs beside it, so that both share "
    "the machine's state. \"s / pair\" is the median over a set's pairs of the time, \"x SGBM\" "
    "the median of the ratios; errors are bad 2.0, 1.0 and 0.5 (% of pixels more than that "
    "many pixels off; KITTI also 3.0). \"ahead\": lower bad 2.0 (all pixels) than every peer at "
    "least as fast. The best value of each column is in bold.")
"""The front's protocol as the results page states it."""


def read_rows(path: Path) -> list[dict]:
    """The rows of a ``front.csv``: numbers as floats, ``True``/``False`` as booleans, empty
    cells left out."""
    with open(path, newline="") as handle:
        return [{k: v if k in ("method", "kind") else v == "True" if v in ("True", "False")
                 else float(v) for k, v in row.items() if v != ""}
                for row in csv.DictReader(handle)]


def run_meta(folder: Path) -> dict:
    """What :func:`results_page` says of a run: ``folder/front.json`` as :func:`main` writes
    it, or, for a run written before it, the machine and repeats of ``front.md``'s last line
    and the date of the commit that added ``front.csv`` (``"unknown"`` without git)."""
    if (folder / "front.json").is_file():
        return json.loads((folder / "front.json").read_text())
    footer = next((line for line in (folder / "front.md").read_text().splitlines()[::-1]
                   if line.startswith("Devices:")), "") if (folder / "front.md").is_file() else ""
    machine, _, rest = footer.removeprefix("Devices: ").partition("; each method ")
    repeats = int(rest.split()[0]) if rest[:1].isdigit() else 3
    try:
        date = subprocess.run(["git", "log", "-1", "--format=%cs", "--", "front.csv"], cwd=folder,
                              capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        date = ""
    return {"date": date or "unknown", "machine": machine or "not recorded", "repeats": repeats,
            "command": f"python benchmarks/front.py --repeats {repeats} -o {folder.as_posix()}"
                       " (the run's options were not recorded: this is the default run)"}


def _label(row: dict) -> str:
    name = row["method"]
    if row.get("kind") == "preset" or name not in PEERS:
        return f"`{name}`"
    return f"{PEERS[name].summary.split(' (')[0].split(', ')[0]} (`{name}`)"


def _set_table(rows: list[dict], set_name: str) -> list[str]:
    """One set's Markdown table: each method's time, ratio, errors by threshold and whether it
    is ahead of every faster peer."""
    shown = [row for row in rows if f"{set_name} s/pair" in row]
    present = [(region, key) for region, key in COLUMNS[set_name]
               if any(f"{set_name} {key} {region}" in row for row in shown)]
    thresholds = list(dict.fromkeys(key for _, key in present))
    regions = {key: [region for region, k in present if k == key] for key in thresholds}
    best = {column: min(row[column] for row in shown if column in row)
            for column in (f"{set_name} {key} {region}" for key in thresholds
                           for region in regions[key]) if any(column in r for r in shown)}

    def cell(row, column, digits):
        if column not in row:
            return ""
        text = f"{row[column]:.{digits}f}"
        return f"**{text}**" if best.get(column) == row[column] else text

    header = ["method", "s / pair", "x SGBM",
              *(f"bad {key[3:]} ({' / '.join(regions[key])})" for key in thresholds), "ahead"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in shown:
        ahead = row.get(f"{set_name} ahead")
        cells = [_label(row), f"{row[f'{set_name} s/pair']:.3f}",
                 f"{row[f'{set_name} x sgbm']:.1f}",
                 *(" / ".join(cell(row, f"{set_name} {key} {region}", 2)
                              for region in regions[key]) for key in thresholds),
                 "" if ahead is None else "yes" if ahead else "no"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def results_page(rows: list[dict], meta: dict, folder: Path, page: Path) -> str:
    """The user's results page (Markdown) from a front run: its rows (``front.csv``), ``meta``
    (:func:`run_meta`), the run's ``folder`` and where the page goes (``page``, for the
    relative links). The page says that it is generated, and by which command."""
    link = Path(os.path.relpath(folder, page.parent)).as_posix()
    regenerate = (f"python benchmarks/front.py --page {page.as_posix()} "
                  f"--from {folder.as_posix()}")
    sets = [s for s in SETS if any(f"{s} s/pair" in row for row in rows)]
    command, _, remark = meta["command"].partition(" (")
    paragraphs = [
        f"Generated by `{regenerate}` from [front.csv]({link}/front.csv); do not edit by hand "
        "(a new run of the front writes it again with `--page`).",
        f"Figures as of {meta['date']}: {meta['machine']}; each method {meta['repeats']} times "
        f"per pair. The run: `{command}`" + (f" ({remark}." if remark else "."),
        PROTOCOL.format(repeats=meta["repeats"]),
        "The presets (`--preset NAME`, `sswjax.preset(NAME)`):"]
    out = ["# Results: every preset against the peers", ""]
    out += [paragraphs[0], ""]  # the command whole on its line, to copy
    for paragraph in paragraphs[1:]:
        out += [textwrap.fill(paragraph, 100, break_on_hyphens=False, break_long_words=False), ""]
    out[-1:] = [textwrap.fill(f"- `{name}`: {entry.summary}", 100, subsequent_indent="  ",
                              break_on_hyphens=False) for name, entry in sswjax.PRESETS.items()]
    out.append("")
    if (folder / "front.png").is_file():
        out += [f"![Time per pair against bad 2.0 on each set, presets and peers]({link}/front.png)",
                ""]
    for set_name in sets:
        title, what = SET_TITLES.get(set_name, (set_name, ""))
        out += [f"## {title}", "", textwrap.fill(f"Errors in %: {what}.", 100), "",
                *_set_table(rows, set_name), ""]
    return "\n".join(out)


def write_page(folder: Path, page: Path) -> None:
    """Write :func:`results_page` of the run in ``folder`` to ``page``."""
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text(results_page(read_rows(folder / "front.csv"), run_meta(folder), folder, page))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data", help="folder holding the three data sets")
    parser.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    parser.add_argument("--methods", nargs="+", default=[*sswjax.PRESETS, *PEERS],
                        choices=[*sswjax.PRESETS, *PEERS])
    parser.add_argument("--scenes", nargs="+", help="only these scenes (of every set)")
    parser.add_argument("--repeats", type=int, default=3, help="timed rounds per pair (3)")
    parser.add_argument("--bucket-step", type=int, default=64)
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results/front"))
    parser.add_argument("--plot-only", action="store_true",
                        help="redraw front.png from the front.csv in -o, running nothing")
    parser.add_argument("--page", type=Path,
                        help="also write the results page (docs/results.md) from the run")
    parser.add_argument("--from", dest="source", type=Path, metavar="FOLDER",
                        help="with --page: write the page from FOLDER's front.csv, running nothing")
    args = parser.parse_args(argv)
    if args.source is not None:
        if args.page is None:
            parser.error("--from needs --page")
        write_page(args.source, args.page)
        return 0
    if args.plot_only:
        rows = read_rows(args.output / "front.csv")
        plot(rows, [s for s in args.sets if any(f"{s} s/pair" in r for r in rows)],
             args.output / "front.png")
        return 0
    started = time.perf_counter()
    if REFERENCE not in args.methods:
        parser.error(f"--methods must include {REFERENCE}, the reference of the time ratios")
    runners = _method_runners(args.methods, args.bucket_step)
    rows = [{"method": name, "kind": "preset" if name in sswjax.PRESETS else "peer"}
            for name in runners]
    for set_name in args.sets:
        folder = SETS[set_name][0]
        scenes = [s for s in load_scenes(args.data / folder)
                  if not args.scenes or s.name in args.scenes]
        if not scenes:
            continue
        print(f"{set_name}: {len(scenes)} pairs", file=sys.stderr, flush=True)
        kind = "exact" if set_name == "trainingQ" else "bucket"
        seconds, ratios, maps = time_set(runners, scenes, kind, args.repeats)
        for row in rows:
            name = row["method"]
            times = seconds[name]
            row[f"{set_name} s/pair"] = float(np.median(list(times.values())))
            row[f"{set_name} x sgbm"] = float(np.median(list(ratios[name].values())))
            row.update({f"{set_name} {k}": v for k, v in score(maps[name], scenes, set_name).items()})
        ahead_of_faster_peers(rows, set_name)
    keys = list(dict.fromkeys(k for row in rows for k in row))
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for row in rows:
        cells = [("yes" if row[k] else "**no**") if isinstance(row.get(k), bool)
                 else f"{row[k]:.3f}" if k.endswith(("s/pair",)) and k in row
                 else f"{row[k]:.2f}" if isinstance(row.get(k), float)
                 else str(row.get(k, "")) for k in keys]
        lines.append("| " + " | ".join(cells) + " |")
    devices = ", ".join(str(d) for d in jax.devices())
    lines += ["", f"Devices: {devices}; {platform.processor() or platform.machine()}, "
                  f"JAX {jax.__version__}; each method {args.repeats} times per pair, "
                  "alternating with SGBM."]
    args.output.mkdir(parents=True, exist_ok=True)
    write_report(args.output, "front", "\n".join(lines), rows, keys)
    meta = {"date": datetime.date.today().isoformat(),
            "machine": f"{devices}; {platform.processor() or platform.machine()}, "
                       f"{os.cpu_count()} CPU cores, JAX {jax.__version__}",
            "repeats": args.repeats, "minutes": round((time.perf_counter() - started) / 60),
            "command": shlex.join(["python", "benchmarks/front.py", *(argv or sys.argv[1:])])}
    (args.output / "front.json").write_text(json.dumps(meta, indent=1) + "\n")
    plot(rows, [s for s in args.sets if any(f"{s} s/pair" in r for r in rows)],
         args.output / "front.png")
    if args.page is not None:
        write_page(args.output, args.page)
    return 0


if __name__ == "__main__":
    sys.exit(main())
