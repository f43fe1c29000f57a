"""The compiled graph's most expensive XLA operations on one MiddEval3 pair, from a profiler
trace of a warm call: time, number of executions, the size of the fused computation and the
stage scope each belongs to, then the time per stage.

Finds what a stage profile hides: a fusion that carries work of the stage before it (XLA CPU
fuses producers into their consumers, and a concatenation or padding at the root of a fusion
runs element by element, see docs/speed-and-memory.md), or a buffer written afresh each call.

    python benchmarks/top_ops.py --preset accurate --scene Motorcycle [--top 30] [--data DIR]
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


def profile(left, right, params, ndisp, names) -> list[tuple[str, float, int]]:
    """``(instruction, milliseconds, executions)`` of one warm call, most expensive first;
    ``names`` from :func:`compiled_tables` (other thunks, loops among them, are left out)."""
    for _ in range(2):
        jax.block_until_ready(ssw_disparity(left, right, params, ndisp=ndisp))
    with tempfile.TemporaryDirectory() as directory:
        with jax.profiler.trace(directory):
            jax.block_until_ready(ssw_disparity(left, right, params, ndisp=ndisp))
        (trace,) = Path(directory).rglob("*.trace.json.gz")
        events = json.loads(gzip.decompress(trace.read_bytes()))["traceEvents"]
    total, count = collections.Counter(), collections.Counter()
    for event in events:
        name = event.get("name")
        if event.get("ph") != "X" or name not in names or name.startswith("while"):
            continue
        total[name] += event["dur"] / 1e3
        count[name] += 1
    return [(name, ms, count[name]) for name, ms in total.most_common()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path)
    parser.add_argument("--preset", default="accurate", choices=list(sswjax.PRESETS))
    parser.add_argument("--scene", default="Motorcycle")
    parser.add_argument("--top", type=int, default=30)
    args = parser.parse_args()
    (scene,) = load_scenes(find_data_root(data=args.data), scenes=[args.scene])
    left, right = map(jnp.asarray, prepare_pair(scene.left, scene.right))
    params = sswjax.preset(args.preset)
    names, sizes = compiled_tables(ssw_disparity.lower(left, right, params, ndisp=scene.ndisp)
                                   .compile().as_text())
    rows = profile(left, right, params, scene.ndisp, names)
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


if __name__ == "__main__":
    main()
