"""Running a stereo method over scenes and summarising it: MiddEval3 with the official weights,
the other layouts (:mod:`sswjax.data.layouts`) with plain means over scenes.

Conventions: a *method* is a callable ``(left, right, ndisp) -> float32 (H, W)`` disparity
(NumPy in, NumPy out, images as read from disk); a :class:`BatchedMethod` can also run many
scenes together (e.g. grouped by shape and sharded over devices), and its per-scene time is
then its share of a step (see :meth:`BatchedMethod.match_many`). Metrics are those of
:mod:`sswjax.evaluation.metrics` (percentages for bad-t, D1 and invalid, pixels for
avgerr/rms/a90); which ones, and how they are averaged, is a :class:`Scoring` (:data:`SCORINGS`,
by the ``scoring`` of a data layout). Every function defaults to MiddEval3's. A scene without
a known ground-truth pixel cannot be scored (:func:`evaluate_scene` refuses it), and no average
takes a ``nan``: over the scenes given, MiddEval3's weights are renormalised.
"""

from __future__ import annotations

import csv
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np
from tqdm import tqdm

from sswjax._files import atomic_output
from sswjax.data.layouts import StereoScene
from sswjax.evaluation.metrics import (
    MIDDEVAL3_TRAINING_WEIGHTS,
    evaluate_disparity,
    scene_mean,
    weighted_average,
)

THRESHOLDS = (0.5, 1.0, 2.0)
REGIONS = ("nonocc", "all")


class Scoring(NamedTuple):
    """Which metrics a data layout reports and how its summary averages them over scenes.

    Attributes
    ----------
    average : str
        ``"weighted"`` (by ``weights``) or ``"mean"`` (every scene alike), as tables say it.
    thresholds : tuple of float
        bad-t thresholds in pixels, in table order.
    d1 : bool
        Whether KITTI's D1 is reported too (after the bad-t columns).
    weights : Mapping[str, float] or None
        Scene weights of a ``"weighted"`` average.
    """

    average: str
    thresholds: tuple[float, ...]
    d1: bool = False
    weights: Mapping[str, float] | None = None

    @property
    def keys(self) -> list[str]:
        """Metric keys of the tables, in order: ``["bad2.0", ..., "D1"]``."""
        return [f"bad{float(t)}" for t in self.thresholds] + (["D1"] if self.d1 else [])


#: Scoring of each ``Layout.scoring`` of :mod:`sswjax.data.layouts`: MiddEval3 bad 2.0/1.0/0.5
#: with the official weights; the others bad 2.0/1.0/0.5 and 3.0 (KITTI's threshold), means
#: over scenes, and for KITTI also D1.
SCORINGS: dict[str, Scoring] = {
    "middeval3": Scoring("weighted", (2.0, 1.0, 0.5), weights=MIDDEVAL3_TRAINING_WEIGHTS),
    "kitti": Scoring("mean", (2.0, 1.0, 0.5, 3.0), d1=True),
    "mean": Scoring("mean", (2.0, 1.0, 0.5, 3.0)),
}
MIDDEVAL3_SCORING = SCORINGS["middeval3"]

_PAPER_SCENES = ("Adirondack", "ArtL", "Jadeplant", "Motorcycle", "MotorcycleE", "Piano", "PianoL",
                 "Pipes", "Playroom", "Playtable", "PlaytableP", "Recycle", "Shelves", "Teddy",
                 "Vintage")
