"""Which search objective tracks the metric: surrogates on crops against bad 2.0 / 1.0 on whole
held-out images, ranked over a sample of parameter points.

Each data set's scenes are split in two halves (``--seed``): crops are drawn from one half,
whole images of the other half are matched with ``sswjax.match`` (the full pipeline, WTA and
every later stage). The parameter points are the starting preset, the three points the
earlier leave-one-data-set-out search found (``tuning/runs/accurate-datasets``), and random
points around the preset (each searched option scaled by ``exp(U(-spread, spread))``). For
each point and surrogate (:data:`sswjax.search.SURROGATES`, at two temperatures) the mean over
the crops of one set, and the crop WTA bad 2.0 of the old validation; then Spearman's rank
correlation across points, per set and pooled (each set's value divided by the preset's, the
mean over sets), with the whole-image bad 2.0 and 1.0.

    python benchmarks/surrogates.py --points 16 -o benchmarks/results/surrogates
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from scipy.stats import spearmanr

import sswjax
from sswjax import search
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.evaluation.runner import SCORINGS, _average
from sswjax.graph import ssw_disparity
from sswjax.runtime.buckets import ShapeBuckets

from _report import write_report  # benchmarks/, on the path when run as a script

SETS = {"trainingQ": ("MiddEval3", "middeval3", ("nonocc", "all")),
        "KITTI2012": ("KITTI2012", "kitti", ("all",)),
        "Middlebury2001": ("Middlebury2001", "mean", ("all",))}
EARLIER = Path(__file__).resolve().parents[1] / "tuning/runs/accurate-datasets/results.json"
OLD_NAMES = {"sgm_p1": "optimizer.p1", "sgm_p2": "optimizer.p2", "sgm_sigma": "optimizer.sigma",
             "tad_truncation": "cost.tad_truncation",
             "gradient_truncation": "cost.gradient_truncation"}


def points(base, n_random: int, spread: float, rng):
    """``[(name, params)]``: the preset, the earlier search's fold results, random points."""
    out = [("preset", base)]
    if EARLIER.exists():
        for fold in json.loads(EARLIER.read_text())["folds"]:
            changes = {OLD_NAMES[k]: v for k, v in fold["params"].items()}
            out.append((f"searched-without-{fold['held_out']}", base.replace(**changes)))
    for i in range(n_random):
        changes = {k: float(search.value_of(base, k)) * float(np.exp(rng.uniform(-spread, spread)))
                   for k in search.SGM_SEARCHED}
        out.append((f"random-{i}", base.replace(**changes)))
    return out


def crop_sets(scenes_by_set, rng, *, n: int, height: int, width: int, ndisp: int):
    """Fixed crops per set from the crop halves (KITTI redrawn to 10 % ground truth)."""
    out = {}
    for name, scenes in scenes_by_set.items():
        pool = [search.prepare_scene(s, channels=3) for s in scenes if s.ndisp <= ndisp]
        out[name] = search.random_crops(pool, rng, batch=n, height=height, width=width,
                                        min_valid=0.1 if name == "KITTI2012" else 0.0)
    return out


def surrogate_values(params, crops, *, ndisp: int, temperatures, segments: int):
    """``{surrogate@T: mean over valid pixels}`` and ``crop_wta_bad2`` on one set's crops."""
    p = params if params.segments is None else params.replace(**{"segments.n_segments": segments})
    lefts, rights, gts, valids, nds = crops
    sums, counts, bad = {}, 0, 0
    raw = search.to_unconstrained(p, temperature=1.0, searched=search.SGM_SEARCHED)
    for i in range(len(lefts)):
        cost, _ = _volume(raw, lefts[i], rights[i], nds[i], p, ndisp)
        gt, valid = jnp.asarray(gts[i]), jnp.asarray(valids[i])
        for t in temperatures:
            for name, fn in search.SURROGATES.items():
                key = f"{name}@{t:g}"
                value = float(jnp.where(valid, fn(cost, gt, temperature=t), 0.0).sum())
                sums[key] = sums.get(key, 0.0) + value
        counts += int(valid.sum())
        d = np.asarray(ssw_disparity(lefts[i], rights[i], p, ndisp=ndisp))
        bad += int((np.abs(d - gts[i])[valids[i]] > 2.0).sum())
    out = {k: v / max(counts, 1) for k, v in sums.items()}
    out["crop_wta_bad2"] = 100.0 * bad / max(counts, 1)
    return out


_VOLUMES = {}


def _volume(raw, left, right, scene_ndisp, params, ndisp):
    key = (jax.tree_util.tree_structure(params), ndisp, left.shape)
    if key not in _VOLUMES:
        _VOLUMES[key] = jax.jit(lambda r, l, rt, n: search.search_volume(
            r, l, rt, base=params, ndisp=ndisp, scene_ndisp=n))
    return _VOLUMES[key](raw, left, right, scene_ndisp)


