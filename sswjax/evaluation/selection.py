"""The held-out rule that chose the presets' values: among configurations scored on several
data sets, the one with the lowest mean error relative to the best, chosen on every set but
one and scored on that one.

*errors* are ``{configuration: {criterion: error}}``, lower better (bad-pixel percentages),
every configuration scored on every criterion used. A criterion is one number of one data
set: its bad 2.0 (``"KITTI2012"``), or one threshold of it (``"KITTI2012 bad1.0"``) when a
stage's purpose is sub-pixel precision. A configuration's relative error on a criterion is its
error divided by the lowest any configuration has there, so that every criterion weighs alike
whatever its scale; the rule (:func:`choose`) takes the lowest mean of those.

Leaving one data set out (:func:`held_out_choices`, *groups* ``{data set: [its criteria]}``)
chooses on the other sets' criteria and reports the choice's errors on the set held out,
beside the best choice there: what a user on a new kind of scene should expect, and what was
possible. (:mod:`sswjax.search.held_out` holds the search's own folds, over scenes rather than
over scored configurations.)

>>> errors = {"a": {"K": 10.0, "M": 2.0}, "b": {"K": 11.0, "M": 1.0}}
>>> choose(errors, ["K", "M"])
'b'
>>> [(fold.held_out, fold.chosen, fold.best) for fold in held_out_choices(
...     errors, {"K": ["K"], "M": ["M"]})]
[('K', 'b', 'a'), ('M', 'a', 'b')]
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import NamedTuple

__all__ = ["HeldOutChoice", "choose", "held_out_choices", "relative_errors"]

Errors = Mapping[str, Mapping[str, float]]


class HeldOutChoice(NamedTuple):
    """One fold of :func:`held_out_choices`.

    Attributes
    ----------
    held_out : str
        The data set left out of the choice.
    chosen : str
        The configuration chosen on the other sets' criteria.
    errors : dict
        The chosen configuration's errors on the held-out set's criteria.
    best : str
        The configuration the rule chooses on the held-out set's own criteria.
    best_errors : dict
        Its errors there: what was possible.
    """

    held_out: str
    chosen: str
    errors: dict[str, float]
    best: str
    best_errors: dict[str, float]


def relative_errors(errors: Errors, criteria: Iterable[str]) -> dict[str, float]:
    """Each configuration's mean over ``criteria`` of its error divided by the lowest error
    any configuration has on that criterion (1.0: the best on every one).

    Raises ``ValueError`` for no configuration, no criterion, a configuration without an
    error for a criterion, a negative or non-finite error, or a criterion whose lowest error
    is 0 (nothing to divide by).
    """
    criteria = list(criteria)
    if not errors:
        raise ValueError("no configuration to choose from")
    if not criteria:
        raise ValueError("no criterion to choose on")
    for config, values in errors.items():
        for criterion in criteria:
            if criterion not in values:
                raise ValueError(f"configuration {config!r} has no error for {criterion!r}")
            value = float(values[criterion])
            if not math.isfinite(value):
                raise ValueError(f"configuration {config!r} has a non-finite error for "
                                 f"{criterion!r}: {value}")
            if value < 0:
                raise ValueError(f"configuration {config!r} has a negative error for "
                                 f"{criterion!r}: {value}")
    best = {criterion: min(float(values[criterion]) for values in errors.values())
            for criterion in criteria}
    for criterion, lowest in best.items():
        if lowest == 0:
            raise ValueError(f"the lowest error on {criterion!r} is 0: errors relative to it "
                             "are undefined")
    return {config: sum(float(values[c]) / best[c] for c in criteria) / len(criteria)
            for config, values in errors.items()}


def choose(errors: Errors, criteria: Iterable[str]) -> str:
    """The configuration with the lowest :func:`relative_errors` over ``criteria`` (the first
    in ``errors``' order among equals)."""
    scores = relative_errors(errors, criteria)
    return min(scores, key=scores.__getitem__)


def held_out_choices(errors: Errors, groups: Mapping[str, Sequence[str]]) -> list[HeldOutChoice]:
    """Leave each data set of ``groups`` out in turn: the choice on the others' criteria, its
    errors on the held-out set's, and the best choice there; one :class:`HeldOutChoice` per
    set, in ``groups``' order.

    ``groups`` maps a data set to its criteria (keys of every configuration's errors): two sets
    or more, each with a criterion or more, no criterion in two sets.
    """
    if len(groups) < 2:
        raise ValueError("leaving one data set out needs two data sets or more")
    owner: dict[str, str] = {}
    for name, criteria in groups.items():
        if not criteria:
            raise ValueError(f"data set {name!r} has no criterion")
        for criterion in criteria:
            if criterion in owner:
                raise ValueError(f"criterion {criterion!r} is in two data sets: "
                                 f"{owner[criterion]!r} and {name!r}")
            owner[criterion] = name
    folds = []
    for held, criteria in groups.items():
        chosen = choose(errors, [c for c in owner if owner[c] != held])
        best = choose(errors, criteria)
        folds.append(HeldOutChoice(
            held, chosen, {c: float(errors[chosen][c]) for c in criteria},
            best, {c: float(errors[best][c]) for c in criteria}))
    return folds
