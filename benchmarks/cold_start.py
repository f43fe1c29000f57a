"""What a first call costs: fresh processes, with an empty and with a warm persistent cache.

For each preset, in new Python processes (nothing shared with this one but the files):

1. ``sswjax match LEFT RIGHT --ndisp N -o OUT.pfm`` from the command line, timed from outside
   (process start to exit), first with an empty compilation cache (a new folder), then again
   with that folder warm (the default: the stored executable read, :mod:`sswjax.runtime.stored`),
   then warm with the trace only (``SSWJAX_STORE_EXECUTABLES=0``: the stored trace lowered and
   the executable found in XLA's cache), and in a fresh folder after ``sswjax warmup --like
   LEFT``.
   Beside them, once per run, the **floor**: a new process that only imports the command line
   (``sswjax.cli.app``, what ``sswjax match`` imports) and brings up JAX's CPU backend (one
   array made), timed from outside. Every CLI call pays it before it reads a pair; a first
   call can be no faster than the floor plus the graph's warm run.
2. The same pair through the API's stored graph (:mod:`sswjax.runtime.stored`), the phases
   timed inside the process: ``import sswjax``, tracing the graph (empty cache) or loading its
   stored executable (warm: then nothing is lowered or compiled, 0 in those columns) or trace
   (trace only), lowering
   it, compiling it (or finding it in XLA's cache), the first run, and a warm run. Python's
   bytecode cache is on in every process (:func:`child_environment`).

Each measurement is repeated ``--repeat`` times in fresh processes and the median reported;
the machine's noise shows in the spread, printed beside it.

    python benchmarks/cold_start.py [--data ../shared/data] [--scene Motorcycle]
                                    [--presets accurate fast] [--repeat 3] [-o benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _report import write_report  # noqa: E402

PHASES = ("import", "read", "trace or load", "lower", "compile", "first run", "warm run")

_CHILD = r"""
import json, sys, time
start = time.perf_counter()
import jax, numpy as np
import sswjax
from sswjax.api.images import prepare_pair
from sswjax.data.io import read_image
from sswjax.graph import ssw_disparity
from sswjax.graph.alignment import ssw_aligned
from sswjax.runtime.compilation import enable_compilation_cache
from sswjax.runtime.stored import StoredGraph, compile_lowered, graph_folder
times = {"import": time.perf_counter() - start}
enable_compilation_cache(path=sys.argv[4])
t = time.perf_counter()
left, right = prepare_pair(read_image(sys.argv[1]), read_image(sys.argv[2]))
left, right = jax.device_put(left), jax.device_put(right)
params, ndisp = sswjax.preset(sys.argv[5]), int(sys.argv[3])
times["read"] = time.perf_counter() - t
t = time.perf_counter()
# what sswjax.match runs on a pair whole: with the alignment, it and the method in one program
jitted, extra = ((ssw_disparity, {}) if params.alignment is None
                 else (ssw_aligned, {"method": "ssw_disparity"}))
call = {"ndisp": ndisp, **extra}
graph = StoredGraph(jitted.__wrapped__, (left, right, params), call,
                    static=("method", "ndisp", "chunk", "options"), folder=graph_folder())
times["trace or load"] = time.perf_counter() - t
if graph.executable_loaded:  # its stored executable: nothing to lower or compile
    times["lower"] = times["compile"] = 0.0
    compiled = graph.compiled(left, right, params, **call)
else:
    t = time.perf_counter()
    lowered = graph.lower(left, right, params, **call)
    times["lower"] = time.perf_counter() - t
    t = time.perf_counter()
    compiled, fresh = compile_lowered(lowered)
    times["compile"] = time.perf_counter() - t
    graph.keep(compiled, fresh=fresh)
leaves = graph.flat(left, right, params, **call)
t = time.perf_counter()
np.asarray(compiled(*leaves))
times["first run"] = time.perf_counter() - t
t = time.perf_counter()
np.asarray(compiled(*leaves))
times["warm run"] = time.perf_counter() - t
print(json.dumps(times))
"""


def child_environment(cache: Path, executables: bool = True) -> dict[str, str]:
    """The environment of a measured process: ``cache`` as its compilation cache, compiled
    executables stored and read if ``executables``, and Python's bytecode cache on, as a user's
    Python has it (without ``PYTHONDONTWRITEBYTECODE``, which some sandboxes set: then every
    module of the package is compiled from source at every start, about 0.2 s more here)."""
    env = {**os.environ, "SSWJAX_CACHE_DIR": str(cache),
           "SSWJAX_STORE_EXECUTABLES": "1" if executables else "0"}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


_FLOOR = ("import sswjax.cli.app, jax.numpy as jnp; "
          "jnp.zeros(1).block_until_ready()")


def floor_seconds(cache: Path) -> float:
    """Wall time of a new process that imports the command line and brings up JAX's CPU
    backend, nothing else: what every ``sswjax`` call costs before its work."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", _FLOOR], env=child_environment(cache), check=True,
                   capture_output=True)
    return time.perf_counter() - start