def whole_image_errors(params, scenes_by_set, buckets):
    """``{set: {"bad2.0": e, "bad1.0": e}}``: trainingQ the mean of weighted nonocc and all,
    the others the mean over scenes of ``all``."""
    out = {}
    for name, scenes in scenes_by_set.items():
        scoring = SCORINGS[SETS[name][1]]
        metrics = {}
        for s in scenes:
            d = sswjax.match(s.left, s.right, s.ndisp, params=params, buckets=buckets)
            metrics[s.name] = evaluate_disparity(d, s.ground_truth, mask=s.mask, ndisp=s.ndisp,
                                                 thresholds=scoring.thresholds)
        out[name] = {key: float(np.mean([_average({k: m[r][key] for k, m in metrics.items()},
                                                   scoring) for r in SETS[name][2]]))
                     for key in ("bad2.0", "bad1.0")}
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add = parser.add_argument
    add("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data")
    add("--preset", default="accurate")
    add("--points", type=int, default=16, help="random parameter points")
    add("--spread", type=float, default=0.7, help="log-scale half-width of the random points")
    add("--crops", type=int, default=12, help="crops per data set")
    add("--crop", type=int, nargs=2, default=(96, 192), metavar=("H", "W"))
    add("--temperatures", type=float, nargs="+", default=(0.08, 0.02))
    add("--seed", type=int, default=0)
    add("-o", "--output", type=Path, default=Path("benchmarks/results/surrogates"))
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    base = sswjax.preset(args.preset)
    crop_half, image_half = {}, {}
    for name, (folder, _, _) in SETS.items():
        scenes = load_scenes(args.data / folder)
        order = rng.permutation(len(scenes))
        crop_half[name] = [scenes[i] for i in order[: len(scenes) // 2]]
        image_half[name] = [scenes[i] for i in order[len(scenes) // 2:]]
    ndisp = 128
    crops = crop_sets(crop_half, rng, n=args.crops, height=args.crop[0], width=args.crop[1],
                      ndisp=ndisp)
    area = np.mean([s.left.shape[0] * s.left.shape[1] for g in crop_half.values() for s in g])
    full = 0 if base.segments is None else base.segments.n_segments
    segments = search.crop_segments(full, args.crop[0] * args.crop[1], area)
    buckets = ShapeBuckets(size_step=64, ndisp_step=32)
    rows = []
    for name, params in points(base, args.points, args.spread, rng):
        row = {"point": name, **{k: float(search.value_of(params, k)) for k in search.SGM_SEARCHED}}
        for set_name, errors in whole_image_errors(params, image_half, buckets).items():
            row.update({f"{set_name} {k}": v for k, v in errors.items()})
        for set_name, c in crops.items():
            values = surrogate_values(params, c, ndisp=ndisp, temperatures=args.temperatures,
                                      segments=segments)
            row.update({f"{set_name} {k}": v for k, v in values.items()})
        rows.append(row)
        print(json.dumps({k: round(v, 4) if isinstance(v, float) else v for k, v in row.items()}),
              file=sys.stderr, flush=True)
    measures = [k.split(" ", 1)[1] for k in rows[0] if k.startswith("trainingQ ")
                and not k.endswith(("bad2.0", "bad1.0"))]
    table, keys = correlations(rows, measures)
    write_report(args.output, "surrogates", table["md"], table["rows"], keys)
    write_report(args.output, "points", "", rows, list(rows[0]))
    return 0


def correlations(rows, measures):
    """Spearman's rho of each measure with bad 2.0 and 1.0, per set and pooled."""
    out, keys = [], ["surrogate"]
    pooled = {}
    for m in measures + ["bad2.0", "bad1.0"]:
        rel = [np.mean([r[f"{s} {m}"] / rows[0][f"{s} {m}"] for s in SETS]) for r in rows]
        pooled[m] = rel
    for m in measures:
        row = {"surrogate": m}
        for metric in ("bad2.0", "bad1.0"):
            for s in SETS:
                rho = spearmanr([r[f"{s} {m}"] for r in rows], [r[f"{s} {metric}"] for r in rows])[0]
                row[f"{s} {metric}"] = rho
            row[f"pooled {metric}"] = spearmanr(pooled[m], pooled[metric])[0]
        out.append(row)
    keys += [k for k in out[0] if k != "surrogate"]
    lines = ["| surrogate | " + " | ".join(keys[1:]) + " |", "|" + "---|" * len(keys)]
    for row in out:
        lines.append(f"| {row['surrogate']} | " + " | ".join(f"{row[k]:+.2f}" for k in keys[1:]) + " |")
    return {"md": "\n".join(lines), "rows": out}, keys


if __name__ == "__main__":
    sys.exit(main())
