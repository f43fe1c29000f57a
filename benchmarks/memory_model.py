"""Measure the peak memory of ``sswjax.match`` on many sizes and fit the memory guard's model.

Each configuration (size, disparities, preset, parameter changes) runs in a fresh process that
reads a MiddEval3 trainingQ pair (Motorcycle, tiled or cropped to the size, uint8 RGB as
``sswjax match`` reads it) and matches it; its peak RSS (``ru_maxrss``) is recorded. The fit
is non-negative least squares of the peaks on the terms of
:func:`sswjax.runtime.memory.memory_terms`, weighted by 1 / peak (relative errors); the
coefficients, with the margin that puts every estimate above its measurement, are printed for
``sswjax/runtime/memory.py``. A configuration's changes are old flat parameter names or
execution-plan fields (``strip_rows``, ``disparity_chunk``). Results go to
``benchmarks/results/memory_model.{md,csv}``; ``--measured CSV`` refits earlier measurements.

    python benchmarks/memory_model.py [--only-fit --measured benchmarks/results/memory_model.csv]
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

import sswjax
from sswjax.runtime import memory
from sswjax.runtime.memory import COEFFICIENTS, memory_terms
from sswjax.runtime.plan import split_settings

sys.path.insert(0, str(Path(__file__).parent))
from _report import write_report  # noqa: E402

CHILD = r"""
import json, resource, sys
import numpy as np
import sswjax
from sswjax.data.io import read_image
from sswjax.data.layouts import find_data_root
from sswjax.runtime.plan import split_settings

