"""Scaling: the 30 KITTI 2012 pairs on 1 and 2 Dask workers against the in-process folder loop,
and the cost of tiles on full-resolution input.

Folders: ``sswjax match image_0 image_1 --ndisp 128 -o OUT`` (the ``accurate`` preset) in a
fresh process each time, four ways: the in-process loop as it is (XLA's threads on every
core), the same loop on one core (the process's CPU affinity set before it starts, and the
environment every worker gets: a worker as :func:`sswjax.cluster.workers.pin_workers` makes
it), ``--workers 1`` and ``--workers 2`` (each worker on a core of its own). Each first runs
on one pair of each shape, to fill the compilation cache of its XLA flags (the workers' flags
compile other executables), then is timed on all the pairs: the command's wall time, and the
loop's (the summary line's seconds: from the first pair to the last map, the cluster's start
included). Ratios: 2 workers over 1 (goal >= 1.7 on this 2-core machine) and Dask's overhead,
1 worker against the loop on one core (goal <= 10 %).

Tiles: a pair of MiddEval3's full resolution (Motorcycle's quarter-resolution images resized
to 1988 x 2964, ndisp 280) and a KITTI pair (its own full resolution, 1226 x 370, ndisp 128),
matched whole and in the strips and tiles named below, with each collar of ``--overlaps``
(default: the plan's), each the second of two calls in one process (compiled): the time ratio
tiled / whole. Writes ``benchmarks/results/scale.md``.

    python benchmarks/scale.py [--data ../shared/data] [--skip-folders] [--skip-tiles]
                               [--overlaps N ...] [--report-only]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import sswjax
from sswjax.cluster.pairs import folder_pairs
from sswjax.cluster.workers import worker_environment

NDISP = 128
FOLDER_RUNS = {  # name -> (extra options, extra environment)
    "in-process loop": ([], {}),
    "in-process loop on 1 core": ([], "pinned"),
    "--workers 1": (["--workers", "1"], {}),
    "--workers 2": (["--workers", "2"], {}),
}
TILINGS = {  # pair -> the plans timed against the whole image
    "MiddEval3 F (1988 x 2964, ndisp 280)": [{"strip_rows": 512}, {"tile": 1024}],
    "KITTI 000100 (370 x 1226, ndisp 128)": [{"strip_rows": 128}, {"tile": 256}],
}

TILE_CHILD = r"""
import json, sys, time
import numpy as np
import sswjax
from skimage.transform import resize
from sswjax.data.io import read_image
from sswjax.runtime.compilation import enable_compilation_cache
enable_compilation_cache()
data, which, plan = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
if which.startswith("MiddEval3"):
    folder = f"{data}/MiddEval3/trainingQ/Motorcycle"
    left, right = (resize(read_image(f"{folder}/{name}"), (1988, 2964), order=1,
                          preserve_range=True).astype(np.uint8) for name in ("im0.png", "im1.png"))
    ndisp = 280
else:
    left = read_image(f"{data}/KITTI2012/training/image_0/000100_10.png")
    right = read_image(f"{data}/KITTI2012/training/image_1/000100_10.png")
    ndisp = 128
plan = sswjax.ExecutionPlan(**plan)
seconds = []
for _ in range(2):
    start = time.perf_counter()
    sswjax.match(left, right, ndisp, plan=plan, check_memory=False)
    seconds.append(time.perf_counter() - start)