def warmup_seconds(left: Path, ndisp: int, preset: str, cache: Path) -> float:
    """Wall time of ``sswjax warmup --like LEFT`` in a new process, with ``cache``."""
    env = child_environment(cache)
    command = [sys.executable, "-m", "sswjax.cli", "warmup", "--like", str(left),
               "--ndisp", str(ndisp), "--preset", preset]
    start = time.perf_counter()
    subprocess.run(command, env=env, check=True, capture_output=True)
    return time.perf_counter() - start


def cli_seconds(left: Path, right: Path, ndisp: int, preset: str, cache: Path,
                executables: bool = True) -> float:
    """Wall time of one ``sswjax match`` in a new process, with ``cache`` as its XLA cache."""
    with tempfile.TemporaryDirectory() as out:
        env = child_environment(cache, executables)
        command = [sys.executable, "-m", "sswjax.cli", "match", str(left), str(right),
                   "--ndisp", str(ndisp), "--preset", preset, "-o", f"{out}/d.pfm"]
        start = time.perf_counter()
        subprocess.run(command, env=env, check=True, capture_output=True)
        return time.perf_counter() - start


def api_phases(left: Path, right: Path, ndisp: int, preset: str, cache: Path,
               executables: bool = True) -> dict:
    """The phases of a first API call in a new process (seconds per phase, and the total)."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", _CHILD, str(left), str(right), str(ndisp),
                           str(cache), preset], env=child_environment(cache, executables),
                          check=True,
                          capture_output=True, text=True)
    phases = json.loads(done.stdout.strip().splitlines()[-1])
    phases["process"] = time.perf_counter() - start
    return phases


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def measure(left: Path, right: Path, ndisp: int, preset: str, repeat: int) -> list[dict]:
    """Rows of the report for one preset, CLI then API: an empty cache; the same cache warm
    (the default: the stored executable read); warm with the trace only
    (``SSWJAX_STORE_EXECUTABLES=0``: the stored trace lowered, XLA's cache gives the
    executable), measured right after; and for the CLI a fresh cache after ``sswjax warmup``."""
    rows = []
    for surface, once in (("CLI", cli_seconds), ("API", api_phases)):
        runs = {"empty": [], "warm": [], "warm, trace only": []}
        if surface == "CLI":
            runs["after warmup"] = []
        for _ in range(repeat):
            with tempfile.TemporaryDirectory() as cache:
                runs["empty"].append(once(left, right, ndisp, preset, Path(cache)))
                runs["warm"].append(once(left, right, ndisp, preset, Path(cache)))
                runs["warm, trace only"].append(
                    once(left, right, ndisp, preset, Path(cache), False))
            if surface == "CLI":
                with tempfile.TemporaryDirectory() as cache:  # filled by sswjax warmup --like
                    warmup_seconds(left, ndisp, preset, Path(cache))
                    runs["after warmup"].append(once(left, right, ndisp, preset, Path(cache)))
        for state, measured in runs.items():
            row = {"preset": preset, "surface": surface, "cache": state}
            if surface == "CLI":
                row["total"] = spread(measured)
            else:
                row.update({phase: spread([r[phase] for r in measured]) for phase in PHASES})
                row["total"] = spread([r["process"] for r in measured])
            rows.append(row)
            print(row, flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(os.environ.get(
        "SSWJAX_DATA", Path(__file__).resolve().parents[2] / "shared" / "data")))
    parser.add_argument("--scene", default="Motorcycle")
    parser.add_argument("--presets", nargs="+", default=["accurate", "fast"])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("-o", "--output", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args()
    folder = args.data / "MiddEval3" / "trainingQ" / args.scene
    calib = dict(line.strip().split("=", 1) for line in open(folder / "calib.txt") if "=" in line)
    left, right, ndisp = folder / "im0.png", folder / "im1.png", int(calib["ndisp"])
    with tempfile.TemporaryDirectory() as cache:  # the bytecode cache written before timing
        subprocess.run([sys.executable, "-c", "import sswjax.cli.match, sswjax.cli.warmup"],
                       env=child_environment(Path(cache)), check=True)
    with tempfile.TemporaryDirectory() as cache:
        floor = [floor_seconds(Path(cache)) for _ in range(args.repeat)]
    rows = [{"preset": "any", "surface": "CLI", "cache": "floor: import and backend only",
             "total": spread(floor)}]
    print(rows[0], flush=True)
    rows += [row for preset in args.presets
             for row in measure(left, right, ndisp, preset, args.repeat)]
    keys = ["preset", "surface", "cache", *PHASES, "total"]
    header = "| " + " | ".join(keys) + " |\n|" + "---|" * len(keys) + "\n"
    table = (f"First call on trainingQ {args.scene} ({ndisp} disparities), fresh processes, "
             f"seconds, median (min-max) of {args.repeat}; warm (the default): the graph's "
             "stored executable read, nothing lowered or compiled; warm, trace only "
             "(SSWJAX_STORE_EXECUTABLES=0): the graph's stored trace lowered, XLA's cache "
             "gives the executable, run right after\n\n" + header
             + "\n".join("| " + " | ".join(str(row.get(k, "")) for k in keys) + " |"
                         for row in rows))
    write_report(args.output, "cold_start", table, rows, keys)


if __name__ == "__main__":
    main()