_PAPER_ROWS = {  # Table 1 of the SSW paper: (all, nonocc) bad-pixel % per scene, in scene order
    "bf": ((26.9, 23), (31.8, 16.7), (80.6, 61.7), (23.4, 16.6), (22.1, 15.2), (24, 19.7),
           (36.6, 33.3), (32.8, 20.5), (40.8, 25.9), (36.8, 31.3), (25.8, 19.7), (22.7, 19.3),
           (26.4, 24.4), (21.8, 13.7), (73.7, 70.2)),
    "gf": ((23.8, 19.6), (29.6, 13.8), (75.5, 55.1), (20.3, 13.3), (19.4, 12.3), (21.7, 17.3),
           (34.3, 30.9), (30.2, 17.6), (37.8, 22.5), (34.8, 29), (23.3, 17.1), (20.2, 16.7),
           (24.8, 22.6), (19.3, 10.9), (68.5, 64.5)),
    "mf": ((17.6, 13.3), (29.4, 11), (65.2, 42.7), (17.6, 9.82), (17.6, 9.79), (17.1, 11.4),
           (30, 25.4), (26.7, 12.9), (36.3, 17.6), (27.6, 20.6), (19.5, 11.4), (14.5, 11.3),
           (18.6, 15.8), (17.2, 7.22), (51.2, 43.1)),
    "ssw": ((14.2, 9.7), (23.6, 8.71), (54.8, 34.5), (13.6, 6.6), (13.1, 6.08), (16.3, 11.9),
            (25.9, 22.3), (22.6, 9.97), (29.6, 14), (25.3, 19.2), (15.6, 9.23), (12.8, 8.93),
            (17.1, 14.7), (14.6, 5.95), (44.3, 39.2)),
}
_PAPER_ROWS["igf"] = _PAPER_ROWS["gf"]  # the paper prints identical GF and iGF columns

PAPER_TABLE1: dict[str, dict[str, dict[str, float]]] = {
    method: {scene: {"all": a, "nonocc": n} for scene, (a, n) in zip(_PAPER_SCENES, rows)}
    for method, rows in _PAPER_ROWS.items()
}
"""The paper's Table 1, ``{method: {scene: {"all": %, "nonocc": %}}}``; its threshold and
resolution are not stated (we compare it with our bad 2.0 at Q)."""

Method = Callable[[np.ndarray, np.ndarray, int], np.ndarray]


@runtime_checkable
class BatchedMethod(Protocol):
    """A method that can also run many pairs in one go: :func:`evaluate_scenes` then uses
    ``match_many``; plain callables are run one scene at a time."""

    def __call__(self, left: np.ndarray, right: np.ndarray, ndisp: int) -> np.ndarray:
        """One pair, as a plain :data:`Method`."""

    def match_many(
        self, pairs: Sequence[tuple[np.ndarray, np.ndarray]], ndisps: Sequence[int]
    ) -> Iterable[tuple[int, np.ndarray, float]]:
        """Every pair, in any order: ``(index in pairs, float32 (H, W) disparity, seconds)``.

        ``seconds`` is the pair's share of the wall time of the call that computed it (that
        call's time divided by the number of pairs it computed), so the times of a run add up to
        its total.
        """


class SceneResult(NamedTuple):
    """One method on one scene: its disparity, metrics per region and wall time (seconds)."""

    scene: str
    disparity: np.ndarray
    metrics: dict[str, dict[str, float]]
    seconds: float


def _check_ground_truth(scene: StereoScene) -> None:
    """Refuse a scene that cannot be scored: no ground truth, or not one known pixel in it."""
    if scene.ground_truth is None:
        raise ValueError(f"scene {scene.name} has no ground truth (disp0GT.pfm)")
    if not np.isfinite(scene.ground_truth).any():
        raise ValueError(f"scene {scene.name} has no known ground-truth disparity: it cannot "
                         "be scored")


def _scored(scene: StereoScene, disparity, seconds: float, scoring: Scoring) -> SceneResult:
    disparity = np.asarray(disparity, dtype=np.float32)
    thresholds = THRESHOLDS if scoring is MIDDEVAL3_SCORING else sorted(scoring.thresholds)
    metrics = evaluate_disparity(disparity, scene.ground_truth, mask=scene.mask, ndisp=scene.ndisp,
                                 thresholds=thresholds, d1=scoring.d1)
    return SceneResult(scene.name, disparity, metrics, seconds)


def rescore(result: SceneResult, scene: StereoScene, *, scoring: Scoring = MIDDEVAL3_SCORING
            ) -> SceneResult:
    """``result`` with its metrics recomputed from its disparity under ``scoring``.

    Parameters
    ----------
    result : SceneResult
        A result of ``scene`` (its ``float32`` ``(H, W)`` disparity is kept, as is its time).
    scene : StereoScene
        The scene, with ground truth.
    scoring : Scoring
        Metrics to compute (see :data:`SCORINGS`).

    Returns
    -------
    SceneResult
    """
    _check_ground_truth(scene)
    return _scored(scene, result.disparity, result.seconds, scoring)


