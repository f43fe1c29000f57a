"""Gradient-based (optax) search of the continuous SSW parameters with leave-scenes-out CV.

One command runs everything (resumable; re-running skips finished parts)::

    python tuning/search.py --out tuning/runs/main

Plan: the 15 trainingQ scenes are shuffled with ``--seed`` and split into ``--folds`` folds.
For each fold the continuous parameters are searched on the other scenes (random fixed-size
crops, soft-argmin, smooth L1; :mod:`sswjax.search`), then the full WTA pipeline is run on the
held-out scenes with the searched and with the hand-set parameters. A final search on all 15
scenes gives ``tuning/params/tuned.json``. Files in ``--out``: ``fold<k>/`` and ``final/``
(``checkpoint.pkl``, ``log.json``, ``params.json``), ``eval_*.json`` (per-scene metrics),
``results.json`` (CV table) and ``curves.png``.

``--folds datasets --pipeline accurate`` (leave one data set out): the ``accurate`` preset's
truncations and SGM penalties (:data:`sswjax.search.SGM_SEARCHED`) are searched through its
semi-global optimiser on crops of all but one of ``--datasets`` (each step draws a set
uniformly, then a bucket and crops; gray sets repeated to 3 channels so they share compiled
steps; ``--min-valid`` redraws crops short of ground truth, for KITTI), then ``sswjax.match``
runs on the whole held-out set with the searched and with the preset's parameters, scored as
``sswjax evaluate`` scores that set. Files: ``fold-<set>/`` (``log.json``, ``params.json``,
``checkpoint.pkl``), ``eval_<set>_{searched,accurate}.json`` (per scene), ``results.json`` (the
held-out figures, searched values, times), ``results.md`` (them as tables) and ``curves.png``.
Scenes with ndisp > 192 are scored but not searched on.

Crops use the scene's full disparity range. To compile once per shape, scenes are put in two
buckets: ndisp <= 96 (padded ndisp 96, crops ``--crop`` x 128) and ndisp <= 192 (padded 192,
crops ``--crop`` x 224); the padded disparities are masked out before the soft-argmin. Each step
draws a bucket with probability proportional to its number of training scenes. Each step's
crops are split over all JAX devices (:func:`sswjax.search.make_update_step`; on one device the
step is the unsharded one, bit for bit); ``--batch`` a multiple of the device count wastes no
device (another size is padded with zero-weight crops).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from plot import plot_run, results_markdown, summarise, weighted  # tuning/plot.py

import sswjax
from sswjax import search as tuning
from sswjax._files import atomic_output, write_json
from sswjax.config import load_params, save_params
from sswjax.data.layouts import detect_layout, find_data_root, load_scenes
from sswjax.data.layouts.middeval3 import load_middeval3
from sswjax.evaluation.runner import MIDDEVAL3_SCORING, SCORINGS, evaluate_scenes
from sswjax.graph import ssw_disparity

ROOT = Path(__file__).resolve().parent
DATASETS = [ROOT.parent.parent / "shared" / "data" / name
             for name in ("MiddEval3", "KITTI2012", "Middlebury2001")]
BUCKETS = ((96, 128), (192, 224))  # (padded ndisp, crop width)
DATE = "2026-11-22"
OLD_FREEZE_KEYS = {"weight_logits": "cost.weight_logits", "segment_weight": "aggregation.segment_weight",
                   **{k: f"cost.{k}" for k in ("tad_truncation", "gradient_truncation")},
                   **{f"sgm_{k}": f"optimizer.{k}" for k in ("p1", "p2", "sigma")}}
"""The raw keys' names before the configuration was nested (``--freeze``) -> the raw keys."""


def freeze_key(text: str) -> str:
    """``--freeze``: a raw key, or its old name (:data:`OLD_FREEZE_KEYS`)."""
    return OLD_FREEZE_KEYS.get(text, text)


def folds_option(text: str):
    """``--folds``: a positive number of scene folds, or ``"datasets"``."""
    if text == "datasets":
        return text
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or 'datasets', got {text!r}") from None
    if value < 2:
        raise argparse.ArgumentTypeError(f"need at least 2 folds, got {value}")
    return value


