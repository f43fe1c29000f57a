"""A stage change measured on the whole graph, old and new alternating in one process.

On this host two runs minutes apart can differ by more than a stage change saves (the whole
machine is at times twice as slow), and a profile's operation times overstate what a change
saves in wall time: XLA CPU runs an operation's partitions on both threads, and several
operations can overlap. Here the graph is compiled twice in one process: once with named
functions of the package taken from the commit ``--base`` (their module's source at that
commit, run as a module of its own beside the package, so that its imports are the tree's),
once as the tree has them. The two executables then run in turn, the first alternating, on
the same pair, and each call's wall and CPU time is kept. The maps of the two are compared
bit for bit.

    python benchmarks/graph_ab.py --base 6eca509 --swap sswjax.stages.sgm:path_penalties
                                  [--swap MODULE:NAME[,NAME]] [--preset accurate]
                                  [--scenes Motorcycle Teddy] [--rounds 10] [--data DIR]

A function that the graph's modules imported by name (``from m import f``) is looked up in
the importing module: swap it there (``--swap sswjax.graph.volume:fold_volume``).
"""

from __future__ import annotations

import argparse
import importlib
import statistics
import subprocess
import time
import types
from pathlib import Path

import jax
import numpy as np

import sswjax
from sswjax.api.images import prepare_pair
from sswjax.data.layouts import find_data_root, load_scenes
from sswjax.graph import ssw_disparity

REPO = Path(__file__).resolve().parents[1]


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
    for module, name, tree, base in chosen:
        setattr(module, name, base if version == "base" else tree)
    try:
        return ssw_disparity.lower(left, right, params, ndisp=ndisp).compile()
    finally:
        for module, name, tree, _ in chosen:
            setattr(module, name, tree)


def alternate(executables: dict, arguments: tuple, rounds: int) -> tuple[dict, dict, dict]:
    """Wall and CPU seconds of each executable's calls, run in turn; their last outputs."""
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the commit whose functions are compared")
    parser.add_argument("--swap", action="append", required=True, metavar="MODULE:NAME[,NAME]")
    parser.add_argument("--preset", default="accurate", choices=list(sswjax.PRESETS))
    parser.add_argument("--scenes", nargs="+", default=["Motorcycle", "Teddy"])
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--data", type=Path)
    args = parser.parse_args()
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


if __name__ == "__main__":
    main()