def evaluate_scene(
    method: Method, scene: StereoScene, *, scoring: Scoring = MIDDEVAL3_SCORING
) -> SceneResult:
    """Run ``method`` on one scene with ground truth and compute the metrics of ``scoring``."""
    _check_ground_truth(scene)
    start = time.perf_counter()
    disparity = np.asarray(method(scene.left, scene.right, scene.ndisp), dtype=np.float32)
    return _scored(scene, disparity, time.perf_counter() - start, scoring)


def iter_evaluate_scenes(
    method: Method | BatchedMethod, scenes: Sequence[StereoScene], *,
    scoring: Scoring = MIDDEVAL3_SCORING,
) -> Iterator[tuple[int, SceneResult]]:
    """``(index in scenes, result)`` of every scene as soon as it is done.

    A :class:`BatchedMethod` runs all scenes through its ``match_many`` (its order); any other
    method one scene at a time, in order. Every scene must have ground truth (checked first).
    The metrics are those of ``scoring``.
    """
    scenes = list(scenes)
    for scene in scenes:
        _check_ground_truth(scene)
    if not isinstance(method, BatchedMethod):
        for index, scene in enumerate(scenes):
            yield index, evaluate_scene(method, scene, scoring=scoring)
        return
    runs = method.match_many([(s.left, s.right) for s in scenes], [s.ndisp for s in scenes])
    for index, disparity, seconds in runs:
        yield index, _scored(scenes[index], disparity, seconds, scoring)


def evaluate_scenes(
    method: Method | BatchedMethod, scenes: Iterable[StereoScene], *, progress: bool = False,
    scoring: Scoring = MIDDEVAL3_SCORING,
) -> list[SceneResult]:
    """Evaluate ``method`` on every scene, results in scene order (a tqdm bar when ``progress``).

    See :func:`iter_evaluate_scenes` for how plain and batched methods are run and scored.
    """
    scenes = list(scenes)
    results: list[SceneResult | None] = [None] * len(scenes)
    with tqdm(total=len(scenes), desc="scenes", unit="scene", disable=not progress) as bar:
        for index, result in iter_evaluate_scenes(method, scenes, scoring=scoring):
            results[index] = result
            bar.update(1)
    return results


def scene_average(values: Mapping[str, float], scoring: Scoring) -> float:
    """The ``scoring``'s average of per-scene values (scene name -> value): what
    :func:`summary` reports, and what benchmarks that score their own maps average with.

    A weighted scoring falls back to the plain mean when some scene has no weight (a user's
    own folder in MiddEval3's layout); no average takes a ``nan``.
    """
    if scoring.average == "weighted" and all(name in scoring.weights for name in values):
        return weighted_average(values, weights=scoring.weights)
    return scene_mean(values)


def summary(
    results: Sequence[SceneResult], *, scoring: Scoring = MIDDEVAL3_SCORING
) -> dict[str, dict[str, float]]:
    """Averages over scenes: ``{region: {"bad2.0": %, "bad1.0": %, "bad0.5": %, ...}}``.

    Parameters
    ----------
    results : sequence of SceneResult
        One method's results (distinct scene names).
    scoring : Scoring
        Keys and average: MiddEval3's weighted bad 2.0/1.0/0.5 by default; the means (and
        bad 3.0, D1) of the other layouts from :data:`SCORINGS`.

    Returns
    -------
    dict
        Region (those every result has) -> metric key -> percentage.
    """
    out: dict[str, dict[str, float]] = {}
    for region in REGIONS:
        if not all(region in r.metrics for r in results):
            continue
        out[region] = {
            key: scene_average({r.scene: r.metrics[region][key] for r in results}, scoring)
            for key in scoring.keys
        }
    return out


def _columns(results: Sequence[SceneResult], scoring: Scoring) -> list[tuple[str, str]]:
    """(region, metric) columns: the keys of ``scoring`` for the regions every result has."""
    regions = [reg for reg in REGIONS if all(reg in r.metrics for r in results)]
    return [(region, key) for key in scoring.keys for region in regions]


