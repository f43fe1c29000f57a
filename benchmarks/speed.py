"""Where a preset's time goes: per stage against OpenCV SGBM, per compiled operation, and per
kernel of XLA's compile; the profiling tool.

``stages`` (the default when no subcommand is named)
    For every MiddEval3 scene: the first call (compilation + one run), the warm end-to-end time
    (median over ``--repeats``) alternating with OpenCV StereoSGBM 3-way on the same pair so
    that machine noise hits both, throughput in million disparity evaluations per second
    (W * H * ndisp / s), and each stage's warm time in the real compiled graph (cost,
    superpixels, aggregation, selection, refinement...: a profiler trace attributes every XLA
    operation to the outermost :class:`sswjax.graph.Stage` scope in its ``op_name``; stages
    may add up to more than the wall time, operations overlapping on the cores). Writes
    ``speed.{md,csv}``.
``ops``
    The compiled graph's most expensive XLA operations on one pair, from a profiler trace of a
    warm call: time, executions, the size of the fused computation and the stage it belongs to,
    then the time per stage. Finds what a stage profile hides: a fusion that carries work of
    the stage before it (XLA CPU fuses producers into consumers; a concatenation or padding at
    a fusion's root runs element by element: ``docs/notes/speed-and-memory.md``), or a buffer written
    afresh each call. ``--spans``: each stage's wall time too (its first start and last end,
    the union of its operations' intervals, their number), then the call's idle time.
``compile``
    What XLA's compile is made of: per configuration (``NAME=BASE:JSON`` or a preset), a new
    process compiles ``ssw_disparity`` on one trainingQ pair with the compilation cache off
    and XLA's verbose log on (``TF_CPP_MAX_VLOG_LEVEL=1``), and every "Compiled LLVM module:
    NAME time: T" line and XLA's own total are read from it: the compile's wall time (as XLA
    counts it and as the process measured it; the log slows both by about a tenth), the number
    of kernels, their summed LLVM time, the largest and the share under 10 ms. Says whether a
    compile is long because of a few large kernels or many small ones. Writes
    ``compile_kernels.{md,csv}``.

    python benchmarks/speed.py [stages] [--data ../shared/data] [--preset accurate]
        [--scenes Teddy Piano] [--repeats 5] [--pandora] [-o benchmarks/results]
    python benchmarks/speed.py ops --preset accurate --scene Motorcycle [--top 30] [--spans]
    python benchmarks/speed.py compile [--config accurate] [--config fast]
        [--config 'unaligned=accurate:{"alignment": null}'] [--scene Motorcycle]
        [-o benchmarks/results/compile_kernels]
"""

from __future__ import annotations

import argparse
import collections
import gzip
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import sswjax
from sswjax.api.images import prepare_pair
from sswjax.data.layouts import find_data_root, load_scenes
from sswjax.evaluation.peers import sgbm_disparity
from sswjax.graph import Stage

from _report import whole_pair_graph, write_report  # benchmarks/: on the path as a script

STAGES = tuple(stage.value for stage in Stage)
COMMANDS = ("stages", "ops", "compile")


# ---- a warm call's profiler trace ---------------------------------------------------------

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
    """The outermost stage scope in an ``op_name`` (``-`` when there is none): the band's
    cost, paths and fill count as the band."""
    found = [(f"{op_name}/".find(f"/{s}/"), s) for s in STAGES if f"/{s}/" in f"{op_name}/"]
    return min(found)[1] if found else "-"


def operation_events(left, right, params, ndisp, names) -> list[dict]:
    """The trace events (``name``, ``ts``, ``dur`` in microseconds) of the operations of one
    warm call; ``names`` from :func:`compiled_tables` (other thunks, loops among them, are
    left out so that no time counts twice)."""
    graph, extra = whole_pair_graph(params)
    for _ in range(2):
        jax.block_until_ready(graph(left, right, params, ndisp=ndisp, **extra))
    with tempfile.TemporaryDirectory() as directory:
        with jax.profiler.trace(directory):
            jax.block_until_ready(graph(left, right, params, ndisp=ndisp, **extra))
        (trace,) = Path(directory).rglob("*.trace.json.gz")
        events = json.loads(gzip.decompress(trace.read_bytes()))["traceEvents"]
    return [event for event in events if event.get("ph") == "X" and event.get("name") in names
            and not event["name"].startswith("while")]


