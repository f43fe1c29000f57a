"""Where a preset's error below one pixel sits on MiddEval3 trainingQ: pixel locking, bias, slant.

For each preset (``sswjax.match`` at the pair's exact shape) over the scenes' nonocc pixels
with ground truth:

- **locking**: the fractional part of the estimate, by tenths, among the pixels within 0.5 px of
  the truth, beside the truth's own fractional part on the same pixels (uniform where the
  ground truth is not quantised; ArtL's is, in quarters);
- **bias by fraction**: the mean signed error (estimate - truth) of the pixels whose estimate
  has that fractional part, over those within 1 px, and the share of them beyond 0.5 px;
- **by scene**: bad 0.5, its part between 0.5 and 1.0 px, the median signed error within 2 px,
  and bad 0.5 by the truth's local slope (``|grad d|``, px per px), with each bin's share.

Plain means over the scenes' pixels (not MiddEval3's weights). Prints Markdown and writes it
to ``-o``.

    python benchmarks/sub_pixel.py [--data ../shared/data] [--presets accurate fast]
                                   [-o benchmarks/results/sub_pixel.md]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

import sswjax
from sswjax._files import atomic_output
from sswjax.data.layouts import load_scenes

TENTHS = np.linspace(0, 1, 11)
SLOPES = (0.0, 0.02, 0.05, 0.1, 0.15, 0.3, np.inf)
"""Bin edges of the truth's local slope, px of disparity per px."""


def scene_rows(preset: str, scenes) -> tuple[list[str], np.ndarray, np.ndarray, list]:
    """Per-scene table rows, the two fraction histograms and the errors by the estimate's
    tenth, for one preset."""
    rows, locked, truth = [], np.zeros(10), np.zeros(10)
    by_tenth: list[list[np.ndarray]] = [[] for _ in range(10)]
    for scene in scenes:
        estimate = np.asarray(sswjax.match(scene.left, scene.right, scene.ndisp,
                                           params=sswjax.preset(preset)))
        gt = scene.ground_truth
        ok = np.isfinite(gt) & (gt > 0)
        if scene.mask is not None:
            ok &= scene.mask == 255
        error = (estimate - gt)[ok]
        near = np.abs(error) < 0.5
        locked += np.histogram(_fraction(estimate[ok][near]), TENTHS)[0]
        truth += np.histogram(_fraction(gt[ok][near]), TENTHS)[0]
        tenth = np.minimum((_fraction(estimate[ok]) * 10).astype(int), 9)
        for k in range(10):
            by_tenth[k].append(error[(tenth == k) & (np.abs(error) < 1)])
        grad_y, grad_x = np.gradient(np.where(ok, gt, 0.0))
        slope_bin = np.digitize(np.hypot(grad_x, grad_y)[ok], SLOPES) - 1
        cells = []
        for k in range(len(SLOPES) - 1):
            inside = slope_bin == k
            cells.append(f"{100 * np.mean(np.abs(error[inside]) > 0.5):.1f} "
                         f"({100 * inside.mean():.0f} %)" if inside.any() else "")
        bad = np.abs(error) > 0.5
        rows.append(f"| {preset} | {scene.name} | {100 * bad.mean():.1f} | "
                    f"{100 * (bad & (np.abs(error) <= 1)).mean():.1f} | "
                    f"{np.median(error[np.abs(error) < 2]):+.3f} | " + " | ".join(cells) + " |")
    return rows, locked, truth, by_tenth


def _fraction(values: np.ndarray) -> np.ndarray:
    return values - np.floor(values)


def _percent(counts: np.ndarray) -> str:
    return " | ".join(f"{v:.1f}" for v in 100 * counts / max(counts.sum(), 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(os.environ.get(
        "SSWJAX_DATA", Path(__file__).resolve().parents[2] / "shared" / "data")),
        help="the folder holding MiddEval3/trainingQ (default: SSWJAX_DATA, ../shared/data)")
    parser.add_argument("--presets", nargs="+", default=["accurate", "fast"],
                        choices=list(sswjax.PRESETS))
    parser.add_argument("-o", "--output", type=Path,
                        default=Path("benchmarks/results/sub_pixel.md"))
    args = parser.parse_args()
    scenes = load_scenes(args.data / "MiddEval3" / "trainingQ")
    tenths = " | ".join(f"{t:.1f}" for t in TENTHS[:-1])
    lines = ["Fractional part by tenths (%), nonocc pixels within 0.5 px of the truth", "",
             f"| preset | of | {tenths} |", "|---|---|" + "---|" * 10]
    bias = [f"| preset | | {tenths} |", "|---|---|" + "---|" * 10]
    slopes = " | ".join(f"{a:g}-{b:g}" for a, b in zip(SLOPES[:-1], SLOPES[1:]))
    scenes_table = [f"| preset | scene | bad 0.5 | 0.5-1.0 | median error (within 2 px) | "
                    f"bad 0.5 by slope {slopes} |", "|---|---|---|---|---|" + "---|" * 6]
    for preset in args.presets:
        rows, locked, truth, by_tenth = scene_rows(preset, scenes)
        lines += [f"| {preset} | estimate | {_percent(locked)} |",
                  f"| {preset} | truth | {_percent(truth)} |"]
        errors = [np.concatenate(e) for e in by_tenth]
        bias += [f"| {preset} | mean error, px | " +
                 " | ".join(f"{e.mean():+.3f}" for e in errors) + " |",
                 f"| {preset} | beyond 0.5 px, % | " +
                 " | ".join(f"{100 * np.mean(np.abs(e) > 0.5):.1f}" for e in errors) + " |"]
        scenes_table += rows
    text = "\n".join(lines + ["", "By the estimate's fractional part, nonocc pixels within 1 px",
                              ""] + bias + ["", "By scene, nonocc", ""] + scenes_table) + "\n"
    print(text)
    with atomic_output(args.output) as path:
        Path(path).write_text(text)


if __name__ == "__main__":
    main()
