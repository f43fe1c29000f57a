"""Running a stereo method over MiddEval3 scenes and summarising it with the official weights.

Conventions: a *method* is a callable ``(left, right, ndisp) -> float32 (H, W)`` disparity
(NumPy in, NumPy out, images as read from disk); metrics are those of :mod:`sswjax.metrics`
(percentages for bad-t and invalid, pixels for avgerr/rms/a90).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from typing import NamedTuple

import numpy as np

from sswjax.datasets import StereoScene
from sswjax.metrics import evaluate_disparity, weighted_average

THRESHOLDS = (0.5, 1.0, 2.0)
REGIONS = ("nonocc", "all")

Method = Callable[[np.ndarray, np.ndarray, int], np.ndarray]


class SceneResult(NamedTuple):
    """One method on one scene: its disparity, metrics per region and wall time (seconds)."""

    scene: str
    disparity: np.ndarray
    metrics: dict[str, dict[str, float]]
    seconds: float


def evaluate_scene(method: Method, scene: StereoScene) -> SceneResult:
    """Run ``method`` on one scene with ground truth and compute its metrics."""
    if scene.ground_truth is None:
        raise ValueError(f"scene {scene.name} has no ground truth (disp0GT.pfm)")
    start = time.perf_counter()
    disparity = np.asarray(method(scene.left, scene.right, scene.ndisp), dtype=np.float32)
    seconds = time.perf_counter() - start
    metrics = evaluate_disparity(
        disparity, scene.ground_truth, mask=scene.mask, ndisp=scene.ndisp, thresholds=THRESHOLDS
    )
    return SceneResult(scene.name, disparity, metrics, seconds)


def evaluate_scenes(
    method: Method, scenes: Iterable[StereoScene], *, progress: bool = False
) -> list[SceneResult]:
    """Evaluate ``method`` on every scene (with a tqdm progress bar when ``progress``)."""
    scenes = list(scenes)
    if progress:
        from tqdm import tqdm

        scenes = tqdm(scenes, desc="scenes", unit="scene")
    return [evaluate_scene(method, scene) for scene in scenes]


def summary(results: Sequence[SceneResult]) -> dict[str, dict[str, float]]:
    """Weighted MiddEval3 averages: ``{region: {"bad2.0": %, "bad1.0": %, "bad0.5": %}}``."""
    out: dict[str, dict[str, float]] = {}
    for region in REGIONS:
        if not all(region in r.metrics for r in results):
            continue
        out[region] = {
            f"bad{t}": weighted_average({r.scene: r.metrics[region][f"bad{t}"] for r in results})
            for t in sorted(THRESHOLDS, reverse=True)
        }
    return out


def markdown_table(results: Sequence[SceneResult]) -> str:
    """Per-scene bad 2.0 / 1.0 / 0.5 (nonocc and all) with the weighted average as last row."""
    columns = [(region, f"bad{t}") for t in sorted(THRESHOLDS, reverse=True) for region in REGIONS]
    header = "| scene | " + " | ".join(f"{k} {reg}" for reg, k in columns) + " | time s |"
    rule = "|---" * (len(columns) + 2) + "|"
    lines = [header, rule]
    for r in results:
        cells = [f"{r.metrics[reg][k]:.2f}" for reg, k in columns]
        lines.append(f"| {r.scene} | " + " | ".join(cells) + f" | {r.seconds:.2f} |")
    averages = summary(results)
    cells = [f"**{averages[reg][k]:.2f}**" for reg, k in columns]
    median_time = float(np.median([r.seconds for r in results]))
    lines.append("| **weighted average** | " + " | ".join(cells) + f" | {median_time:.2f} (median) |")
    return "\n".join(lines)
