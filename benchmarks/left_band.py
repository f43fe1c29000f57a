"""Errors in the left band: where a pixel's match leaves the right image, and the columns near it.

The left ``ndisp`` columns of a pair are hard for every matcher: a pixel at column ``x`` can only
match disparities ``<= x``, and where its true disparity exceeds ``x`` it has no match at all.
For each method this splits the pixels with ground truth of every scene into three zones and
reports bad 2.0 in each, pooled over the scenes' pixels (not weighted):

* ``no match``: ``x - d_true < 0``, the match lies left of the right image;
* ``band``: the other pixels with ``x < ndisp`` (a match exists, but the search is cut short);
* ``rest``: ``x >= ndisp``.

    python benchmarks/left_band.py [--data DIR] [--sets trainingQ KITTI2012] [--methods paper fast accurate sgbm]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import sswjax
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.methods import PEERS

from _report import write_report  # benchmarks/, on the path when run as a script
from ablation import SETS

ZONES = ("no match", "band", "rest")


def zones(ground_truth: np.ndarray, ndisp: int) -> dict[str, np.ndarray]:
    """Boolean (H, W) masks of the three zones among the pixels with finite ground truth."""
    known = np.isfinite(ground_truth)
    columns = np.arange(ground_truth.shape[1])[None, :]
    no_match = known & (columns - np.where(known, ground_truth, 0) < 0)
    band = known & ~no_match & (columns < ndisp)
    return {"no match": no_match, "band": band, "rest": known & (columns >= ndisp)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data", help="folder holding the data sets")
    parser.add_argument("--sets", nargs="+", default=["trainingQ", "KITTI2012"], choices=list(SETS))
    parser.add_argument("--methods", nargs="+", default=["paper", "fast", "accurate", "sgbm"],
                        choices=[*sswjax.PRESETS, *PEERS])
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args(argv)
    buckets = sswjax.ShapeBuckets(size_step=64, ndisp_step=32)
    rows = []
    for set_name in args.sets:
        scenes = load_scenes(args.data / SETS[set_name][0])
        counts = {m: {z: [0, 0] for z in ZONES} for m in args.methods}  # [bad, known]
        for scene in scenes:
            masks = zones(scene.ground_truth, scene.ndisp)
            for method in args.methods:
                if method in sswjax.PRESETS:
                    disparity = sswjax.match(scene.left, scene.right, scene.ndisp,
                                             params=sswjax.preset(method), buckets=buckets)
                else:
                    disparity = PEERS[method].fn(scene.left, scene.right, scene.ndisp)
                bad = np.abs(disparity - scene.ground_truth) > 2.0
                for zone, mask in masks.items():
                    counts[method][zone][0] += int((bad & mask).sum())
                    counts[method][zone][1] += int(mask.sum())
            print(f"  {set_name} {scene.name}", file=sys.stderr, flush=True)
        for method in args.methods:
            row = {"set": set_name, "method": method}
            for zone in ZONES:
                bad, known = counts[method][zone]
                row[f"{zone} share %"] = 100.0 * known / max(sum(k for _, k in counts[method].values()), 1)
                row[f"{zone} bad2.0 %"] = 100.0 * bad / max(known, 1)
            rows.append(row)
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(f"{r[k]:.2f}" if isinstance(r[k], float) else r[k] for k in keys)
              + " |" for r in rows]
    write_report(args.output, "left_band", "\n".join(lines), rows, keys)
    return 0


if __name__ == "__main__":
    sys.exit(main())