def stage_profile(left, right, params, ndisp) -> dict[str, float]:
    """Seconds spent in each stage of one warm call of the whole pair's graph, from a profiler trace
    (operations outside every stage scope left out)."""
    graph, extra = whole_pair_graph(params)
    names, _ = compiled_tables(graph.lower(left, right, params, ndisp=ndisp, **extra)
                               .compile().as_text())
    seconds = dict.fromkeys(STAGES, 0.0)
    for event in operation_events(left, right, params, ndisp, names):
        stage = stage_of(names[event["name"]])
        if stage != "-":
            seconds[stage] += event["dur"] / 1e6
    return seconds


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


# ---- XLA's compile ------------------------------------------------------------------------

_CHILD = r"""
import json, sys, time
import jax
from sswjax.api.images import prepare_pair
from sswjax.data.layouts import load_scenes
sys.path.insert(0, sys.argv[4])
from _report import parse_config, whole_pair_graph
_, params = parse_config(sys.argv[3])
graph, extra = whole_pair_graph(params)
scene = load_scenes(sys.argv[1], scenes=[sys.argv[2]])[0]
left, right = map(jax.device_put, prepare_pair(scene.left, scene.right))
lowered = graph.lower(left, right, params, ndisp=scene.ndisp, **extra)
start = time.perf_counter()
lowered.compile()
print("COMPILE_SECONDS", json.dumps(time.perf_counter() - start), flush=True)
"""

_KERNEL = re.compile(r"Compiled LLVM module: (\S+) time: ([0-9.]+) (us|ms|s) ")
_TOTAL = re.compile(r"Compiling \[jit_ssw_(?:disparity|aligned)\] for CPU using JIT time: ([0-9.]+) (us|ms|s) ")
_UNIT = {"us": 1e-6, "ms": 1e-3, "s": 1.0}


def kernel_times(log: str) -> tuple[list[float], float | None]:
    """Seconds of each LLVM module compiled, and XLA's total, from a verbose XLA CPU log."""
    kernels = [float(t) * _UNIT[unit] for _, t, unit in _KERNEL.findall(log)]
    total = _TOTAL.search(log)
    return kernels, None if total is None else float(total.group(1)) * _UNIT[total.group(2)]


def compile_profile(config: str, data: Path, scene: str) -> dict:
    """One configuration compiled in a new process: its kernels and compile times."""
    env = {**os.environ, "TF_CPP_MIN_LOG_LEVEL": "0", "TF_CPP_MAX_VLOG_LEVEL": "1",
           "JAX_ENABLE_COMPILATION_CACHE": "false"}
    done = subprocess.run([sys.executable, "-c", _CHILD, str(data / "MiddEval3"), scene, config,
                           str(Path(__file__).parent)], env=env, capture_output=True,
                          text=True, check=True)
    kernels, xla_total = kernel_times(done.stderr)
    if not kernels or xla_total is None:
        raise RuntimeError(f"{config}: no kernel times in XLA's log (another jaxlib's format?)")
    measured = json.loads(done.stdout.split("COMPILE_SECONDS", 1)[1].split()[0])
    return {
        "config": config.split("=", 1)[0],
        "compile_s": measured,
        "xla_compile_s": xla_total,
        "kernels": len(kernels),
        "kernel_sum_s": sum(kernels),
        "kernel_median_ms": 1e3 * statistics.median(kernels),
        "kernel_max_ms": 1e3 * max(kernels),
        "under_10ms_pct": 100.0 * sum(t < 0.01 for t in kernels) / len(kernels),
    }


