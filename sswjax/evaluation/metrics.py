"""Disparity error metrics following the MiddEval3 ``evaldisp`` rules.

Array conventions
-----------------
* ``disparity``: floating ``(H, W)`` prediction in pixels; ``inf``/``nan`` = no prediction.
* ``ground_truth``: floating ``(H, W)`` in pixels; non-finite (``inf``) = unknown.
* ``mask``: ``uint8`` ``(H, W)``; 255 = non-occluded, 128 = occluded, 0 = unknown.

Rules
-----
* Pixels with non-finite ground truth are skipped entirely. Region ``"all"`` is every other
  pixel; region ``"nonocc"`` further requires ``mask == 255``.
* A non-finite prediction is *invalid*: it stays in the denominator, counts as bad for every
  threshold, is reported as ``invalid`` and is left out of ``avgerr`` and ``rms``.
* Valid predictions are clipped to ``[0, ndisp]`` before comparison.
* ``bad<t>`` = percentage with ``|d - gt| > t`` (strict) or invalid; ``D1`` (KITTI, on
  request) = percentage with ``|d - gt| > 3`` and ``|d - gt| > 0.05 gt`` or invalid; ``invalid`` =
  percentage invalid; ``avgerr``/``rms`` = mean / root-mean-square of ``|d - gt|`` over valid
  pixels; ``a90`` = smallest error ``e`` such that at least 90 % of the evaluated pixels have
  error ``<= e``, with invalid pixels counted as infinite error (so ``a90`` is ``inf`` when
  more than 10 % are invalid).
* Percentages are in ``[0, 100]``; errors in pixels. A region with no pixels gives ``nan``
  everywhere, as do ``avgerr``/``rms`` when no prediction is valid.
* Averages over scenes (:func:`weighted_average`, :func:`scene_mean`) refuse a value that is
  not finite, naming its scene: a ``nan`` is never averaged.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from sswjax._checks import (
    check_floating,
    check_integer,
    check_positive_int,
    check_rank,
    check_same_shape,
)

__all__ = ["D1_FRACTION", "D1_PIXELS", "MIDDEVAL3_TRAINING_WEIGHTS", "evaluate_disparity",
           "scene_mean", "weighted_average"]

#: KITTI's D1 outlier: an error above this many pixels *and* above :data:`D1_FRACTION` of the
#: true disparity (the devkit's ``tau = [3, 0.05]``).
D1_PIXELS = 3.0
D1_FRACTION = 0.05

#: Weights of the MiddEval3 training scenes in the official averages.
MIDDEVAL3_TRAINING_WEIGHTS: dict[str, float] = {
    **dict.fromkeys(
        [
            "Adirondack", "ArtL", "Jadeplant", "Motorcycle", "MotorcycleE",
            "Piano", "Pipes", "PlaytableP", "Recycle", "Teddy",
        ],
        0.08,
    ),
    **dict.fromkeys(["PianoL", "Playroom", "Playtable", "Shelves", "Vintage"], 0.04),
}  # fmt: skip


def _region_metrics(
    error: np.ndarray, thresholds: Sequence[float], ground_truth: np.ndarray | None
) -> dict[str, float]:
    """Metrics of a 1-D array of absolute errors where ``inf`` marks invalid predictions.

    ``ground_truth`` (1-D, same size) adds ``"D1"``; ``None`` leaves it out.
    """
    d1 = [] if ground_truth is None else ["D1"]
    keys = [f"bad{t}" for t in thresholds] + d1 + ["invalid", "avgerr", "rms", "a90"]
    n = error.size
    if n == 0:
        return dict.fromkeys(keys, float("nan"))
    valid = error[np.isfinite(error)]
    out = {f"bad{t}": 100.0 * int(np.count_nonzero(error > t)) / n for t in thresholds}
    if ground_truth is not None:
        bad = (error > D1_PIXELS) & (error > D1_FRACTION * ground_truth)
        out["D1"] = 100.0 * int(np.count_nonzero(bad)) / n
    out["invalid"] = 100.0 * (n - valid.size) / n
    out["avgerr"] = float(valid.mean()) if valid.size else float("nan")
    out["rms"] = float(np.sqrt(np.mean(valid**2))) if valid.size else float("nan")
    out["a90"] = float(np.sort(error)[(9 * n + 9) // 10 - 1])  # the ceil(0.9 n)-th smallest
    return out


def evaluate_disparity(
    disparity: np.ndarray,
    ground_truth: np.ndarray,
    *,
    mask: np.ndarray | None = None,
    ndisp: int,
    thresholds: Sequence[float] = (0.5, 1.0, 2.0, 4.0),
    d1: bool = False,
) -> dict[str, dict[str, float]]:
    """Evaluate a disparity map against ground truth with the MiddEval3 rules.

    Parameters
    ----------
    disparity : numpy.ndarray
        Floating ``(H, W)`` prediction; ``inf``/``nan`` = invalid.
    ground_truth : numpy.ndarray
        Floating ``(H, W)``; non-finite = unknown (skipped).
    mask : numpy.ndarray, optional
        Integer ``(H, W)`` occlusion mask; 255 = non-occluded. Enables region ``"nonocc"``.
    ndisp : int
        Disparity range; valid predictions are clipped to ``[0, ndisp]``.
    thresholds : sequence of float
        Error thresholds in pixels, each reported as ``f"bad{float(t)}"``.
    d1 : bool
        Also report KITTI's ``"D1"`` (after the ``bad`` keys; see the module docstring).

    Returns
    -------
    dict
        ``{"all": metrics}`` plus ``"nonocc"`` if ``mask`` is given, where ``metrics`` maps
        ``"bad0.5"``, ``"bad1.0"``, ... (then ``"D1"`` if asked) and ``"invalid"`` to
        percentages and ``"avgerr"``, ``"rms"``, ``"a90"`` to pixels (see the module docstring).

    Raises
    ------
    ValueError, TypeError
        On bad shapes, dtypes, ``ndisp`` or thresholds.

    Examples
    --------
    >>> gt = np.array([[1.0, 2.0, np.inf]], np.float32)
    >>> d = np.array([[1.0, 5.0, 3.0]], np.float32)
    >>> evaluate_disparity(d, gt, ndisp=16)["all"]["bad2.0"]
    50.0
    """
    disparity = np.asarray(disparity)
    ground_truth = np.asarray(ground_truth)
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    check_rank("ground_truth", ground_truth, 2)
    check_floating("ground_truth", ground_truth)
    check_same_shape("disparity", disparity, "ground_truth", ground_truth)
    if mask is not None:
        mask = np.asarray(mask)
        check_rank("mask", mask, 2)
        check_integer("mask", mask)
        check_same_shape("mask", mask, "ground_truth", ground_truth)
    check_positive_int("ndisp", ndisp)
    thresholds = tuple(float(t) for t in thresholds)
    if not thresholds or not all(math.isfinite(t) and t >= 0 for t in thresholds):
        raise ValueError(f"thresholds must be finite numbers >= 0 (at least one), got {thresholds}")

    d = disparity.astype(np.float64)
    gt = ground_truth.astype(np.float64)
    known = np.isfinite(gt)
    valid = np.isfinite(d)
    error = np.full(d.shape, np.inf)
    error[valid] = np.abs(np.clip(d[valid], 0.0, ndisp) - gt[valid])

    regions = {"all": known} if mask is None else {"all": known, "nonocc": known & (mask == 255)}
    return {
        region: _region_metrics(error[where], thresholds, gt[where] if d1 else None)
        for region, where in regions.items()
    }


def _check_finite(values: Mapping[str, float]) -> None:
    """Refuse an average over ``values`` when a scene's value is not a finite number."""
    if not values:
        raise ValueError("values must name at least one scene")
    for scene, value in values.items():
        if not math.isfinite(float(value)):
            raise ValueError(f"scene {scene} has no score to average ({float(value)}): a scene "
                             "without a known ground-truth pixel in the region cannot be "
                             "scored; leave it out")