def bucket_of(scene) -> int:
    for i, (nd, _) in enumerate(BUCKETS):
        if scene.ndisp <= nd:
            return i
    raise ValueError(f"scene {scene.name}: ndisp {scene.ndisp} > {BUCKETS[-1][0]}")


def with_segments(params, n_segments: int):
    """``params`` with ``n_segments`` superpixels (unchanged without superpixels)."""
    if params.segments is None:
        return params
    return params.replace(**{"segments.n_segments": n_segments})


def crop_wta_bad2(params, crops_by_bucket, segments_by_bucket):
    """Weighted-by-pixels bad 2.0 (%) of the full WTA pipeline on fixed validation crops."""
    bad = total = 0
    for b, crops in crops_by_bucket.items():
        if crops is None:
            continue
        lefts, rights, gts, valids, _ = crops
        p = with_segments(params, segments_by_bucket[b])
        nd = BUCKETS[b][0]
        for i in range(len(lefts)):
            d = np.asarray(ssw_disparity(lefts[i], rights[i], p, ndisp=nd))
            err = np.abs(d - gts[i])[valids[i]]
            bad += int((err > 2.0).sum())
            total += err.size
    return 100.0 * bad / max(total, 1)


def run_search(train, val, out: Path, base, args, desc, *, searched=tuning.SEARCHED):
    """Search the options ``searched`` on ``train``; log held-out crop WTA bad 2.0 on ``val``
    (or train) scenes.

    ``train`` is a list of scenes, or a list of groups of scenes (one per data set): then each
    step first draws a group uniformly, so that no set outweighs the others by its scene count.
    """
    groups = train if train and isinstance(train[0], list) else [train]
    train = [s for g in groups for s in g]
    out.mkdir(parents=True, exist_ok=True)
    ckpt, log_path = out / "checkpoint.pkl", out / "log.json"
    area = float(np.mean([s.left.shape[0] * s.left.shape[1] for s in train]))
    full = 0 if base.segments is None else base.segments.n_segments
    segments = {b: tuning.crop_segments(full, args.crop * w, area) for b, (_, w) in enumerate(BUCKETS)}
    by_group = [{b: [s for s in g if bucket_of(s) == b] for b in range(len(BUCKETS))} for g in groups]
    counts = [np.array([len(by_bucket[b]) for b in range(len(BUCKETS))], float) for by_bucket in by_group]
    group_probs = [c / c.sum() for c in counts]
    # Adam; the --freeze keys get optax.set_to_zero() (multi_transform), so they never move
    optimizer = tuning.make_optimizer(args.lr, frozen=args.freeze)
    raw = tuning.to_unconstrained(base, temperature=args.temperature, searched=searched)
    opt_state = optimizer.init(raw)
    rng = np.random.default_rng(args.seed)
    log = {"train_scenes": [s.name for s in train], "val_scenes": [s.name for s in val],
           "loss": [], "val": [], "seconds": 0.0}
    step = 0
    if ckpt.exists():
        raw, opt_state, step, rng, log = tuning.load_checkpoint(ckpt, opt_state_like=opt_state)
        print(f"[{desc}] resumed at step {step}", flush=True)
    # Polyak (exponential moving) average of the raw iterates: the reported parameters
    ema = {k: np.asarray(v) for k, v in (log.get("ema") or raw).items()}

    def averaged():
        return {k: np.asarray(v, np.float32) for k, v in ema.items()}

    if step >= args.steps:
        log["temperature"] = float(tuning.from_unconstrained(averaged(), base=base)[1])
        return tuning.raw_to_params(averaged(), base), log
    # fixed validation crops (own RNG, so resuming does not change them)
    vrng = np.random.default_rng(args.seed + 1000)
    vcrops = {}
    for b, (_, w) in enumerate(BUCKETS):
        pool = [s for s in val if bucket_of(s) == b]
        n = args.val_crops if b == 0 else max(1, args.val_crops // 4)
        vcrops[b] = tuning.random_crops(pool, vrng, batch=n, height=args.crop, width=w,
                                        min_valid=args.min_valid) if pool else None
    steps_fn = {b: tuning.make_update_step(optimizer, base=with_segments(base, segments[b]),
                                           ndisp=BUCKETS[b][0])
                for b in range(len(BUCKETS)) if any(g[b] for g in by_group)}

    def validate(at):
        value = crop_wta_bad2(tuning.raw_to_params(averaged(), base), vcrops, segments)
        log["val"].append([at, value])
        return value

    if step == 0 and not log["val"]:
        validate(0)
    bar = tqdm(total=args.steps, initial=step, desc=desc, unit="step")
    start = time.perf_counter()
    while step < args.steps:
        # one group (the scenes CV) draws no group index: the random stream of earlier runs
        g = int(rng.integers(len(groups))) if len(groups) > 1 else 0
        b = int(rng.choice(len(BUCKETS), p=group_probs[g]))
        batch = tuning.random_crops(by_group[g][b], rng, batch=args.batch, height=args.crop,
                                    width=BUCKETS[b][1], min_valid=args.min_valid)
        raw, opt_state, value = steps_fn[b](raw, opt_state, batch)
        step += 1
        ema = {k: args.ema * ema[k] + (1 - args.ema) * np.asarray(raw[k]) for k in ema}
        log["ema"] = {k: v.tolist() for k, v in ema.items()}
        log["loss"].append([step, float(value), b])
        bar.update(1)
        bar.set_postfix(loss=f"{float(value):.3f}")
        if step % args.val_every == 0 or step == args.steps:
            v = validate(step)
            bar.write(f"[{desc}] step {step} crop WTA bad2.0 {v:.2f}%")
        if step % args.checkpoint_every == 0 or step == args.steps:
            log["seconds"] += time.perf_counter() - start
            start = time.perf_counter()
            tuning.save_checkpoint(ckpt, raw=raw, opt_state=opt_state, step=step, rng=rng, extra=log)
            write_json(log_path, log)
    bar.close()
    params = tuning.raw_to_params(averaged(), base)
    _, temperature = tuning.from_unconstrained(averaged(), base=base)
    log["temperature"] = float(temperature)
    write_json(log_path, log)
    return params, log


def evaluate(params, scenes, path: Path, desc, *, scoring=MIDDEVAL3_SCORING):
    """Per-scene metrics of the full WTA pipeline (cached in ``path``)."""
    if path.exists():
        return json.loads(path.read_text())
    method = lambda l, r, n: sswjax.match(l, r, n, params=params)  # noqa: E731
    print(f"evaluating {desc} on {len(scenes)} scenes", flush=True)
    results = evaluate_scenes(method, scenes, progress=True, scoring=scoring)
    data = {r.scene: r.metrics for r in results}
    write_json(path, data)
    return data


def base_params(args):
    """The starting parameters and the searched fields of ``--pipeline``."""
    if args.pipeline == "paper":
        return load_params(args.init), tuning.SEARCHED
    return sswjax.preset(args.pipeline), tuning.SGM_SEARCHED


def run_dataset_cv(args, base, searched, t0):
    """Leave-one-dataset-out: search on crops of the other sets, run the full pipeline on the
    held-out set with the searched and with the starting parameters; ``results.json``."""
    sets = {}
    for folder in args.datasets:
        layout = detect_layout(folder)
        raw_scenes = load_scenes(folder, layout=layout)
        sets[layout.name] = (raw_scenes, SCORINGS[layout.scoring])
    names = list(sets)
    largest = BUCKETS[-1][0]
    prepared, dropped = {}, {}
    for name, (raw_scenes, _) in sets.items():
        prepared[name] = [tuning.prepare_scene(s, channels=3) for s in raw_scenes if s.ndisp <= largest]
        dropped[name] = [s.name for s in raw_scenes if s.ndisp > largest]
    print("data sets:", {n: len(p) for n, p in prepared.items()}, "not searched on (ndisp > "
          f"{largest}):", dropped, flush=True)
    results = {"pipeline": args.pipeline, "searched_fields": list(searched),
               "not_searched_on": dropped, "folds": []}
    for held, others in tuning.dataset_folds(names):
        out = args.out / f"fold-{held}"
        params, log = run_search([prepared[n] for n in others], prepared[held], out, base, args,
                                 f"held out {held}", searched=searched)
        save_params(out / "params.json", params)
        raw_scenes, scoring = sets[held]
        searched_eval = evaluate(params, raw_scenes, args.out / f"eval_{held}_searched.json",
                                 f"searched without {held}", scoring=scoring)
        base_eval = evaluate(base, raw_scenes, args.out / f"eval_{held}_{args.pipeline}.json",
                             f"{args.pipeline} on {held}", scoring=scoring)
        results["folds"].append({
            "held_out": held, "trained_on": others,
            "params": {k: float(tuning.value_of(params, k)) for k in searched},
            "start": {k: float(tuning.value_of(base, k)) for k in searched},
            "temperature": log.get("temperature"),
            "search_seconds": log.get("seconds"),
            "searched": summarise(searched_eval, scoring),
            args.pipeline: summarise(base_eval, scoring),
        })
        write_json(args.out / "results.json", results)
    if not args.no_final:
        params, _ = run_search([prepared[n] for n in names], [s for n in names for s in prepared[n]],
                               args.out / "final", base, args, "final (all sets)", searched=searched)
        save_params(args.out / "final" / "params.json", params)
        results["final_params"] = {k: float(tuning.value_of(params, k)) for k in searched}
    results["seconds"] = time.perf_counter() - t0
    write_json(args.out / "results.json", results)
    with atomic_output(args.out / "results.md") as tmp:
        Path(tmp).write_text(results_markdown(results))
    print(json.dumps(results["folds"], indent=1), flush=True)
    return results


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add = parser.add_argument
    add("--out", type=Path, default=ROOT / "runs" / "main")
    add("--steps", type=int, default=150, help="optimizer steps per search")
    add("--batch", type=int, default=2, help="crops per step")
    add("--crop", type=int, default=64, help="crop height (widths per bucket)")
    add("--folds", type=folds_option, default=3, help="number of leave-scenes-out folds of "
        "trainingQ, or 'datasets': leave one data set of --datasets out")
    add("--pipeline", choices=("paper", "accurate"), default="paper",
        help="paper: aggregated cost -> soft-argmin, searching the weights, truncations, segment "
             "weight (from --init); accurate: the accurate preset, through its SGM optimiser, "
             f"searching the truncations and the penalties ({', '.join(tuning.SGM_SEARCHED)})")
    add("--datasets", type=Path, nargs="+", default=DATASETS,
        help="data folders of --folds datasets (any layout)")
    add("--min-valid", type=float, default=0.0, help="share of valid ground-truth pixels a crop "
        "needs (redrawn until it has it; for sparse ground truth such as KITTI's)")
    add("--seed", type=int, default=0)
    add("--lr", type=float, default=0.02)
    add("--ema", type=float, default=0.95,
        help="decay of the moving average of the iterates (the result); 0 = last")
    add("--temperature", type=float, default=None, help="initial soft-argmin temperature "
        "(default 0.02, times the paths with an SGM optimiser: its volume sums them)")
    add("--freeze", nargs="*", default=[], type=freeze_key, choices=tuning.all_raw_keys(),
        metavar="KEY", help="raw variables kept at their initial value, one of %(choices)s (old "
        "names such as weight_logits or sgm_p2 too): optax.set_to_zero() for them, Adam for the "
        "rest (sswjax.search.make_optimizer)")
    add("--val-every", type=int, default=25)
    add("--val-crops", type=int, default=4)
    add("--checkpoint-every", type=int, default=10)
    add("--init", type=Path, default=ROOT / "params" / "hand.json")
    add("--no-final", action="store_true", help="skip the search on all scenes")
    add("--write-tuned", type=Path, default=ROOT / "params" / "tuned.json")
    add("--resume", action="store_true",
        help="continue an existing --out (otherwise it must not hold a run)")
    args = parser.parse_args(argv)
    # every check before anything is written
    if (args.out / "config.json").exists() and not args.resume:
        parser.error(f"{args.out} holds a run; pass --resume to continue it")
    if args.pipeline != "paper" and args.folds != "datasets":
        parser.error(f"--pipeline {args.pipeline} needs --folds datasets")
    if not 0 <= args.min_valid < 1:
        parser.error(f"--min-valid must be in [0, 1), got {args.min_valid}")
    base, searched = base_params(args)
    unknown = sorted(set(args.freeze) - set(tuning.raw_keys(searched)))
    if unknown:
        parser.error(f"--freeze {' '.join(unknown)}: not searched with --pipeline {args.pipeline}")
    if args.temperature is None:
        args.temperature = 0.02 * (base.optimizer.paths if base.optimizer is not None else 1)
    args.out.mkdir(parents=True, exist_ok=True)
    command = "python tuning/search.py " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:]))
    config = {k: str(v) if isinstance(v, Path) else [str(p) for p in v] if k == "datasets" else v
              for k, v in vars(args).items()}
    config["command"] = command
    if not (args.out / "config.json").exists():
        write_json(args.out / "config.json", config)
    t0 = time.perf_counter()
    if args.folds == "datasets":
        run_dataset_cv(args, base, searched, t0)
        plot_run(args.out, args.out / "curves.png")
        print(f"total {time.perf_counter() - t0:.0f} s", flush=True)
        return
    hand = base
    root = find_data_root()
    raw_scenes = load_middeval3(root)
    scenes = [tuning.prepare_scene(s) for s in raw_scenes]
    names = [s.name for s in scenes]
    order = np.random.default_rng(args.seed).permutation(len(scenes))
    folds = [sorted(names[i] for i in order[k::args.folds]) for k in range(args.folds)]
    print("folds:", folds, flush=True)

    hand_eval = evaluate(hand, raw_scenes, args.out / "eval_hand.json", "hand")
    searched_eval, fold_params = {}, []
    for k, held in enumerate(folds):
        train = [s for s in scenes if s.name not in held]
        val = [s for s in scenes if s.name in held]
        params, _ = run_search(train, val, args.out / f"fold{k}", hand, args, f"fold {k}")
        save_params(args.out / f"fold{k}" / "params.json", params)
        fold_params.append(params.to_dict())
        held_raw = [s for s in raw_scenes if s.name in held]
        searched_eval.update(evaluate(params, held_raw, args.out / f"eval_fold{k}.json", f"fold {k}"))
    cv = {"folds": folds, "hand": weighted({s: hand_eval[s] for s in searched_eval}),
          "searched": weighted(searched_eval), "fold_params": fold_params,
          "per_scene_bad2_nonocc": {s: [hand_eval[s]["nonocc"]["bad2.0"], searched_eval[s]["nonocc"]["bad2.0"]]
                                     for s in searched_eval}}
    write_json(args.out / "results.json", cv)
    print(json.dumps({"hand": cv["hand"], "searched": cv["searched"]}, indent=1), flush=True)

    if not args.no_final:
        params, log = run_search(scenes, scenes, args.out / "final", hand, args, "final")
        final_eval = evaluate(params, raw_scenes, args.out / "eval_final.json", "final (all scenes)")
        cv["final_full_trainingQ"] = weighted(final_eval)
        cv["hand_full_trainingQ"] = weighted(hand_eval)
        cv["seconds"] = time.perf_counter() - t0 + 0.0
        write_json(args.out / "results.json", cv)
        bad2 = {c: {r: cv[c][r]["bad2.0"] for r in ("nonocc", "all")}
                for c in ("hand", "searched", "final_full_trainingQ")}
        provenance = {
            "how": "optax adam search (moving average of the iterates) of the continuous "
                   "parameters through soft-argmin on random crops (sswjax.search, "
                   "tuning/search.py), from hand.json; static options, segments.compactness and "
                   "checks.tolerance kept as in hand.json",
            "data": f"MiddEval3 trainingQ, 15 scenes ({root})", "seed": args.seed,
            "command": command, "date": DATE, "soft_argmin_temperature": log.get("temperature"),
            "cv_folds": folds,
            **{f"cv_heldout_weighted_bad2_{r}": {c: bad2[c][r] for c in ("hand", "searched")}
               for r in ("nonocc", "all")},
            "full_trainingQ_weighted_bad2": bad2["final_full_trainingQ"],
        }
        save_params(args.write_tuned, params, provenance=provenance)
        print(f"wrote {args.write_tuned}", flush=True)
    plot_run(args.out, args.out / "curves.png")
    print(f"total {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