# ---- subcommands ---------------------------------------------------------------------------

def _timed(fn, *args):
    start = time.perf_counter()
    jax.block_until_ready(fn(*args))
    return time.perf_counter() - start


def bench_scene(scene, params, repeats, pandora=False):
    """One row of ``stages``: first call, warm and SGBM times, throughput, stage times."""
    left, right = map(jnp.asarray, prepare_pair(scene.left, scene.right))
    ndisp = scene.ndisp
    graph, extra = whole_pair_graph(params)
    full = lambda: graph(left, right, params, ndisp=ndisp, **extra)  # noqa: E731
    first = _timed(full)
    ssw_times, sgbm_times = [], []
    sgbm_disparity(scene.left, scene.right, ndisp)  # warm OpenCV's allocations too
    for _ in range(repeats):
        ssw_times.append(_timed(full))
        sgbm_times.append(_timed(lambda: sgbm_disparity(scene.left, scene.right, ndisp)))
    stages = stage_profile(left, right, params, ndisp)
    if pandora:  # one run: it takes seconds per pair, far above the machine's noise
        from sswjax.evaluation.peers import pandora_disparity

        pandora_s = _timed(lambda: pandora_disparity(scene.left, scene.right, ndisp))
    warm = float(np.median(ssw_times))
    sgbm = float(np.median(sgbm_times))
    height, width = scene.left.shape[:2]
    return {
        "scene": scene.name,
        "size": f"{width}x{height}x{ndisp}",
        "first_call_s": first,
        "warm_s": warm,
        "sgbm_s": sgbm,
        "ratio": warm / sgbm,
        "mde_per_s": width * height * ndisp / warm / 1e6,
        **{f"{k}_s": float(v) for k, v in stages.items()},
        **({"pandora_s": pandora_s, "pandora_ratio": pandora_s / warm} if pandora else {}),
    }


def _middeval3(data) -> Path:
    root = find_data_root(data=data)
    if (root / "MiddEval3").is_dir():  # the data sets' folder, as the other benchmarks take it
        root = root / "MiddEval3"
    return root


def run_stages(args) -> int:
    params = sswjax.Params() if args.params is None else sswjax.load_params(args.params)
    params = sswjax.preset(args.preset) if args.preset else params
    scenes = load_scenes(_middeval3(args.data), scenes=args.scenes)
    rows = []
    if args.pandora:  # its first call imports and registers plugins: keep that out of the timings
        from sswjax.evaluation.peers import pandora_disparity

        pandora_disparity(scenes[0].left, scenes[0].right, scenes[0].ndisp)
    for scene in scenes:
        rows.append(bench_scene(scene, params, args.repeats, pandora=args.pandora))
        print(f"{scene.name}: warm {rows[-1]['warm_s']:.3f} s, sgbm {rows[-1]['sgbm_s']:.3f} s",
              flush=True)
    keys = list(rows[0])
    median = {k: float(np.median([r[k] for r in rows])) for k in keys if k not in ("scene", "size")}
    rss_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    lines = [
        f"SSW ({args.preset or args.params or 'defaults'}) vs OpenCV StereoSGBM 3-way, {len(rows)} "
        f"pairs, median of {args.repeats} warm runs "
        f"each; jax {jax.__version__}, {jax.devices()[0].platform}; peak RSS {rss_gb:.2f} GB; "
        "stage columns: milliseconds from one profiled run",
        "",
        "| scene | W x H x D | first call s | SSW warm s | SGBM s | SSW / SGBM | Mde/s | "
        + " | ".join(f"{stage} ms" for stage in STAGES)
        + (" | Pandora s | Pandora / SSW" if args.pandora else "") + " |",
        "|---" * (7 + len(STAGES) + 2 * args.pandora) + "|",
    ]
    for r in rows + [{"scene": "**median**", "size": "", **median}]:
        stage_cells = " | ".join(f"{1e3 * r[f'{stage}_s']:.0f}" for stage in STAGES)
        lines.append(
            f"| {r['scene']} | {r['size']} | {r['first_call_s']:.2f} | {r['warm_s']:.3f} | "
            f"{r['sgbm_s']:.3f} | {r['ratio']:.1f} | {r['mde_per_s']:.0f} | {stage_cells} |"
            + (f" {r['pandora_s']:.2f} | {r['pandora_ratio']:.1f} |" if args.pandora else "")
        )
    write_report(args.output, "speed", "\n".join(lines), rows, keys)
    return 0


