"""The grid around the continuous search: options without a gradient, tried on whole images.

The occlusion tests' gaps, the left-right tolerance, the fill's vote tolerance and intensity
scale, the smoothing's gate: none of them is on the soft path the gradient follows (they act
after the winner-takes-all), and the gaps are static. Each declares a grid step where it is
declared (``Option.grid`` in :mod:`sswjax.config`). :func:`grid_search` is one pass of
coordinate descent over them: for each option in turn, the value one step below and one step
above (kept within its bounds and only where the configuration accepts it), scored by the mean
whole-image bad 2.0 on the validation scenes (:func:`sswjax.search.run.validation_error`); a
value is kept only when it lowers that error. A static option's new value compiles the graph
once per image shape.
"""

from __future__ import annotations

from sswjax.config import ConfigError, Params, check_params
from sswjax.config.fields import option_fields
from sswjax.search.space import value_of

__all__ = ["grid_options", "grid_search"]


def grid_options(params: Params) -> tuple[tuple[str, float], ...]:
    """``((path, step), ...)`` of the options of ``params``' stages that declare a grid step.

    >>> import sswjax
    >>> dict(grid_options(sswjax.preset("accurate")))["fill.tolerance"]
    1.0
    """
    return tuple((f"{slot}.{name}", spec.grid) for slot, config in params.stages()
                 if config is not None for name, spec in option_fields(config)
                 if spec.grid is not None)


def _neighbours(params: Params, path: str, step: float) -> list[Params]:
    """``params`` with ``path`` one ``step`` lower and one higher, where valid."""
    value = value_of(params, path)
    out = []
    for candidate in (value - step, value + step):
        candidate = type(value)(round(candidate, 6))
        try:
            out.append(check_params(params.replace(**{path: candidate})))
        except ConfigError:
            continue
    return out


def grid_search(params: Params, error, *, start_error: float | None = None, log=None,
                progress=None) -> tuple[Params, float, list]:
    """One pass of coordinate descent over :func:`grid_options`.

    Parameters
    ----------
    params : Params
        The start (the continuous search's result).
    error : callable
        ``Params -> float``, lower = better (the validation error).
    start_error : float, optional
        ``error(params)``, when known.
    log : list, optional
        The trials of an interrupted pass (``[path, value, error]`` rows), replayed instead of
        measured again.
    progress : callable, optional
        ``(trials) -> None``, called after every trial (e.g. to save ``trials``).

    Returns
    -------
    (Params, float, list)
        The best parameters, their error, and every trial.
    """
    trials = list(log or [])
    known = {(path, repr(value)): e for path, value, e in trials}
    best = params
    best_error = error(params) if start_error is None else start_error
    for path, step in grid_options(params):
        for candidate in _neighbours(best, path, step):
            value = value_of(candidate, path)
            key = (path, repr(value))
            if key not in known:
                known[key] = error(candidate)
                trials.append([path, value, known[key]])
                if progress is not None:
                    progress(trials)
            if known[key] < best_error:
                best, best_error = candidate, known[key]
    return best, best_error, trials