def weighted_average(
    values: Mapping[str, float], *, weights: Mapping[str, float] = MIDDEVAL3_TRAINING_WEIGHTS
) -> float:
    """Weighted average of per-scene values over the scenes present.

    The weights are renormalised over the scenes in ``values``: leaving a scene out divides by
    the sum of the others' weights.

    Parameters
    ----------
    values : Mapping[str, float]
        Scene name -> value (e.g. bad2.0 percentage), each finite.
    weights : Mapping[str, float]
        Scene name -> weight; defaults to the MiddEval3 training weights.

    Returns
    -------
    float
        ``sum(w * v) / sum(w)`` over the scenes in ``values``.

    Raises
    ------
    ValueError
        If ``values`` is empty, names a scene without a weight, or holds a value that is not
        finite (``nan``: a scene with no known ground truth; the message names it).

    Examples
    --------
    >>> round(weighted_average({"Teddy": 10.0, "Vintage": 40.0}), 6)
    20.0
    """
    _check_finite(values)
    unknown = sorted(set(values) - set(weights))
    if unknown:
        raise ValueError(f"values has scenes without a weight: {', '.join(unknown)}")
    total = sum(weights[s] for s in values)
    if total <= 0:
        raise ValueError(f"weights of the scenes in values must sum to > 0, got {total}")
    return sum(weights[s] * float(v) for s, v in values.items()) / total


def scene_mean(values: Mapping[str, float]) -> float:
    """Plain mean of per-scene values (every scene alike), each finite.

    Raises
    ------
    ValueError
        If ``values`` is empty or a value is not finite (the message names its scene).

    Examples
    --------
    >>> scene_mean({"000000": 10.0, "000001": 40.0})
    25.0
    """
    _check_finite(values)
    return float(np.mean([float(v) for v in values.values()]))