def run_ops(args) -> int:
    (scene,) = load_scenes(_middeval3(args.data), scenes=[args.scene])
    left, right = map(jnp.asarray, prepare_pair(scene.left, scene.right))
    params = sswjax.preset(args.preset)
    graph, extra = whole_pair_graph(params)
    names, sizes = compiled_tables(graph.lower(left, right, params, ndisp=scene.ndisp, **extra)
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
    return 0


def run_compile(args) -> int:
    rows = [compile_profile(config, args.data, args.scene)
            for config in args.config or ["accurate", "fast"]]
    lines = [
        f"XLA CPU's compile of `ssw_disparity` on trainingQ {args.scene}, cache off, verbose "
        "log on; one new process per configuration",
        "",
        "| config | compile s (process) | compile s (XLA) | kernels | LLVM s, summed | median "
        "kernel ms | largest ms | kernels under 10 ms % |",
        "|---|---|---|---|---|---|---|---|",
    ]
    lines += [f"| {r['config']} | {r['compile_s']:.2f} | {r['xla_compile_s']:.2f} | "
              f"{r['kernels']} | {r['kernel_sum_s']:.2f} | {r['kernel_median_ms']:.1f} | "
              f"{r['kernel_max_ms']:.0f} | {r['under_10ms_pct']:.0f} |" for r in rows]
    write_report(args.output, "compile_kernels", "\n".join(lines), rows, list(rows[0]))
    return 0


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in (*COMMANDS, "-h", "--help"):
        argv = ["stages", *argv]  # the stage table, as this script ran before it had others
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    sub = commands.add_parser("stages", help="per scene: time against SGBM and per stage")
    sub.add_argument("--data", type=Path,
                     help="MiddEval3 (or its split folder), or the folder holding it as the "
                          "other benchmarks take it (../shared/data)")
    sub.add_argument("--scenes", nargs="+")
    group = sub.add_mutually_exclusive_group()
    group.add_argument("--params", type=Path, help="parameters JSON (default: Params())")
    group.add_argument("--preset", choices=list(sswjax.PRESETS), help="a named preset")
    sub.add_argument("--repeats", type=int, default=5)
    sub.add_argument("--pandora", action="store_true",
                     help="also time CNES Pandora (census + SGM; pip install 'sswjax[pandora]')")
    sub.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    sub = commands.add_parser("ops", help="one pair's most expensive compiled operations")
    sub.add_argument("--data", type=Path,
                     help="the data sets' folder (../shared/data), MiddEval3 or its trainingQ")
    sub.add_argument("--preset", default="accurate", choices=list(sswjax.PRESETS))
    sub.add_argument("--scene", default="Motorcycle")
    sub.add_argument("--top", type=int, default=30)
    sub.add_argument("--spans", action="store_true", help="each stage's wall time too")
    sub = commands.add_parser("compile", help="the kernels of XLA's compile, per configuration")
    sub.add_argument("--config", action="append", default=[],
                     help="NAME=BASE:JSON or a preset's name; repeatable (accurate, fast)")
    sub.add_argument("--scene", default="Motorcycle", help="the trainingQ pair compiled for")
    sub.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                     / "shared" / "data")
    sub.add_argument("-o", "--output", type=Path,
                     default=Path("benchmarks/results/compile_kernels"))
    args = parser.parse_args(argv)
    return {"stages": run_stages, "ops": run_ops, "compile": run_compile}[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