height, width, ndisp, preset, changes = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], json.loads(sys.argv[5])
scene = find_data_root() / "trainingQ" / "Motorcycle"
left, right = (read_image(scene / name) for name in ("im0.png", "im1.png"))
left, right = (np.resize(im, (height, width, 3)) if im.shape[:2] != (height, width) else im for im in (left, right))
params, plan = split_settings(sswjax.preset(preset), changes)
sswjax.match(left, right, ndisp, params=params, plan=plan)
print(json.dumps({"peak": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}))
"""

# (height, width, ndisp, preset, parameter changes): Motorcycle Q, Vintage Q's size, the H and
# full-resolution sizes, tiny sizes (the constant), chunks, strips, the int16 storage, 8 paths,
# no SLIC, the band, the window of a tile of 1024 with 256 disparities (1216 x 1728), and fast
# (coarse-to-fine: its full-resolution stages are the window term).
CONFIGS = [
    (64, 96, 16, "paper", {}),
    (64, 96, 16, "accurate", {}),
    (497, 741, 70, "paper", {}),
    (480, 722, 190, "paper", {}),
    (497, 741, 70, "paper", {"disparity_chunk": 16}),
    (497, 741, 70, "paper", {"disparity_chunk": 0}),
    (497, 741, 70, "paper", {"n_segments": 0}),
    (994, 1482, 140, "paper", {}),
    (994, 1482, 140, "paper", {"strip_rows": 128}),
    (497, 741, 70, "accurate", {}),
    (480, 722, 190, "accurate", {}),
    (497, 741, 140, "accurate", {}),
    (497, 741, 70, "accurate", {"sgm_dtype": "int16"}),
    (480, 722, 190, "accurate", {"sgm_dtype": "int16"}),
    (994, 1482, 140, "accurate", {"sgm_dtype": "int16"}),
    (497, 741, 70, "accurate", {"sgm_paths": 8}),
    (497, 741, 70, "accurate", {"disparity_chunk": 0}),
    (480, 722, 190, "accurate", {"strip_rows": 160}),
    (994, 1482, 140, "accurate", {"strip_rows": 64}),
    (994, 1482, 140, "accurate", {}),
    (1988, 2964, 280, "paper", {}),
    (1988, 2964, 280, "accurate", {"strip_rows": 64}),
    (497, 741, 70, "balanced", {}),
    (480, 722, 190, "balanced", {}),
    (994, 1482, 140, "balanced", {}),
    (1216, 1728, 256, "accurate", {}),
    (994, 1482, 280, "accurate", {}),
    (64, 96, 16, "fast", {}),
    (497, 741, 70, "fast", {}),
    (480, 722, 190, "fast", {}),
    (994, 1482, 140, "fast", {}),
    (1216, 1728, 256, "fast", {}),
    (1988, 2964, 280, "fast", {}),
]

TINY = 10_000  # pixels: pairs this small measure the compile floor, not the terms
KEYS = ("height", "width", "ndisp", "preset", "changes", "peak")


def measure(height, width, ndisp, preset, changes) -> int:
    """Peak RSS in bytes of a fresh process matching one pair of this size."""
    run = subprocess.run([sys.executable, "-c", CHILD, str(height), str(width), str(ndisp), preset,
                          json.dumps(changes)], capture_output=True, text=True, check=True)
    return int(json.loads(run.stdout.strip().splitlines()[-1])["peak"])


def fit(rows):
    """Non-negative least squares of the peaks on the model's terms, relative errors."""
    from scipy.optimize import nnls

    names = list(COEFFICIENTS)
    design, peaks = [], []
    for row in rows:
        if row["height"] * row["width"] < TINY:
            continue
        params, plan = split_settings(sswjax.preset(row["preset"]), row["changes"])
        terms = memory_terms(row["height"], row["width"], row["ndisp"], params=params, plan=plan)
        design.append([terms[n] for n in names])
        peaks.append(row["peak"])
    design, peaks = np.array(design), np.array(peaks, float)
    coefficients, _ = nnls(design / peaks[:, None], np.ones(len(peaks)))
    return dict(zip(names, coefficients))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--measured", type=Path, help="CSV of earlier measurements to refit")
    parser.add_argument("--only-fit", action="store_true", help="no new measurement")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    rows = []
    if args.measured is not None:
        with open(args.measured) as handle:
            for row in csv.DictReader(handle):
                rows.append({"height": int(row["height"]), "width": int(row["width"]),
                             "ndisp": int(row["ndisp"]), "preset": row["preset"],
                             "changes": json.loads(row["changes"]), "peak": int(row["peak"])})
    if not args.only_fit:
        for height, width, ndisp, preset, changes in CONFIGS:
            try:
                peak = measure(height, width, ndisp, preset, changes)
            except subprocess.CalledProcessError as error:
                print(f"{width} x {height} x {ndisp} {preset} {changes}: failed: "
                      f"{(error.stderr.strip().splitlines() or ['?'])[-1]}", flush=True)
                continue
            print(f"{width} x {height} x {ndisp} {preset} {changes}: {peak / 1e9:.2f} GB", flush=True)
            rows.append({"height": height, "width": width, "ndisp": ndisp, "preset": preset,
                         "changes": changes, "peak": peak})
    memory.COEFFICIENTS.update(fit(rows))
    floor = {"none": 0.0, "sgm": 0.0}
    for row in rows:
        if row["height"] * row["width"] < TINY:
            key = "none" if sswjax.preset(row["preset"]).optimizer is None else "sgm"
            floor[key] = max(floor[key], row["peak"])
    memory.COMPILE_FLOOR.update(floor)
    memory.MARGIN, memory.SLACK = 1.0, 0
    fitted = np.array([memory.estimate_peak_bytes(
        r["height"], r["width"], r["ndisp"],
        **dict(zip(("params", "plan"), split_settings(sswjax.preset(r["preset"]), r["changes"]))))
        for r in rows], float)
    ratios = np.array([row["peak"] for row in rows]) / fitted
    print("COEFFICIENTS =", {k: float(f"{v:.4g}") for k, v in memory.COEFFICIENTS.items()})
    print("COMPILE_FLOOR =", floor)
    print(f"measured / fitted: {ratios.min():.3f} .. {ratios.max():.3f} (MARGIN >= the largest)")
    table = ["| W x H x D | preset | changes | measured GB | fitted GB |", "|---|---|---|---|---|"]
    table += [f"| {r['width']} x {r['height']} x {r['ndisp']} | {r['preset']} | "
              f"{json.dumps(r['changes'])} | {r['peak'] / 1e9:.2f} | {f / 1e9:.2f} |"
              for r, f in zip(rows, fitted)]
    write_report(args.output, "memory_model", "\n".join(table),
                 [{**r, "changes": json.dumps(r["changes"])} for r in rows], KEYS)


if __name__ == "__main__":
    main()
