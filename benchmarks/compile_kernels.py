"""What XLA's compile of a graph is made of: the LLVM modules XLA CPU builds, one per kernel.

For each configuration (``NAME=BASE:JSON`` as for ``benchmarks/ablation.py``, or a preset's
name), a new Python process lowers and compiles ``ssw_disparity`` on one trainingQ pair with
XLA's compilation cache off and its verbose log on (``TF_CPP_MAX_VLOG_LEVEL=1``), and this
script reads from that log every "Compiled LLVM module: NAME time: T" line and XLA's own total
("Compiling [jit_ssw_disparity] for CPU ... time: T"). Reported per configuration: the compile's
wall time as XLA counts it and as the process measured it (``lower().compile()``; the verbose
log makes both slower than a quiet compile, by about a tenth), the number of kernels, the sum
of their LLVM times (XLA builds them on several threads, so the sum exceeds the wall time),
the largest kernel's time and the share of the kernels under 10 ms. It says whether a compile
is long because of a few large kernels or because of many small ones, which is what decides
whether making a stage's code smaller can shorten it.

    python benchmarks/compile_kernels.py [--config accurate] [--config fast]
        [--config 'unaligned=accurate:{"alignment": null}'] [--scene Motorcycle]
        [--data ../shared/data] [-o benchmarks/results/compile_kernels]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

from _report import write_report  # benchmarks/, on the path when run as a script

_CHILD = r"""
import json, sys, time
import jax
import sswjax
from sswjax.api.images import prepare_pair
from sswjax.data.layouts import load_scenes
from sswjax.graph import ssw_disparity
sys.path.insert(0, sys.argv[4])
from ablation import parse_config
_, params = parse_config(sys.argv[3])
scene = load_scenes(sys.argv[1], scenes=[sys.argv[2]])[0]
left, right = map(jax.device_put, prepare_pair(scene.left, scene.right))
lowered = ssw_disparity.lower(left, right, params, ndisp=scene.ndisp)
start = time.perf_counter()
lowered.compile()
print("COMPILE_SECONDS", json.dumps(time.perf_counter() - start), flush=True)
"""

_KERNEL = re.compile(r"Compiled LLVM module: (\S+) time: ([0-9.]+) (us|ms|s) ")
_TOTAL = re.compile(r"Compiling \[jit_ssw_disparity\] for CPU using JIT time: ([0-9.]+) (us|ms|s) ")
_UNIT = {"us": 1e-6, "ms": 1e-3, "s": 1.0}


def kernel_times(log: str) -> tuple[list[float], float | None]:
    """Seconds of each LLVM module compiled, and XLA's total, from a verbose XLA CPU log."""
    kernels = [float(t) * _UNIT[unit] for _, t, unit in _KERNEL.findall(log)]
    total = _TOTAL.search(log)
    return kernels, None if total is None else float(total.group(1)) * _UNIT[total.group(2)]


def profile(config: str, data: Path, scene: str) -> dict:
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", action="append", default=[],
                        help="NAME=BASE:JSON or a preset's name; repeatable (accurate, fast)")
    parser.add_argument("--scene", default="Motorcycle", help="the trainingQ pair compiled for")
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data")
    parser.add_argument("-o", "--output", type=Path,
                        default=Path("benchmarks/results/compile_kernels"))
    args = parser.parse_args(argv)
    rows = [profile(config, args.data, args.scene)
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


if __name__ == "__main__":
    sys.exit(main())
