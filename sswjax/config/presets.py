"""Named compositions of the stage configurations: the presets, and the default.

``paper`` is ``Params()``. The others were chosen by the static grids of ``docs/`` ("Beyond
the paper", "Speed") under the held-out rule of :mod:`sswjax.evaluation.selection` (lowest
mean error relative to the best, over MiddEval3 trainingQ, KITTI 2012 and Middlebury 2001;
``benchmarks/grid.py`` scores the rows and applies it): P1 and P2 of each
preset, the separable median's width and the side-window passes. Every semi-global preset stores
the aggregated cost in uint8 levels for the int16 paths (a quarter of float32's bytes through
the memory-bound scans; the same errors within 0.03 on every set) and runs the occlusion tests:
the uniqueness test on the costs before aggregation, the aggregated cost's right view and the
left band's fitted line. Every semi-global preset ends with the gated bilateral smoothing of
the map (two passes, gate 2 px, measured from the map's local slope), chosen on the three sets
by the same rule over bad 2.0, 1.0 and 0.5 (``docs/notes/precision.md``, ``docs/paper-parts.md``);
``accurate`` runs each pass as a row
then a column of the window, ``fast`` three such passes (the same errors within 0.05 at bad
2.0, 2-5x less time in the stage).
``balanced`` is ``accurate`` coarse-to-fine with the full-resolution band of 7 disparities
(``benchmarks/grid.py configs``, ``docs/notes/band.md``). ``fast`` fits its doubled map again on the
full-resolution cost, each plane over a 5 x 5 window (``coarse.refit_radius`` 2, chosen on the
three sets by the rule over bad 2.0, 1.0 and 0.5: ``benchmarks/grid.py refit``,
``docs/notes/precision.md``), and on the halved pair runs ``accurate``'s one side-window pass, the
penalties ``accurate`` had until 2026-12-06 (P1 0.2, P2 1.15, as ``balanced``) and a 7 x 7 fill
median, chosen with the refit by the same rule (``benchmarks/grid.py configs``,
``docs/notes/speed.md``). ``accurate``'s own penalties (P1 0.35, P2 2.4) were gridded again on the
finished pipeline; ``fast`` and ``balanced`` keep theirs by the rule
(``docs/notes/beyond-the-paper.md``). ``accurate`` first aligns the right image's rows to the left's
(the vertical offset measured on its method over the pair halved once, every pixel of that first
pass counting: chosen by the rule on bad 2.0 and over 2.0, 1.0 and 0.5, for about a third more
time), and so does ``balanced`` (its own first pass, chosen by the same rule, for about 45 %
more time); ``fast`` stays without it (half again its time for little at bad 2.0, measured on a
first pass or on its coarse pass, ``docs/notes/alignment.md``).
"""

from __future__ import annotations

from typing import NamedTuple

from sswjax.config.aggregation import SideWindowAggregation
from sswjax.config.alignment import VerticalAlignment
from sswjax.config.band import DisparityBand
from sswjax.config.checks import LeftRightCheck
from sswjax.config.coarse import CoarseToFine
from sswjax.config.fill import LeftBandFill, VoteFill, WeightedMedianFill
from sswjax.config.optimizer import SemiGlobal
from sswjax.config.params import Params
from sswjax.config.selection import WinnerTakesAll
from sswjax.config.smoothing import GatedBilateralSmoothing

__all__ = ["DEFAULT_PRESET", "PRESETS", "Preset", "default_params", "preset"]


class Preset(NamedTuple):
    """An entry of :data:`PRESETS`: the parameters and a one-line summary."""

    params: Params
    summary: str


_PAPER = Params()
_OCCLUSION_CHECKS = LeftRightCheck(uniqueness_gap=2, uniqueness_radius=2, aggregated_gap=2)
# The smoothing of the finished map: better than none at bad 2.0, 1.0 and 0.5 on every set.
# Its gate measured from the map's slope (tilted): chosen by the held-out rule over bad 2.0,
# 1.0 and 0.5 on the three sets for accurate, balanced and fast (docs/notes/precision.md, "A
# tilted gate").
_SMOOTHING = GatedBilateralSmoothing(gate=2.0, iterations=2, tilted=True)
_SEMI_GLOBAL = _PAPER.replace(
    segments=None,
    optimizer=SemiGlobal(paths=4, dtype="uint8", p1=0.12, p2=0.8),
    checks=_OCCLUSION_CHECKS,
    # fast's fill on its halved pair: a 7 x 7 separable median, chosen with its refit by the
    # held-out rule over radii 1 .. 7 (docs/notes/speed.md, "fast's fill on its halved pair").
    fill=LeftBandFill(median_radius=3, median="separable", band_fit=15),
    smoothing=_SMOOTHING,
    # Two lines instead of Eq. 8's parabola: less pixel locking on the semi-global sums, chosen
    # held out on the three sets for each preset (docs/notes/precision.md, docs/paper-parts.md).
    selection=WinnerTakesAll(fit="equiangular"),
)
# accurate: one side-window pass, the vote fill with a 19 x 19 separable median instead of
# three passes and the left-band fill; fast takes the pass.
_ONE_PASS = SideWindowAggregation(iterations=1)
# The penalties of fast's halved pair and of balanced: accurate's until 2026-12-06, kept by the
# held-out rule over 2.0, 1.0 and 0.5 against accurate's new ones (docs/notes/beyond-the-paper.md,
# "P1 and P2 on the finished pipeline").
_PATHS = SemiGlobal(paths=4, dtype="uint8", p1=0.2, p2=1.15)
# accurate's penalties, gridded again after the smoothing, its tilt and the vote fill: chosen
# by the held-out rule on bad 2.0 and over 2.0, 1.0 and 0.5 (docs/notes/beyond-the-paper.md).
_ACCURATE_PATHS = SemiGlobal(paths=4, dtype="uint8", p1=0.35, p2=2.4)
_ACCURATE_WINDOWS = _SEMI_GLOBAL.replace(
    aggregation=_ONE_PASS,
    optimizer=_ACCURATE_PATHS,
    fill=VoteFill(median_radius=9, median="separable", band_fit=15),
)
# The smoothing of accurate and fast as a row then a column of its window (3.5x fewer weights
# per pass): the cheapest point of the grid within 0.05 of the held-out choice at bad 2.0 on
# every set (benchmarks/grid.py smoothing, docs/notes/precision.md); balanced takes it by the same rule
# (docs/notes/band.md, "The separable smoothing in balanced"); finest keeps the square.
# accurate first measures the rectification's residual vertical offset on its own method over
# the pair halved and takes it out of the right image: better at bad 2.0, 1.0 and 0.5 on the
# three sets (docs/notes/alignment.md).
_ACCURATE = _ACCURATE_WINDOWS.replace(smoothing=_SMOOTHING.replace(separable=True),
                                      alignment=VerticalAlignment(levels=1))
