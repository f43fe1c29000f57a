"""Sparsification curves of the confidence measures: is a confident pixel a correct one?

For every scene with ground truth, the pixels with ground truth are sorted by confidence
(most confident first) and the bad 2.0 rate (error > 2 px) of the most confident x % is
measured, x = 5, 10, ..., 100. The oracle sorts by the true error (the best any confidence can
do); a random order gives the overall bad rate at every x. The area under a curve (its mean
over the 20 fractions) summarises it: lower is better, the oracle's is the floor. Curves are
averaged over scenes. Every measure of :data:`sswjax.stages.confidence.MEASURES` is scored on
one run of the graph per scene (``sswjax.graph.ssw_cues``), plus ``ratio x lr``.

The validity bits are scored too: for each low-confidence threshold, the share of pixels with
ground truth that carry a bit, and the bad 2.0 of those without one.

    python benchmarks/sparsification.py [--presets paper,accurate] [--sets middeval3,kitti]

writes ``benchmarks/results/sparsification.{md,csv}`` and ``sparsification.png``.
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

import sswjax
from sswjax.api.match import match_graph
from sswjax.graph import DEFAULT_CHUNK, ssw_cues
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.runtime.compilation import enable_compilation_cache
from sswjax.data.layouts import load_scenes
from sswjax.stages.confidence import (MEASURES, ConfidenceCues, ambiguous, confidence,
                                      validity_mask)

sys.path.insert(0, str(Path(__file__).parent))
from _report import write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = {"middeval3": ROOT.parent / "shared" / "data" / "MiddEval3",
        "kitti": ROOT.parent / "shared" / "data" / "KITTI2012"}
SET_NAMES = {"middeval3": "MiddEval3 trainingQ", "kitti": "KITTI 2012"}
FRACTIONS = np.arange(5, 101, 5)
BAD = 2.0
THRESHOLDS = (0.0, 0.02, 0.05, 0.1, 0.2)


class _Maps(NamedTuple):
    disparity: jax.Array
    cost: jax.Array
    second: jax.Array
    lr_distance: jax.Array
    initial: jax.Array
    lr_failed: jax.Array
    margin: jax.Array  # how far the matching cost's minimum stands out (bit 4 where it does not)


@functools.partial(jax.jit, static_argnames=("ndisp", "chunk"))
def _graph(left, right, params, *, ndisp, valid_ndisp=None, chunk=DEFAULT_CHUNK,
           valid_shape=None):
    """``ssw_cues`` flattened into one NamedTuple of maps, so strips and buckets crop each."""
    disparity, cues = ssw_cues(left, right, params, ndisp=ndisp, valid_ndisp=valid_ndisp,
                               chunk=chunk, valid_shape=valid_shape)
    return _Maps(disparity, *cues)


def sparsification(error: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Bad rate (%) of the first x % of ``order`` for x in :data:`FRACTIONS`.

    Parameters
    ----------
    error : float (N,), absolute errors
    order : int (N,), indices from the most to the least trusted

    Returns
    -------
    float64 (len(FRACTIONS),)

    Examples
    --------
    >>> sparsification(np.array([0.0, 5.0]), np.array([0, 1]))[[0, -1]].tolist()
    [0.0, 50.0]
    """
    bad = (error[order] > BAD).astype(np.float64)
    counts = np.maximum(np.ceil(FRACTIONS / 100 * len(error)).astype(int), 1)
    return 100 * np.cumsum(bad)[counts - 1] / counts


def _by_confidence(value: np.ndarray, rng) -> np.ndarray:
    """Indices from the most to the least confident, ties in random order."""
    return np.lexsort((rng.random(value.shape), -value))


def scene_curves(maps: _Maps, ground_truth: np.ndarray, rng) -> tuple[dict, dict]:
    """Sparsification curves of every measure (and oracle, random) and the validity rows."""
    known = np.isfinite(ground_truth)
    disparity = maps.disparity
    error = np.abs(disparity - ground_truth)[known]
    cues = ConfidenceCues(*(jnp.asarray(m) for m in maps[1:]))
    values = {name: np.asarray(confidence(cues, jnp.asarray(disparity), measure=name))
              for name in MEASURES}
    values["ratio x lr"] = values["ratio"] * values["lr"]
    curves = {name: sparsification(error, _by_confidence(v[known], rng)) for name, v in values.items()}
    curves["oracle"] = sparsification(error, np.argsort(error, kind="stable"))
    curves["random"] = np.full(len(FRACTIONS), 100 * np.mean(error > BAD))
    validity = {}
    for threshold in THRESHOLDS:
        bits = np.asarray(validity_mask(jnp.asarray(disparity), jnp.asarray(values["combined"]),
                                        jnp.asarray(maps.lr_failed), threshold=threshold,
                                        ambiguous=ambiguous(cues)))[known]
        kept = bits == 0
        validity[threshold] = (100 * np.mean(~kept),
                               100 * np.mean(error[kept] > BAD) if kept.any() else np.nan)
    return curves, validity


