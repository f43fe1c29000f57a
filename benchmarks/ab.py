"""Two versions of the code, A against B: a stage change timed on the whole graph, and every
preset's maps hashed to prove a change bit-neutral; the A/B tool.

``graph``
    On this host two runs minutes apart can differ by more than a stage change saves (the
    whole machine is at times twice as slow), and a profile's operation times overstate what a
    change saves in wall time: XLA CPU runs an operation's partitions on both threads, and
    several operations can overlap. Here the graph is compiled twice in one process: once with
    named functions of the package taken from the commit ``--base`` (their module's source at
    that commit, run as a module of its own beside the package, so that its imports are the
    tree's), once as the tree has them. The two executables then run in turn, the first
    alternating, on the same pair; each call's wall and CPU time is kept, and the maps of the
    two are compared bit for bit. A function that the graph's modules imported by name
    (``from m import f``) is looked up in the importing module: swap it there
    (``--swap sswjax.graph.volume:fold_volume``).
``hashes``
    SHA-256 of every map each preset computes on the shared data sets: run it on two commits
    and ``diff`` the outputs; a refactoring that must not change results shows no difference.
    Each preset runs in a fresh process (one preset's ~50 shapes stay far from the memory
    mappings' limit). Per pair it hashes the float32 disparity of ``sswjax.match`` at the exact
    shape, and on Middlebury 2001 the three maps of ``sswjax.match_with_confidence`` too. Only
    names every version of sswjax has are used (the other subcommand's imports wait until it
    runs), so the same script measures an older checkout
    (``PYTHONPATH=/path/to/old/checkout python benchmarks/ab.py hashes ...``).

    python benchmarks/ab.py graph --base 6eca509 --swap sswjax.stages.sgm:path_penalties
        [--swap MODULE:NAME[,NAME]] [--preset accurate] [--scenes Motorcycle Teddy]
        [--rounds 10] [--data DIR]
    python benchmarks/ab.py hashes [--data ../shared/data] [--presets paper accurate fast finest]
        [--sets MiddEval3 KITTI2012 Middlebury2001] -o hashes.txt
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import statistics
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np

import sswjax
from sswjax.data.layouts import load_scenes

REPO = Path(__file__).resolve().parents[1]
SETS = ("MiddEval3", "KITTI2012", "Middlebury2001")
PRESETS = ("paper", "accurate", "fast", "finest")


# ---- graph: a stage change timed ----------------------------------------------------------

def base_functions(commit: str, module_name: str, names: list[str]) -> dict:
    """The functions ``names`` of ``module_name`` as its source at ``commit`` defines them."""
    path = module_name.replace(".", "/") + ".py"
    source = subprocess.run(["git", "-C", str(REPO), "show", f"{commit}:{path}"],
                            check=True, capture_output=True, text=True).stdout
    old = types.ModuleType(f"{module_name}@{commit}")
    old.__file__ = str(REPO / path)
    exec(compile(source, f"{commit}:{path}", "exec"), old.__dict__)
    return {name: getattr(old, name) for name in names}


def swaps(commit: str, specs: list[str]) -> list[tuple]:
    """``(module, name, tree's function, base's function)`` for each ``MODULE:NAME[,NAME]``."""
    found = []
    for spec in specs:
        module_name, names = spec.split(":")
        module = importlib.import_module(module_name)
        old = base_functions(commit, module_name, names.split(","))
        found += [(module, name, getattr(module, name), old[name]) for name in old]
    return found


def compiled(left, right, params, ndisp: int, chosen: list[tuple], version: str):
    """The graph compiled with the base's or the tree's functions."""
    from _report import whole_pair_graph

    graph, extra = whole_pair_graph(params)
    for module, name, tree, base in chosen:
        setattr(module, name, base if version == "base" else tree)
    try:
        return graph.lower(left, right, params, ndisp=ndisp, **extra).compile()
    finally:
        for module, name, tree, _ in chosen:
            setattr(module, name, tree)


def alternate(executables: dict, arguments: tuple, rounds: int) -> tuple[dict, dict, dict]:
    """Wall and CPU seconds of each executable's calls, run in turn; their last outputs."""
    import jax

    wall = {name: [] for name in executables}
    cpu = {name: [] for name in executables}
    outputs = {}
    for round_ in range(rounds):
        order = list(executables) if round_ % 2 == 0 else list(executables)[::-1]
        for name in order:
            start, start_cpu = time.perf_counter(), time.process_time()
            outputs[name] = jax.block_until_ready(executables[name](*arguments))
            wall[name].append(time.perf_counter() - start)
            cpu[name].append(time.process_time() - start_cpu)
    return wall, cpu, outputs


