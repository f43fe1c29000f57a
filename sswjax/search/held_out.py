"""A search run with its held-out report: folds, each fold's search and scores, the final
search on everything.

A run (:func:`search_with_report`) takes named data sets of scenes with ground truth. Its
folds (:func:`folds`): ``"datasets"`` holds each data set out in turn (the search sees the
others), ``"scenes"`` each scene (the search sees every other scene, grouped by set),
``"none"`` skips the report. Each fold's searched parameters and the base ones run on the
held-out scenes with the full pipeline and are scored as ``sswjax evaluate`` scores their
layout (:data:`sswjax.evaluation.runner.SCORINGS`). Then one search on every scene gives the
run's result. A run folder holds ``fold-<name>/`` and ``final/`` (the starts' checkpoints),
``eval-<fold>-{searched,base}.json`` (per-scene metrics) and ``report.json``; every file is
written atomically and a finished part is read back, never recomputed.
"""

from __future__ import annotations

import json
from pathlib import Path

from sswjax._files import write_json
from sswjax.api.match import match
from sswjax.config import Params
from sswjax.evaluation.runner import SCORINGS, evaluate_scenes, summary
from sswjax.search.grid import grid_options
from sswjax.search.run import SearchResult, run_search, searched_options
from sswjax.search.settings import SearchSettings
from sswjax.search.space import value_of

__all__ = ["FOLD_MODES", "folds", "report_markdown", "search_with_report"]

FOLD_MODES = ("datasets", "scenes", "none")


def folds(sets: dict, mode: str) -> list[tuple[str, dict, dict]]:
    """``[(fold name, {set: training scenes}, {set: held-out scenes})]`` for ``mode``.

    ``sets`` maps a data set's name to ``(scenes, scoring name)``; ``"datasets"`` needs two
    sets or more, ``"scenes"`` two scenes or more.
    """
    if mode not in FOLD_MODES:
        raise ValueError(f"held-out mode must be one of {FOLD_MODES}, got {mode!r}")
    if mode == "none":
        return []
    if mode == "datasets":
        if len(sets) < 2:
            raise ValueError("leaving one data set out needs two data sets or more")
        return [(held, {n: s for n, (s, _) in sets.items() if n != held}, {held: sets[held][0]})
                for held in sets]
    every = [(n, s) for n, (scenes, _) in sets.items() for s in scenes]
    if len(every) < 2:
        raise ValueError("leaving one scene out needs two scenes or more")
    out = []
    for name, held in every:
        train = {n: [s for s in scenes if (n, s.name) != (name, held.name)]
                 for n, (scenes, _) in sets.items()}
        out.append((f"{name}-{held.name}" if len(sets) > 1 else held.name,
                    {n: s for n, s in train.items() if s}, {name: [held]}))
    return out


def _scores(params: Params, held: dict, sets: dict, path: Path) -> dict:
    """``{set: {region: {metric: value}}}`` of ``params`` on the held-out scenes (cached)."""
    if path.exists():
        return json.loads(path.read_text())
    out = {}
    for name, scenes in held.items():
        scoring = SCORINGS[sets[name][1]]
        method = lambda l, r, n: match(l, r, n, params=params)  # noqa: E731
        results = evaluate_scenes(method, scenes, scoring=scoring)
        out[name] = summary(results, scoring=scoring)
    write_json(path, out)
    return out


def search_with_report(sets: dict, base: Params, settings: SearchSettings, *, folder,
                       mode: str, progress: bool = True, interrupted=None
                       ) -> tuple[SearchResult, dict]:
    """Run the folds of ``mode`` and the final search; return the final result and the report.

    Parameters
    ----------
    sets : dict
        Data set name -> ``(scenes, scoring name)``, scenes with ground truth.
    base : Params
    settings : SearchSettings
    folder : path
        The run folder (created; a finished part in it is reused).
    mode : str
        One of :data:`FOLD_MODES`.
    interrupted : callable, optional
        ``() -> bool``, asked after every step (:func:`sswjax.search.run.run_search`).

    Returns
    -------
    SearchResult, dict
        The final search, and ``{"folds": [...], "final": {...}}`` (also ``report.json``).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cache: dict = {}
    options = searched_options(base)
    grid = tuple(p for p, _ in grid_options(base))
    moved = options + grid
    report = {"searched": list(options), "grid": list(grid), "mode": mode, "folds": []}
    for name, train, held in folds(sets, mode):
        result = run_search(list(train.values()), base, settings, folder=folder / f"fold-{name}",
                            desc=f"without {name}", progress=progress, steps_cache=cache,
                            interrupted=interrupted)
        report["folds"].append({
            "held_out": name, "trained_on": sorted(train),
            "params": {k: float(value_of(result.params, k)) for k in moved},
            "starts": result.starts, "grid": result.grid_trials,
            "searched": _scores(result.params, held, sets, folder / f"eval-{name}-searched.json"),
            "base": _scores(base, held, sets, folder / f"eval-{name}-base.json"),
        })
        write_json(folder / "report.json", report)
    final = run_search([scenes for scenes, _ in sets.values()], base, settings,
                       folder=folder / "final", desc="all scenes", progress=progress,
                       steps_cache=cache, interrupted=interrupted)
    report["final"] = {"params": {k: float(value_of(final.params, k)) for k in moved},
                       "start": {k: float(value_of(base, k)) for k in moved},
                       "validation": final.validation, "start_validation": final.start_validation,
                       "starts": final.starts, "grid": final.grid_trials}
    write_json(folder / "report.json", report)
    return final, report


def report_markdown(report: dict) -> str:
    """The held-out table of a report: per fold and set, bad 2.0 / 1.0 / 0.5 of the base and
    the searched parameters (first region: ``nonocc`` where the set has it)."""
    lines = ["| held out | set | region | base 2.0 / 1.0 / 0.5 | searched 2.0 / 1.0 / 0.5 |",
             "|---|---|---|---|---|"]
    for fold in report["folds"]:
        for name, regions in fold["base"].items():
            for region, base in regions.items():
                searched = fold["searched"][name][region]
                cells = [" / ".join(f"{m[k]:.2f}" for k in ("bad2.0", "bad1.0", "bad0.5"))
                         for m in (base, searched)]
                lines.append(f"| {fold['held_out']} | {name} | {region} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines)