def run(preset: str, data: str, *, limit: int = 0) -> tuple[dict, dict, float]:
    """Mean curves and validity rows over the scenes of one set (the first ``limit`` if > 0),
    and the seconds it took."""
    params = sswjax.preset(preset)
    scenes = load_scenes(DATA[data])
    scenes = scenes[:limit] if limit > 0 else scenes
    rng = np.random.default_rng(0)
    curves, validity = [], []
    start = time.perf_counter()
    for scene in scenes:
        maps = match_graph(scene.left, scene.right, scene.ndisp, graph=_graph, params=params,
                           buckets=ShapeBuckets(), check_memory=False)
        c, v = scene_curves(maps, scene.ground_truth, rng)
        curves.append(c)
        validity.append(v)
        print(f"{preset} {data} {scene.name}: auc combined {c['combined'].mean():.2f}, "
              f"oracle {c['oracle'].mean():.2f}, random {c['random'].mean():.2f}", flush=True)
    mean_curves = {name: np.mean([c[name] for c in curves], axis=0) for name in curves[0]}
    mean_validity = {t: tuple(np.nanmean([v[t][i] for v in validity]) for i in range(2))
                     for t in THRESHOLDS}
    return mean_curves, mean_validity, time.perf_counter() - start


def figure(path: Path, results: dict) -> None:
    """One panel per (set, preset): the mean sparsification curves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(results)
    fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.6), squeeze=False)
    styles = {"oracle": dict(color="k", ls="--"), "random": dict(color="0.6", ls=":")}
    for axis, key in zip(axes[0], keys):
        for name, curve in results[key][0].items():
            axis.plot(FRACTIONS, curve, label=name, **styles.get(name, {}))
        axis.set_title(f"{SET_NAMES[key[1]]}, {key[0]}", fontsize=10)
        axis.set_xlabel("most confident pixels kept (%)")
        axis.set_ylim(bottom=0)
        axis.grid(alpha=0.3)
    axes[0][0].set_ylabel(f"bad {BAD} (%) of the pixels kept")
    axes[0][-1].legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--presets", default="paper,accurate")
    parser.add_argument("--sets", default="middeval3,kitti")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    parser.add_argument("--limit", type=int, default=0, help="only the first N scenes of each set")
    args = parser.parse_args(argv)
    enable_compilation_cache()
    results = {}
    for data in args.sets.split(","):
        for preset in args.presets.split(","):
            results[(preset, data)] = run(preset, data, limit=args.limit)
    names = list(next(iter(results.values()))[0])
    lines = [f"Area under the sparsification curve (mean bad {BAD} % over the most confident "
             f"5, 10, ..., 100 % of pixels with ground truth; lower is better; curves averaged "
             f"over scenes); jax {jax.__version__}", "",
             "| set | preset | " + " | ".join(names) + " | seconds |",
             "|---|---|" + "---|" * (len(names) + 1)]
    rows = []
    for (preset, data), (curves, validity, seconds) in results.items():
        aucs = {name: curves[name].mean() for name in names}
        best = min((n for n in names if n not in ("oracle", "random")), key=aucs.get)
        cells = [f"**{aucs[n]:.2f}**" if n == best else f"{aucs[n]:.2f}" for n in names]
        lines.append(f"| {SET_NAMES[data]} | {preset} | " + " | ".join(cells) + f" | {seconds:.0f} |")
        for name in names:
            rows.append({"set": data, "preset": preset, "measure": name, "auc": f"{aucs[name]:.4f}",
                         **{f"bad@{x}": f"{v:.4f}" for x, v in zip(FRACTIONS, curves[name])}})
    lines += ["", f"Validity bits (measure `combined`): share of pixels with ground truth that "
              f"carry a bit, and bad {BAD} % of those that carry none, by low-confidence "
              "threshold (0: bits 0 and 1 only)", "",
              "| set | preset | " + " | ".join(f"t = {t}: flagged % / bad % kept" for t in THRESHOLDS)
              + " |", "|---|---|" + "---|" * len(THRESHOLDS)]
    for (preset, data), (_, validity, _) in results.items():
        lines.append(f"| {SET_NAMES[data]} | {preset} | " + " | ".join(
            f"{validity[t][0]:.1f} / {validity[t][1]:.2f}" for t in THRESHOLDS) + " |")
        for t in THRESHOLDS:
            rows.append({"set": data, "preset": preset, "measure": f"validity t={t}",
                         "flagged_pct": f"{validity[t][0]:.4f}", "bad_kept_pct": f"{validity[t][1]:.4f}"})
    keys = (["set", "preset", "measure", "auc"] + [f"bad@{x}" for x in FRACTIONS]
            + ["flagged_pct", "bad_kept_pct"])
    write_report(args.out, "sparsification", "\n".join(lines), rows, keys)
    figure(args.out / "sparsification.png", results)
    print(f"wrote {args.out / 'sparsification.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
