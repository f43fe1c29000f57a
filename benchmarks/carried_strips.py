"""The price of carrying the semi-global paths across row strips: warm seconds of `accurate` on
KITTI 2012 pairs, whole, in strips with their paths restarted, and in strips with their paths
carried (``sswjax.runtime.carried``), each pair's three runs in turn, best of ``--repeat``.

    python benchmarks/carried_strips.py [--data ../shared/data] [--pairs 000100 000101 000102]
                                        [--rows 64] [--ndisp 128] [--repeat 3] [-o benchmarks/results]

Writes ``carried_strips.{md,csv}``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import sswjax
from sswjax.data.io import read_image

sys.path.insert(0, str(Path(__file__).parent))
from _report import write_report  # noqa: E402

KEYS = ("pair", "rows", "whole", "restarted", "carried", "differ_restarted", "differ_carried")


def measure(left, right, ndisp: int, rows: int, repeat: int) -> dict:
    """Best warm seconds of the three runs (each compiled first), and the % of pixels whose
    disparity differs from the whole image's."""
    plans = {"whole": sswjax.ExecutionPlan(),
             "restarted": sswjax.ExecutionPlan(strip_rows=rows, carry_paths=False),
             "carried": sswjax.ExecutionPlan(strip_rows=rows)}
    maps = {name: sswjax.match(left, right, ndisp, plan=plan, check_memory=False)
            for name, plan in plans.items()}
    best = dict.fromkeys(plans, float("inf"))
    for _ in range(repeat):
        for name, plan in plans.items():
            start = time.perf_counter()
            sswjax.match(left, right, ndisp, plan=plan, check_memory=False)
            best[name] = min(best[name], time.perf_counter() - start)
    return {**best, **{f"differ_{name}": 100 * float(np.mean(maps[name] != maps["whole"]))
                       for name in ("restarted", "carried")}}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--pairs", nargs="+", default=["000100", "000101", "000102"])
    parser.add_argument("--rows", type=int, default=64)
    parser.add_argument("--ndisp", type=int, default=128)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("-o", "--output", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args(argv)
    folder = args.data / "KITTI2012" / "training"
    rows = []
    for pair in args.pairs:
        left = read_image(folder / "image_0" / f"{pair}_10.png")
        right = read_image(folder / "image_1" / f"{pair}_10.png")
        rows.append({"pair": pair, "rows": args.rows,
                     **measure(left, right, args.ndisp, args.rows, args.repeat)})
        print(rows[-1], file=sys.stderr, flush=True)
    lines = [f"# Carried paths in strips of {args.rows} rows (`accurate`, KITTI 2012, ndisp "
             f"{args.ndisp}, warm, best of {args.repeat}, the three runs in turn)", "",
             "| pair | whole s | restarted s | carried s | carried / restarted | differ % "
             "restarted | differ % carried |", "|---|---:|---:|---:|---:|---:|---:|"]
    lines += [f"| {r['pair']} | {r['whole']:.2f} | {r['restarted']:.2f} | {r['carried']:.2f} | "
              f"{r['carried'] / r['restarted']:.2f} | {r['differ_restarted']:.3f} | "
              f"{r['differ_carried']:.3f} |" for r in rows]
    write_report(args.output, "carried_strips", "\n".join(lines), rows, KEYS)
    return 0


if __name__ == "__main__":
    sys.exit(main())
