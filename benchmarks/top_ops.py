"""The compiled graph's most expensive XLA operations on one MiddEval3 pair, from a profiler
trace of a warm call: time, number of executions, the size of the fused computation and the
stage scope each belongs to, then the time per stage.

Finds what a stage profile hides: a fusion that carries work of the stage before it (XLA CPU
fuses producers into their consumers, and a concatenation or padding at the root of a fusion
runs element by element, see docs/speed-and-memory.md), or a buffer written afresh each call.

With ``--spans``, each stage's wall time too: when its first operation starts and its last
ends, the time any of its operations runs (the union of their intervals: operations of a stage
overlap, and an operation's own time counts once however many threads run its partitions) and
how many operations it runs, then the time between operations of the whole call.

    python benchmarks/top_ops.py --preset accurate --scene Motorcycle [--top 30] [--spans]
                                 [--data DIR]
"""

from __future__ import annotations

import argparse
import collections
import gzip
import json
import re
import tempfile
from pathlib import Path

import jax
import jax.numpy as jnp

import sswjax
from sswjax.api.images import prepare_pair
from sswjax.data.layouts import find_data_root, load_scenes
from sswjax.graph import Stage, ssw_disparity

STAGES = tuple(stage.value for stage in Stage)


def compiled_tables(text: str) -> tuple[dict[str, str], dict[str, int]]:
    """From a compiled module's text: instruction -> ``op_name``, instruction -> lines of the
    computation it calls (0 for an unfused operation)."""
    names, calls, lengths = {}, {}, collections.Counter()
    current = None
    for line in text.splitlines():
        header = re.match(r"%(\S+) .*\{$", line)
        if header:
            current = header.group(1)
            continue
        if line.startswith("}"):
            current = None
        elif current:
            lengths[current] += 1
        op = re.match(r'\s*(?:ROOT )?%(\S+) = .*?op_name="([^"]*)"', line)
        if op:
            names[op.group(1)] = op.group(2)
        called = re.match(r"\s*(?:ROOT )?%(\S+) = .*calls=%([^,\s]+)", line)
        if called:
            calls[called.group(1)] = called.group(2)
    return names, {name: lengths.get(callee, 0) for name, callee in calls.items()}


def stage_of(op_name: str) -> str:
    """The outermost stage scope in an ``op_name`` (``-`` when there is none)."""
    found = [(f"{op_name}/".find(f"/{s}/"), s) for s in STAGES if f"/{s}/" in f"{op_name}/"]
    return min(found)[1] if found else "-"


def operation_events(left, right, params, ndisp, names) -> list[dict]:
    """The trace events (``name``, ``ts``, ``dur`` in microseconds) of the operations of one
    warm call; ``names`` from :func:`compiled_tables` (other thunks, loops among them, are
    left out)."""
    for _ in range(2):
        jax.block_until_ready(ssw_disparity(left, right, params, ndisp=ndisp))
    with tempfile.TemporaryDirectory() as directory:
        with jax.profiler.trace(directory):
            jax.block_until_ready(ssw_disparity(left, right, params, ndisp=ndisp))
        (trace,) = Path(directory).rglob("*.trace.json.gz")
        events = json.loads(gzip.decompress(trace.read_bytes()))["traceEvents"]
    return [event for event in events if event.get("ph") == "X" and event.get("name") in names
            and not event["name"].startswith("while")]


def profile(events: list[dict]) -> list[tuple[str, float, int]]:
    """``(instruction, milliseconds, executions)``, most expensive first."""
    total, count = collections.Counter(), collections.Counter()
    for event in events:
        total[event["name"]] += event["dur"] / 1e3
        count[event["name"]] += 1
    return [(name, ms, count[name]) for name, ms in total.most_common()]


def busy_ms(intervals: list[tuple[float, float]]) -> float:
    """Milliseconds covered by the union of ``(start, end)`` microsecond intervals."""
    covered, reach = 0.0, None
    for start, end in sorted(intervals):
        if reach is None or start > reach:
            covered, reach = covered + end - start, end
        elif end > reach:
            covered, reach = covered + end - reach, end
    return covered / 1e3


def spans(events: list[dict], names: dict[str, str]) -> str:
    """Each stage's first start and last end (ms from the call's first operation), the time
    its operations run (union) and their number; then the call's span and idle time."""
    origin = min(event["ts"] for event in events)
    by_stage = collections.defaultdict(list)
    for event in events:
        by_stage[stage_of(names[event["name"]])].append((event["ts"] - origin,
                                                         event["ts"] - origin + event["dur"]))
    lines = ["| stage | first ms | last ms | busy ms | operations |", "|---|---|---|---|---|"]
    for stage, intervals in sorted(by_stage.items(), key=lambda item: min(item[1])):
        lines.append(f"| {stage} | {min(intervals)[0] / 1e3:.1f} | "
                     f"{max(end for _, end in intervals) / 1e3:.1f} | {busy_ms(intervals):.1f} "
                     f"| {len(intervals)} |")
    every = [interval for intervals in by_stage.values() for interval in intervals]
    span = max(end for _, end in every) / 1e3
    lines.append(f"\ncall: {span:.1f} ms from the first operation to the last, "
                 f"{span - busy_ms(every):.1f} ms of it with no operation running")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path,
                        help="the data sets' folder (../shared/data), MiddEval3 or its trainingQ")
    parser.add_argument("--preset", default="accurate", choices=list(sswjax.PRESETS))
    parser.add_argument("--scene", default="Motorcycle")
    parser.add_argument("--top", type=int, default=30)
    parser.add_argument("--spans", action="store_true", help="each stage's wall time too")
    args = parser.parse_args()
    root = find_data_root(data=args.data)
    if (root / "MiddEval3").is_dir():  # the data sets' folder, as front.py and band.py take it
        root = root / "MiddEval3"
    (scene,) = load_scenes(root, scenes=[args.scene])
    left, right = map(jnp.asarray, prepare_pair(scene.left, scene.right))
    params = sswjax.preset(args.preset)
    names, sizes = compiled_tables(ssw_disparity.lower(left, right, params, ndisp=scene.ndisp)
                                   .compile().as_text())
    events = operation_events(left, right, params, scene.ndisp, names)
    rows = profile(events)
    print(f"{args.preset} on {scene.name} ({left.shape[1]} x {left.shape[0]} x {scene.ndisp}): "
          f"{sum(ms for _, ms, _ in rows):.0f} ms of operations (both threads)")
    print("| ms | runs | operation | fused lines | stage | op_name |\n|---|---|---|---|---|---|")
    for name, ms, runs in rows[:args.top]:
        print(f"| {ms:.1f} | {runs} | {name} | {sizes.get(name, 0)} | {stage_of(names[name])} "
              f"| {names[name][-80:]} |")
    by_stage = collections.Counter()
    for name, ms, _ in rows:
        by_stage[stage_of(names[name])] += ms
    print("\nby stage (ms):", ", ".join(f"{s} {ms:.0f}" for s, ms in by_stage.most_common()))
    if args.spans:
        print("\n" + spans(events, names))


if __name__ == "__main__":
    main()