def markdown_table(results: Sequence[SceneResult], *, scoring: Scoring = MIDDEVAL3_SCORING) -> str:
    """Per-scene metrics of ``scoring`` (nonocc and all) with their average as last row.

    MiddEval3 by default: bad 2.0 / 1.0 / 0.5 and the weighted average. Scenes without an
    occlusion mask have no "nonocc" region; the table then shows "all" only.
    """
    columns = _columns(results, scoring)
    header = "| scene | " + " | ".join(f"{k} {reg}" for reg, k in columns) + " | time s |"
    rule = "|---" * (len(columns) + 2) + "|"
    lines = [header, rule]
    for r in results:
        cells = [f"{r.metrics[reg][k]:.2f}" for reg, k in columns]
        lines.append(f"| {r.scene} | " + " | ".join(cells) + f" | {r.seconds:.2f} |")
    averages = summary(results, scoring=scoring)
    cells = [f"**{averages[reg][k]:.2f}**" for reg, k in columns]
    median_time = float(np.median([r.seconds for r in results]))
    label = "weighted average" if scoring.average == "weighted" else "mean"
    lines.append(f"| **{label}** | " + " | ".join(cells) + f" | {median_time:.2f} (median) |")
    return "\n".join(lines)


def table1_markdown(results: Mapping[str, Sequence[SceneResult]], *, threshold: float = 2.0) -> str:
    """The paper's Table 1 layout: per scene, All and Nonocc of each method, ours then the paper's.

    Parameters
    ----------
    results : {method name: per-scene results}
    threshold : float
        Bad-pixel threshold of our columns.
    """
    key = f"bad{float(threshold)}"
    methods = list(results)
    header = ["scene"]
    for m in methods:
        header += [f"{m.upper()} All", f"{m.upper()} Nonocc"]
        if m in PAPER_TABLE1:
            header += [f"{m.upper()} All (paper)", f"{m.upper()} Nonocc (paper)"]
    lines = ["| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
    scenes = [r.scene for r in next(iter(results.values()))]
    for i, scene in enumerate(scenes):
        cells = [scene]
        for m in methods:
            metrics = results[m][i].metrics
            cells += [f"{metrics['all'][key]:.2f}", f"{metrics['nonocc'][key]:.2f}"]
            if m in PAPER_TABLE1:
                paper = PAPER_TABLE1[m].get(scene, {})
                cells += [f"{paper.get('all', float('nan')):g}", f"{paper.get('nonocc', float('nan')):g}"]
        lines.append("| " + " | ".join(cells) + " |")
    cells = ["**Average**"]
    for m in methods:
        cells += [f"**{weighted_average({r.scene: r.metrics[region][key] for r in results[m]}):.2f}**"
                  for region in ("all", "nonocc")]
        if m in PAPER_TABLE1:
            cells += [f"**{weighted_average({s: PAPER_TABLE1[m][s][region] for s in scenes if s in PAPER_TABLE1[m]}):.2f}**"
                      for region in ("all", "nonocc")]
    lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def summary_markdown(
    results: Mapping[str, Sequence[SceneResult]], *, scoring: Scoring = MIDDEVAL3_SCORING
) -> str:
    """One row per method: the averages of ``scoring`` (nonocc and all) and median time.

    MiddEval3 by default: weighted bad 2.0 / 1.0 / 0.5.
    """
    columns = _columns([r for rows in results.values() for r in rows], scoring)
    lines = ["| method | " + " | ".join(f"{k} {reg}" for reg, k in columns) + " | median s |",
             "|---" * (len(columns) + 2) + "|"]
    for method, rows in results.items():
        averages = summary(rows, scoring=scoring)
        cells = [f"{averages[reg][k]:.2f}" for reg, k in columns]
        seconds = float(np.median([r.seconds for r in rows]))
        lines.append(f"| {method} | " + " | ".join(cells) + f" | {seconds:.2f} |")
    return "\n".join(lines)


def write_metrics_csv(path: str | Path, results: Mapping[str, Sequence[SceneResult]]) -> None:
    """Per-scene metrics, one row per (method, scene, region), written atomically."""
    rows = [
        {"method": m, "scene": r.scene, "region": region, "seconds": f"{r.seconds:.3f}",
         **{k: f"{v:.4f}" for k, v in r.metrics[region].items()}}
        for m, per_scene in results.items() for r in per_scene for region in r.metrics
    ]
    with atomic_output(path) as tmp, open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
