"""The search loop: Adam on random crops, validated on whole images, restarted, resumable.

One search (:func:`run_search`) takes groups of training scenes (one group per data set, so
that every step first draws a set uniformly and no set outweighs the others by its number of
scenes) and the base parameters, and runs ``settings.restarts`` starts. Each start:

1. draws a batch of crops per step (a set, then a disparity bucket of it in proportion to its
   scenes, then crops; :func:`sswjax.search.random_crops`) and takes one Adam step on the
   surrogate (:func:`sswjax.search.make_update_step`);
2. keeps a moving average of the iterates, and every ``val_every`` steps runs the *whole*
   pipeline (:func:`sswjax.match`) on up to ``val_images`` whole training images with it,
   scoring the mean bad 2.0 (the start itself is validated at step 0);
3. stops after ``patience`` validations without improvement, and returns the best validated
   point, so a search never returns parameters that validated worse than its start.

Of the starts, the one with the lowest validated error wins; then (``settings.grid``) one pass
of the grid over the options without a gradient (:mod:`sswjax.search.grid`) on the same
validation images. Each start keeps a checkpoint
(raw variables, optimizer state, random stream, log; atomically written) in its own folder, so
an interrupted search resumes where it stopped and a finished start is never run again.

Scenes are :class:`sswjax.data.layouts.StereoScene` as loaded (uint8 or float images, float32
ground truth with non-finite = unknown).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import numpy as np
from tqdm import tqdm

from sswjax._files import write_json
from sswjax.api.match import match
from sswjax.config import ConfigError, Params, check_params
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.search.checkpoints import load_checkpoint, save_checkpoint
from sswjax.search.crops import crop_segments, prepare_scene, random_crops
from sswjax.search.grid import grid_options, grid_search
from sswjax.search.settings import SearchSettings
from sswjax.search.space import raw_to_params, searchable, to_unconstrained, value_of
from sswjax.search.step import make_optimizer, make_update_step

__all__ = ["SearchResult", "run_search", "searched_options", "validation_error"]

VALIDATION_BUCKETS = ShapeBuckets(size_step=64, ndisp_step=32)
"""Shape buckets of the validation runs: few compilations over images of many sizes."""


class SearchResult(NamedTuple):
    """What :func:`run_search` returns.

    Attributes
    ----------
    params : Params
        The best validated parameters over all starts.
    validation : float
        Their mean bad 2.0 (%) on the validation images.
    start_validation : float
        The base parameters' mean bad 2.0 (%) there.
    starts : list of dict
        Per start: ``{"best_step", "best", "steps", "stopped_early"}``.
    grid_trials : list
        The grid's trials after the continuous search, ``[path, value, error]``
        (:mod:`sswjax.search.grid`; empty without ``settings.grid``).
    """

    params: Params
    validation: float
    start_validation: float
    starts: list
    grid_trials: list


def searched_options(base: Params) -> tuple[str, ...]:
    """The options a search of ``base`` moves: every option of its stages that declares a
    search transform (``Option.search``) and acts in this pipeline (a changed value passes
    :func:`~sswjax.config.check_params`: ``aggregation.segment_weight`` does not without
    superpixels), except the cost weights when the pipeline has a semi-global optimiser
    (searching them there overfits the colour term: tuning/README)."""
    def acts(option):
        try:
            check_params(base.replace(**{option: float(value_of(base, option)) * 1.1}))
        except ConfigError:
            return False
        return True

    options = tuple(o for o in searchable(base) if acts(o))
    if base.optimizer is not None:
        options = tuple(o for o in options if not (o.startswith("cost.") and o.endswith("_weight")))
    return options


def validation_error(params: Params, scenes) -> float:
    """Mean over ``scenes`` of the whole-image bad 2.0 (%, every pixel with ground truth in
    the scene's range, non-occluded where the scene has a mask) of :func:`sswjax.match`."""
    errors = []
    for s in scenes:
        d = match(s.left, s.right, s.ndisp, params=params, buckets=VALIDATION_BUCKETS)
        metrics = evaluate_disparity(d, s.ground_truth, mask=s.mask, ndisp=s.ndisp,
                                     thresholds=(2.0,))
        errors.append(metrics["nonocc" if "nonocc" in metrics else "all"]["bad2.0"])
    return float(np.mean(errors))


def _buckets(scenes, settings: SearchSettings):
    """``{padded ndisp: [prepared scenes]}`` of the scenes the crops fit in."""
    out = {}
    for s in scenes:
        nd = -(-s.ndisp // settings.ndisp_step) * settings.ndisp_step
        h, w = s.left.shape[:2]
        if nd <= settings.max_ndisp and h >= settings.crop_height and w >= nd + settings.crop_context:
            out.setdefault(nd, []).append(s)
    return dict(sorted(out.items()))


def _validation_scenes(groups, settings: SearchSettings):
    """Up to ``val_images`` whole training scenes, taken in turn from each group (seeded)."""
    rng = np.random.default_rng(settings.seed + 7919)
    pools = [list(rng.permutation(len(g))) for g in groups]
    chosen = []
    while len(chosen) < settings.val_images and any(pools):
        for g, pool in zip(groups, pools):
            if pool and len(chosen) < settings.val_images:
                chosen.append(g[pool.pop(0)])
    return chosen


def _perturbed(base: Params, options, rng, spread: float) -> Params:
    return base.replace(**{k: float(value_of(base, k)) * float(np.exp(rng.uniform(-spread, spread)))
                           for k in options})


def run_search(groups, base: Params, settings: SearchSettings, *, folder, desc: str = "search",
               progress: bool = True, steps_cache: dict | None = None,
               interrupted=None) -> SearchResult:
    """Search ``base``'s continuous options (:func:`searched_options`) on crops of ``groups``.

    Parameters
    ----------
    groups : list of list of StereoScene
        The training scenes, one list per data set; scenes without ground truth are not
        passed here (the callers check).
    base : Params
        The start, and the values of everything not searched.
    settings : SearchSettings
    folder : path
        Where the starts keep ``start-<k>/checkpoint.pkl`` and ``log.json``.
    desc : str
        The progress bar's label.
    steps_cache : dict, optional
        Compiled update steps by ``(ndisp, crop width)``, shared between searches of one
        ``base`` structure and ``settings`` (e.g. the folds and the final search of a run).
    interrupted : callable, optional
        ``() -> bool``, asked after every step: when true, the start saves its checkpoint and
        ``KeyboardInterrupt`` is raised, so a resumed search continues from that very step.
        (A SIGINT raised by Python's own handler may land in a garbage-collection callback
        of JAX and be lost; the command line's handler sets a flag instead.)

    Returns
    -------
    SearchResult
    """
    folder = Path(folder)
    options = searched_options(base)
    prepared = [[prepare_scene(s, channels=3) for s in g] for g in groups]
    by_group = [_buckets(g, settings) for g in prepared]
    if not any(by_group):
        raise ValueError(f"no training scene is large enough for a {settings.crop_height}-row "
                         f"crop of its range plus {settings.crop_context} columns")
    validation = _validation_scenes(groups, settings)
    folder.mkdir(parents=True, exist_ok=True)
    start_path = folder / "start.json"  # the base's validation, kept for a resumed run
    if start_path.exists():
        start_validation = json.loads(start_path.read_text())["validation_bad2"]
    else:
        start_validation = validation_error(base, validation)
        write_json(start_path, {"validation_bad2": start_validation,
                                "images": [s.name for s in validation]})
    temperature = settings.temperature or 0.02 * (base.optimizer.paths if base.optimizer else 1)
    optimizer = make_optimizer(settings.lr, frozen=settings.frozen)
    steps_cache = {} if steps_cache is None else steps_cache
    area = float(np.mean([s.left.shape[0] * s.left.shape[1] for g in prepared for s in g]))
    full_segments = 0 if base.segments is None else base.segments.n_segments

    def step_fn(nd: int):
        width = nd + settings.crop_context
        if (nd, width) not in steps_cache:
            segments = crop_segments(full_segments, settings.crop_height * width, area)
            b = base if base.segments is None else base.replace(
                **{"segments.n_segments": segments})
            steps_cache[(nd, width)] = make_update_step(optimizer, base=b, ndisp=nd,
                                                        surrogate=settings.surrogate)
        return steps_cache[(nd, width)]

    starts, best = [], None
    for k in range(settings.restarts):
        start_rng = np.random.default_rng([settings.seed, k])
        start = base if k == 0 else _perturbed(base, options, start_rng, settings.restart_spread)
        raw = to_unconstrained(start, temperature=temperature, searched=options)
        outcome = _run_start(raw, optimizer, by_group, validation, base, settings, step_fn,
                             folder=folder / f"start-{k}", desc=f"{desc} start {k + 1}/"
                             f"{settings.restarts}", progress=progress, rng=start_rng,
                             start_error=start_validation if k == 0 else None,
                             interrupted=interrupted or (lambda: False))
        starts.append({key: outcome[key] for key in ("best_step", "best", "steps",
                                                     "stopped_early")})
        if best is None or outcome["best"] < best["best"]:
            best = outcome
    params = raw_to_params({key: np.asarray(v, np.float32) for key, v in best["best_raw"].items()},
                           base)
    error, trials = best["best"], []
    if settings.grid:
        params, error, trials = _grid_phase(params, error, validation, folder / "grid.json",
                                            interrupted or (lambda: False),
                                            desc=f"{desc} grid", progress=progress)
    return SearchResult(params, error, start_validation, starts, trials)


def _grid_phase(params, error, validation, path: Path, interrupted, *, desc, progress):
    """:func:`sswjax.search.grid.grid_search` on the validation scenes, its trials kept in
    ``path`` after each one (a resumed run replays them); a bar over the trials (at most two
    per option)."""
    stored = json.loads(path.read_text()) if path.exists() else {"trials": []}
    bar = tqdm(total=2 * len(grid_options(params)), initial=len(stored["trials"]), desc=desc,
               unit="trial", disable=not progress)

    def keep(trials):
        write_json(path, {"trials": trials})
        bar.update(len(trials) - bar.n)
        if interrupted():
            bar.close()
            raise KeyboardInterrupt

    try:
        return grid_search(params, lambda p: validation_error(p, validation), start_error=error,
                           log=stored["trials"], progress=keep)
    finally:
        bar.close()


def _run_start(raw, optimizer, by_group, validation, base, settings, step_fn, *, folder, desc,
               progress, rng, start_error, interrupted):
    """One start of :func:`run_search`; its log (with ``best_raw``) once finished."""
    folder.mkdir(parents=True, exist_ok=True)
    ckpt, log_path = folder / "checkpoint.pkl", folder / "log.json"
    opt_state = optimizer.init(raw)
    step = 0
    log = {"loss": [], "val": [], "since_best": 0, "stopped_early": False, "done": False}
    if ckpt.exists():
        raw, opt_state, step, rng, log = load_checkpoint(ckpt, opt_state_like=opt_state)
        if log["done"]:
            return log
    if not log["val"]:
        error = start_error if start_error is not None else validation_error(
            raw_to_params(raw, base), validation)
        log.update(val=[[0, error]], best=error, best_step=0, steps=0,
                   best_raw={key: np.asarray(v).tolist() for key, v in raw.items()},
                   ema={key: np.asarray(v).tolist() for key, v in raw.items()})
    ema = {key: np.asarray(v, np.float64) for key, v in log["ema"].items()}
    probs = [np.array([len(b[nd]) for nd in b], float) for b in by_group]
    usable = [g for g, b in enumerate(by_group) if b]
    bar = tqdm(total=settings.steps, initial=step, desc=desc, unit="step", disable=not progress)
    while step < settings.steps and not log["stopped_early"]:
        g = usable[int(rng.integers(len(usable)))]
        nds = list(by_group[g])
        nd = nds[int(rng.choice(len(nds), p=probs[g] / probs[g].sum()))]
        batch = random_crops(by_group[g][nd], rng, batch=settings.batch,
                             height=settings.crop_height, width=nd + settings.crop_context,
                             min_valid=settings.min_valid)
        raw, opt_state, value = step_fn(nd)(raw, opt_state, batch)
        step += 1
        ema = {key: settings.ema * ema[key] + (1 - settings.ema) * np.asarray(raw[key])
               for key in ema}
        log["loss"].append([step, float(value), nd])
        log["ema"] = {key: v.tolist() for key, v in ema.items()}
        log["steps"] = step
        bar.update(1)
        bar.set_postfix(loss=f"{float(value):.4f}", best=f"{log['best']:.2f}")
        if step % settings.val_every == 0 or step == settings.steps:
            averaged = {key: np.asarray(v, np.float32) for key, v in ema.items()}
            error = validation_error(raw_to_params(averaged, base), validation)
            log["val"].append([step, error])
            if error < log["best"]:
                log.update(best=error, best_step=step, since_best=0,
                           best_raw={key: v.tolist() for key, v in averaged.items()})
            else:
                log["since_best"] += 1
                log["stopped_early"] = log["since_best"] >= settings.patience
        stop = interrupted()
        if (step % settings.checkpoint_every == 0 or step == settings.steps
                or log["stopped_early"] or stop):
            save_checkpoint(ckpt, raw=raw, opt_state=opt_state, step=step, rng=rng, extra=log)
        if stop:
            bar.close()
            raise KeyboardInterrupt
    bar.close()
    log["done"] = True
    save_checkpoint(ckpt, raw=raw, opt_state=opt_state, step=step, rng=rng, extra=log)
    write_json(log_path, {key: v for key, v in log.items() if key not in ("ema",)})
    return log