print(json.dumps(seconds))
"""


def folder_run(folders: tuple[Path, Path], out: Path, options, environment
               ) -> tuple[float, float]:
    """``(command seconds, loop seconds)`` of one folder run of ``folders`` (left, right)."""
    pinned = environment == "pinned"
    env = dict(os.environ, **(worker_environment() if pinned else environment))
    argv = [sys.executable, "-m", "sswjax.cli", "match", str(folders[0]), str(folders[1]),
            "--ndisp", str(NDISP), "-o", str(out), *options]
    start = time.perf_counter()
    run = subprocess.run(argv, env=env, capture_output=True, text=True, check=False,
                         preexec_fn=_on_first_core if pinned else None)
    seconds = time.perf_counter() - start
    if run.returncode != 0:
        raise RuntimeError(run.stderr)
    loop = float(re.search(r"shapes, ([0-9.]+) s", run.stdout).group(1))
    return seconds, loop


def _on_first_core() -> None:
    """In the child before it starts: on one core, as a worker (its threads inherit it)."""
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


def _one_of_each_shape(data: Path, scratch: Path) -> tuple[Path, Path]:
    """Folders (links) holding the first KITTI pair of each image size: the warm-up."""
    left, right = data / "KITTI2012/training/image_0", data / "KITTI2012/training/image_1"
    seen = {}
    for pair in folder_pairs(left, right):
        seen.setdefault(pair.size, pair)
    warm = scratch / "warm-left", scratch / "warm-right"
    for folder, side in zip(warm, ("left", "right")):
        folder.mkdir()
        for pair in seen.values():
            (folder / pair.name).symlink_to(getattr(pair, side))
    return warm


def measure_folders(data: Path, rounds: int = 1) -> list[dict]:
    """Each run of :data:`FOLDER_RUNS`, ``rounds`` times, in turn (the order reversed every
    other round)."""
    rows = []
    kitti = data / "KITTI2012/training/image_0", data / "KITTI2012/training/image_1"
    count = len(folder_pairs(*kitti))
    with tempfile.TemporaryDirectory() as scratch:
        warm = _one_of_each_shape(data, Path(scratch))
        for round_ in range(rounds):
            names = list(FOLDER_RUNS) if round_ % 2 == 0 else list(FOLDER_RUNS)[::-1]
            for name in names:
                options, environment = FOLDER_RUNS[name]
                folder_run(warm, Path(scratch) / f"warm-{len(rows)}", options, environment)
                load = os.getloadavg()[0]
                command, loop = folder_run(kitti, Path(scratch) / f"run-{len(rows)}", options,
                                           environment)
                rows.append({"what": name, "round": round_ + 1, "command_s": command,
                             "loop_s": loop, "pairs": count,
                             "pairs_per_minute": count * 60 / loop, "load_before": load,
                             "load_average": os.getloadavg()[0]})
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    return rows


def measure_tiles(data: Path, overlaps: list[int]) -> list[dict]:
    rows = []
    for pair, plans in TILINGS.items():
        times = {}
        for plan in [{}] + [dict(p, strip_overlap=c) for c in overlaps for p in plans]:
            run = subprocess.run([sys.executable, "-c", TILE_CHILD, str(data), pair,
                                  json.dumps(plan)], capture_output=True, text=True, check=False)
            if run.returncode != 0:
                raise RuntimeError(run.stderr)
            times[json.dumps(plan)] = json.loads(run.stdout.strip().splitlines()[-1])[1]
            whole = times["{}"]
            rows.append({"pair": pair, "plan": json.dumps(plan) if plan else "whole",
                         "seconds": times[json.dumps(plan)],
                         "ratio": times[json.dumps(plan)] / whole,
                         "load_average": os.getloadavg()[0]})
            print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    return rows


def table(folders: list[dict], tiles: list[dict]) -> str:
    lines = ["# Scaling on this machine (2 cores)", "", "`python benchmarks/scale.py`.", ""]
    if folders:
        by = {name: statistics.median(r["loop_s"] for r in folders if r["what"] == name)
              for name in FOLDER_RUNS}
        rounds = max(r.get("round", 1) for r in folders)
        lines += ["## 30 KITTI 2012 pairs, `accurate`, ndisp 128", "",
                  (f"{rounds} round(s), the runs in turn (every other round in reverse); the "
                   "ratios are of the median loop seconds."), "",
                  "| run | round | command s | loop s | pairs / min | load (1 min) before / after |",
                  "|---|---:|---:|---:|---:|---|"]
        lines += [f"| {r['what']} | {r.get('round', 1)} | {r['command_s']:.1f} | "
                  f"{r['loop_s']:.1f} | {r['pairs_per_minute']:.1f} | "
                  f"{r.get('load_before', float('nan')):.2f} / {r['load_average']:.2f} |"
                  for r in sorted(folders, key=lambda r: list(FOLDER_RUNS).index(r["what"]))]
        one, two = by["--workers 1"], by["--workers 2"]
        pinned, loop = by["in-process loop on 1 core"], by["in-process loop"]
        lines += ["", (f"- 2 workers over 1: **{one / two:.2f}x** the throughput (goal >= 1.7); "
                       f"over the in-process loop: {loop / two:.2f}x."),
                  (f"- Dask's overhead, 1 worker against the loop on one core: "
                   f"**{100 * (one / pinned - 1):+.1f} %** (goal <= 10 %); against the loop as "
                   f"it is: {100 * (one / loop - 1):+.1f} %."), ""]
        load = max(r.get("load_before", r["load_average"]) for r in folders)
        if load > (os.cpu_count() or 1):
            lines += [(f"The 1-minute load average before a run reached {load:.1f} on "
                       f"{os.cpu_count()} cores. It lags by about a minute, so it counts the "
                       "previous run's own workers as well as any other job: where the rounds "
                       "disagree, other jobs shared the machine."), ""]
    if tiles:
        lines += ["## The cost of tiles (`accurate`, compiled)", "",
                  "| pair | plan | s | tiled / whole | load average (1 min) after |",
                  "|---|---|---:|---:|---:|"]
        lines += [f"| {r['pair']} | {r['plan']} | {r['seconds']:.1f} | {r['ratio']:.2f} | "
                  f"{r.get('load_average', float('nan')):.1f} |" for r in tiles]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--skip-folders", action="store_true",
                        help="keep the folders' figures of the last run (scale.json)")
    parser.add_argument("--skip-tiles", action="store_true",
                        help="keep the tiles' figures of the last run (scale.json)")
    parser.add_argument("--rounds", type=int, default=1,
                        help="how many times each folder run is timed, in turn")
    parser.add_argument("--overlaps", type=int, nargs="+",
                        default=[sswjax.ExecutionPlan().strip_overlap],
                        help="the collars the tiles are timed with (default: the plan's)")
    parser.add_argument("--results", type=Path, default=Path(__file__).parent / "results")
    parser.add_argument("--report-only", action="store_true",
                        help="write scale.md again from scale.json, measuring nothing")
    args = parser.parse_args(argv)
    data = args.data.resolve()
    saved_path = args.results / "scale.json"     # a part not measured is kept from the last run
    saved = json.loads(saved_path.read_text()) if saved_path.exists() else \
        {"folders": [], "tiles": []}
    skip_folders = args.skip_folders or args.report_only
    skip_tiles = args.skip_tiles or args.report_only
    folders = saved["folders"] if skip_folders else measure_folders(data, args.rounds)
    tiles = saved["tiles"] if skip_tiles else measure_tiles(data, args.overlaps)
    text = table(folders, tiles)
    print(text)
    args.results.mkdir(parents=True, exist_ok=True)
    (args.results / "scale.md").write_text(text + "\n")
    (args.results / "scale.json").write_text(json.dumps({"folders": folders, "tiles": tiles},
                                                        indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
