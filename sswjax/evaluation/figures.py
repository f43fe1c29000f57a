"""Comparison figure of evaluated methods (needs matplotlib, extra ``[bench]``).

Conventions: scenes are :class:`sswjax.data.datasets.StereoScene`; results map a method name to its
per-scene :class:`sswjax.evaluation.SceneResult` in the same scene order.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from sswjax.data.datasets import StereoScene
from sswjax.evaluation.runner import SceneResult
from sswjax.data.io import atomic_output, disparity_to_rgb


def error_map(disparity: np.ndarray, ground_truth: np.ndarray, *, threshold: float = 2.0) -> np.ndarray:
    """uint8 (H, W, 3): bad pixels (error > threshold) red, good ones gray, unknown GT black."""
    known = np.isfinite(ground_truth)
    bad = known & ~(np.abs(disparity - np.where(known, ground_truth, 0)) <= threshold)
    out = np.zeros(disparity.shape + (3,), np.uint8)
    out[known] = (150, 150, 150)
    out[bad] = (220, 30, 30)
    return out


def comparison_figure(
    path: str | Path,
    scenes: Sequence[StereoScene],
    results: Mapping[str, Sequence[SceneResult]],
    *,
    threshold: float = 2.0,
    thumb_inches: float = 1.6,
) -> None:
    """Write a PNG grid: per scene, left image, ground truth, each method's disparity and errors."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ValueError("the figure needs matplotlib: pip install 'sswjax[bench]'") from error
    methods = list(results)
    columns = 2 + 2 * len(methods)
    aspect = scenes[0].left.shape[0] / scenes[0].left.shape[1]
    fig, axes = plt.subplots(len(scenes), columns, squeeze=False,
                             figsize=(columns * thumb_inches, len(scenes) * thumb_inches * aspect + 0.4))
    for row, scene in enumerate(scenes):
        gt = scene.ground_truth
        vmax = float(np.nanmax(np.where(np.isfinite(gt), gt, np.nan)))
        panels = [(scene.left, "left"), (disparity_to_rgb(gt, vmin=0, vmax=vmax), "ground truth")]
        for m in methods:
            d = results[m][row].disparity
            bad = results[m][row].metrics["all"][f"bad{float(threshold)}"]
            panels.append((disparity_to_rgb(d, vmin=0, vmax=vmax), m))
            panels.append((error_map(d, gt, threshold=threshold), f"{m} bad {bad:.1f}%"))
        for col, (image, title) in enumerate(panels):
            ax = axes[row, col]
            ax.imshow(image, cmap="gray" if image.ndim == 2 else None)
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 0 or "bad" in title:
                ax.set_title(title, fontsize=6)
        axes[row, 0].set_ylabel(scene.name, fontsize=7)
    fig.tight_layout(pad=0.2)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png", dpi=80)
    plt.close(fig)