# fast's doubled map fitted again on the full-resolution cost: below SGBM at bad 2.0, 1.0 and
# 0.5 on the three sets, for about a fifth more time (docs/notes/precision.md). With the refit, its
# halved pair takes accurate's one side-window pass and its penalties of then (_PATHS) instead
# of three passes at P1 0.12, P2 0.8: chosen by the held-out rule in every fold, on bad 2.0
# and over 2.0, 1.0 and 0.5, for 5-10 % less time (docs/notes/speed.md, "fast's halved pair as
# accurate's").
_FAST = _SEMI_GLOBAL.replace(aggregation=_ONE_PASS, optimizer=_PATHS,
                             coarse=CoarseToFine(levels=1, refit_radius=2),
                             smoothing=_SMOOTHING.replace(separable=True, iterations=3))

PRESETS: dict[str, Preset] = {
    "paper": Preset(_PAPER, "the paper's method: SSW aggregation, winner-takes-all, LR check, "
                            "fill, side-window median"),
    "accurate": Preset(_ACCURATE, "the right image's rows aligned to the left's (the offset "
                                  "measured on a first pass over the pair halved), one "
                                  "side-window pass without the segment term, then "
                                  "semi-global optimisation of the aggregated cost (4 paths), "
                                  "occlusion tests, intensity-weighted vote fill, the map "
                                  "smoothed along its surfaces"),
    "fast": Preset(_FAST,
                   "the same method on the pair halved (one side-window pass), the map "
                   "doubled back guided by the left image and fitted again on the "
                   "full-resolution cost (coarse-to-fine): about 3-4x faster, less precise "
                   "below 2 pixels"),
    # balanced aligns as accurate does, its first pass its own method over the pair halved:
    # chosen by the held-out rule on bad 2.0 and over 2.0, 1.0 and 0.5, against no alignment
    # and the offset measured on its own coarse pass (docs/notes/alignment.md, "On the coarse pass").
    "balanced": Preset(_ACCURATE.replace(coarse=CoarseToFine(levels=1), optimizer=_PATHS,
                                         band=DisparityBand(width=7)),
                       "aligned as accurate, then accurate on the pair halved and again at "
                       "full resolution over 7 disparities around each pixel's doubled "
                       "disparity (the band): about 1.8x faster than accurate on large "
                       "pairs, behind it at bad 2.0, ahead at 1.0 and 0.5 on KITTI"),
    "finest": Preset(_ACCURATE_WINDOWS.replace(
        aggregation=SideWindowAggregation(iterations=2),
        optimizer=SemiGlobal(paths=8, dtype="uint8", p1=0.05, p2=0.8),
        # The equiangular fit and the smoothing, as accurate: chosen together, held out on
        # the three sets at bad 2.0 and at 2.0, 1.0 and 0.5 (docs/paper-parts.md).
        fill=WeightedMedianFill(band_fit=15)),
        "accurate with two side-window passes, 8 paths, P1 0.05 and P2 0.8, and the guided "
        "weighted-median fill of the rejected pixels: the most accurate on occlusions and "
        "slanted planes, about 2x accurate's time"),
}
"""Preset name -> :class:`Preset`."""

DEFAULT_PRESET = "accurate"
"""The preset of :func:`sswjax.match`, ``match_with_confidence``, the batch functions and the
CLI when no parameters are given (:func:`default_params`). ``Params()`` itself holds the
paper's values (the ``paper`` preset)."""


def preset(name: str) -> Params:
    """The parameters of a named preset of :data:`PRESETS`.

    Examples
    --------
    >>> preset("accurate").optimizer.kind
    'sgm'
    """
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    return PRESETS[name].params


def default_params() -> Params:
    """The parameters used when none are given: the :data:`DEFAULT_PRESET` preset
    (``accurate``), chosen across data sets; ``Params()`` is the paper's method.

    Examples
    --------
    >>> default_params() == preset("accurate")
    True
    """
    return preset(DEFAULT_PRESET)
