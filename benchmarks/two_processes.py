"""What two processes gain over one on this machine, without Dask: the ceiling of any scheduler.

The same work is done by one process, then by two independent processes started together
(each half of it), alternating, ``--rounds`` times; the throughput ratio is the one process's
seconds over the two's (the later of the two to finish). Three kinds of work:

``pairs``
    the 30 KITTI 2012 pairs matched with ``accurate`` (ndisp 128, as ``benchmarks/scale.py``),
    each process on a core of its own with a worker's environment, as a Dask worker is
    (:func:`sswjax.cluster.workers.pin_workers`); two processes take every other pair.
    Each process first matches one pair of each of its shapes (compiles, or reads the cache),
    then waits until both are ready: only the loops are timed (reading the images included).
``stream``
    a memory-bandwidth probe: NumPy copies and adds over float64 arrays of 256 MB each, far
    larger than the 32 MB L3 cache (``b[:] = a`` moves 16 bytes an element, ``c[:] = a + b``
    24); the GB/s of one process and of both together.
``cached``
    the control: arithmetic on arrays that fit in the L1 cache (``sin`` of 4,096 numbers, again
    and again), which the memory does not limit. If it scales by ~2x and ``stream`` does not,
    the cores are two but the memory is one; if it does not scale either, the two virtual cores
    share one physical core (or the host holds them back).

Writes ``benchmarks/results/two_processes.{md,json}``; the 1-minute load average before each
run is recorded (run it on a quiet machine).

    python benchmarks/two_processes.py [--data ../shared/data] [--rounds 3]
                                       [--kinds pairs stream cached]
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import sswjax
from sswjax.cluster.pairs import folder_pairs
from sswjax.cluster.workers import worker_environment
from sswjax.data.io import read_image
from sswjax.runtime.compilation import enable_compilation_cache

KINDS = ("pairs", "stream", "cached")
STREAM_ELEMENTS = 32 * 2**20          # float64: 256 MB an array
STREAM_REPEATS = 48                   # copies and adds, for the whole work
CACHED_ELEMENTS, CACHED_REPEATS = 4096, 100_000
sys.path.insert(0, str(Path(__file__).parent))
from _report import write_json_report

NDISP = 128


def _pairs_work(data: Path, part: int, parts: int):
    """The child's pairs (every ``parts``-th from ``part``), warmed up; returns the loop."""
    enable_compilation_cache()
    pairs = folder_pairs(data / "KITTI2012/training/image_0",
                         data / "KITTI2012/training/image_1")[part::parts]
    params = sswjax.preset("accurate")

    def one(pair):
        return sswjax.match(read_image(pair.left), read_image(pair.right), NDISP, params=params)

    for pair in {p.size: p for p in pairs}.values():     # one of each shape: compiled
        one(pair)

    def loop():
        for pair in pairs:
            one(pair)
        return {"pairs": len(pairs)}

    return loop


def _stream_work(part: int, parts: int):
    """Copies and adds over three arrays of :data:`STREAM_ELEMENTS` (this child's share)."""
    a, b, c = (np.full(STREAM_ELEMENTS, 1.0 + i) for i in range(3))    # pages touched now
    repeats = STREAM_REPEATS // parts

    def loop():
        for _ in range(repeats):
            np.copyto(b, a)
            np.add(a, b, out=c)
        return {"bytes": repeats * STREAM_ELEMENTS * 8 * (2 + 3)}

    return loop


def _cached_work(part: int, parts: int):
    """``sin`` of :data:`CACHED_ELEMENTS` numbers, held in the L1 cache (this child's share)."""
    x, y = np.linspace(0, 1, CACHED_ELEMENTS), np.empty(CACHED_ELEMENTS)
    repeats = CACHED_REPEATS // parts

    def loop():
        for _ in range(repeats):
            np.sin(x, out=y)
        return {"numbers": repeats * CACHED_ELEMENTS}

    return loop


def child(kind: str, part: int, parts: int, data: Path) -> None:
    """Prepare, say ``ready``, wait for a line on stdin, run the loop, print its seconds."""
    loop = _pairs_work(data, part, parts) if kind == "pairs" else \
        _stream_work(part, parts) if kind == "stream" else _cached_work(part, parts)
    print("ready", flush=True)
    sys.stdin.readline()
    start = time.perf_counter()
    done = loop()
    print(json.dumps({"seconds": time.perf_counter() - start, **done}), flush=True)