def run_graph(args) -> int:
    import jax
    from sswjax.api.images import prepare_pair
    from sswjax.data.layouts import find_data_root

    chosen = swaps(args.base, args.swap)
    params = sswjax.preset(args.preset)
    print(f"{args.preset}, {', '.join(args.swap)} at {args.base} (base) against the tree; "
          f"{args.rounds} calls each, ms\n")
    print("| scene | base best | base median | tree best | tree median | CPU base | CPU tree "
          "| same maps |\n|---|---|---|---|---|---|---|---|")
    root = find_data_root(data=args.data)
    for scene in load_scenes(root, scenes=args.scenes):
        left, right = map(jax.device_put, prepare_pair(scene.left, scene.right))
        executables = {version: compiled(left, right, params, scene.ndisp, chosen, version)
                       for version in ("base", "tree")}
        wall, cpu, outputs = alternate(executables, (left, right, params), args.rounds)
        same = all(np.array_equal(a, b) for a, b in zip(
            jax.tree_util.tree_leaves(outputs["base"]), jax.tree_util.tree_leaves(outputs["tree"])))
        ms = {name: (1e3 * min(t), 1e3 * statistics.median(t)) for name, t in wall.items()}
        print(f"| {scene.name} | {ms['base'][0]:.1f} | {ms['base'][1]:.1f} | {ms['tree'][0]:.1f} "
              f"| {ms['tree'][1]:.1f} | {1e3 * statistics.median(cpu['base']):.0f} "
              f"| {1e3 * statistics.median(cpu['tree']):.0f} | {'yes' if same else 'no'} |",
              flush=True)
    return 0


# ---- hashes: every map, bit for bit -------------------------------------------------------

def digest(array) -> str:
    """Hex SHA-256 of an array's dtype, shape and bytes."""
    array = np.ascontiguousarray(array)
    header = f"{array.dtype.str}{array.shape}".encode()
    return hashlib.sha256(header + array.tobytes()).hexdigest()


def hash_preset(preset: str, data: Path, sets) -> list[str]:
    """``<preset> <set> <scene> <what> <sha256>`` lines for one preset, in this process."""
    params = sswjax.preset(preset)
    lines = []
    for name in sets:
        for scene in load_scenes(data / name):
            disparity = sswjax.match(scene.left, scene.right, scene.ndisp, params=params)
            lines.append(f"{preset} {name} {scene.name} disparity {digest(disparity)}")
            if name == "Middlebury2001":
                matched = sswjax.match_with_confidence(scene.left, scene.right, scene.ndisp,
                                                       params=params)
                for what in ("disparity", "confidence", "validity"):
                    lines.append(f"{preset} {name} {scene.name} matched.{what} "
                                 f"{digest(getattr(matched, what))}")
            print(lines[-1], file=sys.stderr, flush=True)
    return lines


def run_hashes(args) -> int:
    if args.one:
        print("\n".join(hash_preset(args.one, args.data, args.sets)))
        return 0
    lines = []
    for preset in args.presets:
        run = subprocess.run([sys.executable, __file__, "hashes", "--one", preset,
                              "--data", str(args.data), "--sets", *args.sets,
                              "-o", str(args.output)],
                             stdout=subprocess.PIPE, text=True, check=True)
        lines += run.stdout.strip().splitlines()
    args.output.write_text("\n".join(lines) + "\n")
    print(f"wrote {len(lines)} hashes to {args.output}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    sub = commands.add_parser("graph", help="a stage change timed on the whole graph")
    sub.add_argument("--base", required=True, help="the commit whose functions are compared")
    sub.add_argument("--swap", action="append", required=True, metavar="MODULE:NAME[,NAME]")
    sub.add_argument("--preset", default="accurate", choices=list(sswjax.PRESETS))
    sub.add_argument("--scenes", nargs="+", default=["Motorcycle", "Teddy"])
    sub.add_argument("--rounds", type=int, default=10)
    sub.add_argument("--data", type=Path)
    sub = commands.add_parser("hashes", help="every preset's maps hashed, to diff two commits")
    sub.add_argument("--data", type=Path, default=Path("../shared/data"),
                     help="folder holding the data sets (default ../shared/data)")
    sub.add_argument("--presets", nargs="+", default=list(PRESETS))
    sub.add_argument("--sets", nargs="+", default=list(SETS))
    sub.add_argument("-o", "--output", type=Path, required=True)
    sub.add_argument("--one", help=argparse.SUPPRESS)  # the child process: one preset
    args = parser.parse_args(argv)
    return {"graph": run_graph, "hashes": run_hashes}[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