def run(kind: str, parts: int, data: Path) -> dict:
    """``parts`` children of ``kind`` started together: each one's result, and the load before."""
    env = dict(os.environ, **worker_environment())
    cores = sorted(os.sched_getaffinity(0))
    children = [subprocess.Popen([sys.executable, __file__, "--child", kind, "--part", str(i),
                                  "--parts", str(parts), "--data", str(data)],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
                                 preexec_fn=functools.partial(os.sched_setaffinity, 0,
                                                              {cores[i % len(cores)]}))
                for i in range(parts)]
    for process in children:
        line = process.stdout.readline().strip()
        if line != "ready":
            raise RuntimeError(f"a {kind} child did not start: {line!r}")
    load = os.getloadavg()[0]
    for process in children:          # both go at once
        process.stdin.write("go\n")
        process.stdin.flush()
    results = []
    for process in children:
        out, _ = process.communicate()
        if process.returncode != 0:
            raise RuntimeError(f"a {kind} child failed with status {process.returncode}")
        results.append(json.loads(out.strip().splitlines()[-1]))
    return {"kind": kind, "processes": parts, "load_before": load,
            "seconds": max(r["seconds"] for r in results), "children": results}


def table(rows: list[dict]) -> str:
    lines = ["# One process against two independent ones (no Dask)", "",
             "`python benchmarks/two_processes.py`: the same work by one process, then by two "
             "started together (half each), alternating; ratio: one's seconds over the two's "
             "(the later to finish). Every process on a core of its own (its CPU affinity, "
             f"as a Dask worker's); {os.cpu_count()} cores. Load: the 1-minute load average before each "
             "run.", "",
             "| work | round | 1 process s | 2 processes s (each) | 2 over 1 | load before (1 / 2) |",
             "|---|---:|---:|---:|---:|---|"]
    summary = []
    for kind in KINDS:
        ones = [r for r in rows if r["kind"] == kind and r["processes"] == 1]
        twos = [r for r in rows if r["kind"] == kind and r["processes"] == 2]
        for i, (one, two) in enumerate(zip(ones, twos)):
            each = " / ".join(f"{c['seconds']:.1f}" for c in two["children"])
            lines.append(f"| {kind} | {i + 1} | {one['seconds']:.2f} | {two['seconds']:.2f} "
                         f"({each}) | {one['seconds'] / two['seconds']:.2f}x | "
                         f"{one['load_before']:.2f} / {two['load_before']:.2f} |")
        if ones and twos:
            ratio = np.median([o["seconds"] / t["seconds"] for o, t in zip(ones, twos)])
            summary.append(f"- {kind}: **{ratio:.2f}x** (median of {len(twos)} rounds)"
                           + _rate(kind, ones, twos))
    return "\n".join(lines + [""] + summary)


def _rate(kind: str, ones: list[dict], twos: list[dict]) -> str:
    """The rates behind a ratio, in the kind's units (medians)."""
    def rate(rows, key, scale):
        return np.median([sum(c[key] for c in r["children"]) / r["seconds"] / scale for r in rows])

    if kind == "pairs":
        return (f"; pairs / min: {60 * rate(ones, 'pairs', 1):.1f} one process, "
                f"{60 * rate(twos, 'pairs', 1):.1f} two")
    if kind == "stream":
        return (f"; memory traffic: {rate(ones, 'bytes', 1e9):.1f} GB/s one process, "
                f"{rate(twos, 'bytes', 1e9):.1f} GB/s two together")
    return (f"; sines: {rate(ones, 'numbers', 1e6):.0f} M/s one process, "
            f"{rate(twos, 'numbers', 1e6):.0f} M/s two")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--kinds", nargs="+", choices=KINDS, default=list(KINDS))
    parser.add_argument("--results", type=Path, default=Path(__file__).parent / "results")
    parser.add_argument("--child", choices=KINDS, help=argparse.SUPPRESS)
    parser.add_argument("--part", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--parts", type=int, default=1, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    data = args.data.resolve()
    if args.child:
        child(args.child, args.part, args.parts, data)
        return 0
    rows = []
    for round_ in range(args.rounds):
        for kind in args.kinds:
            for parts in (1, 2) if round_ % 2 == 0 else (2, 1):    # which goes first alternates
                rows.append(run(kind, parts, data))
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    text = table(rows)
    write_json_report(args.results, "two_processes", text, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
