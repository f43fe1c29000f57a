"""The one table of interchangeable parts: pre-processors, aggregators, optimizers, fills,
presets, method variants and peers.

Every place that names a part derives from these tables: parameter validation
(``Params.aggregation`` must be a key of :data:`AGGREGATORS`), the pipeline (which calls the
entry's function), the CLI's help, the evaluation's method names (:func:`method_names`) and the
Table 1 script. Adding a part is adding one entry.

Conventions
-----------
* A **pre-processor** maps each image of the pair before the matching cost:
  ``fn(image, *, params) -> image`` on float32 ``(H, W, C)`` in [0, 1] (superpixels and guides
  keep the original images); ``None`` for none.
* An **aggregator** is a pure function ``fn(cost, guide, *, radius, iterations,
  window_selection, segments) -> cost`` on a float32 ``(D, H, W)`` cost volume (lower is
  better) with the left image as guide, float32 ``(H, W, C)`` in [0, 1]. ``segments`` is a
  :class:`~sswjax.stages.aggregation.SegmentTerm` (superpixel labels and the weight lambda) or
  ``None``; an aggregator that does not use an option ignores it. ``radius`` is the entry's own
  radius when it declares one, else ``Params.aggregation_radius``.
* An **optimizer** runs between aggregation and selection on the whole aggregated volume:
  ``fn(cost, guide, *, labels, params) -> cost`` with ``labels`` the superpixels (int32
  ``(H, W)``) or ``None`` and ``params`` the :class:`~sswjax.params.Params`; ``None`` for the
  paper's winner-takes-all directly on the aggregated cost.
* A **variant** is a named set of parameter changes applied on top of the user's parameters
  (the paper's ablations and the baseline aggregators as methods).
* A **fill** replaces the disparities the left-right check rejected:
  ``fn(disparity, valid, *, labels, num_segments, params) -> disparity`` on float32 ``(H, W)``
  maps with the bool ``(H, W)`` validity.
* A **preset** is a named set of parameter changes on top of ``Params()`` (what
  :func:`sswjax.preset` returns, ``--preset`` on the command line).
* A **peer** is another project's matcher ``fn(left, right, ndisp) -> float32 (H, W)`` on NumPy
  images as read from disk, run under our protocol (optional dependencies).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

from sswjax.evaluation.peers import bm_disparity, pandora_disparity, sgbm_disparity
from sswjax.stages.aggregation import segment_side_window_aggregation
from sswjax.stages.planes import plane_refine
from sswjax.stages.preprocess import local_contrast_normalization
from sswjax.stages.fill import vote_fill, weighted_median_fill
from sswjax.stages.refinement import fill_invalid
from sswjax.stages.sgm import half_resolution_semi_global, quantisation, semi_global_sums
from sswjax.stages.baselines import (
    bilateral_filter,
    box_filter,
    guided_filter,
    iterated_guided_filter,
    median_cost_filter,
)


class Preprocessor(NamedTuple):
    """An entry of :data:`PREPROCESSORS`: ``fn(image, *, params)`` (or ``None``) and a summary."""

    fn: Callable[..., Any] | None
    summary: str


PREPROCESSORS: dict[str, Preprocessor] = {
    "none": Preprocessor(None, "the images as given (the paper)"),
    "lcn": Preprocessor(
        lambda image, *, params: local_contrast_normalization(
            image, radius=params.static.lcn_radius, eps=params.dynamic.lcn_eps),
        "local contrast normalisation of the images seen by the cost (dark, low-contrast pairs)",
    ),
}
"""Pre-processor name (``Params.preprocess``) -> :class:`Preprocessor`."""


class Aggregator(NamedTuple):
    """An entry of :data:`AGGREGATORS`.

    Attributes
    ----------
    fn : callable
        ``fn(cost, guide, *, radius, iterations, window_selection, segments) -> cost``.
    summary : str
        One line for the CLI's help and the tables.
    radius : int or None
        The radius the aggregator always runs with; ``None`` honours
        ``Params.aggregation_radius``.
    uses_segments : bool
        Whether it uses the superpixels (the pipeline runs SLIC only then).
    """

    fn: Callable[..., Any]
    summary: str
    radius: int | None = None
    uses_segments: bool = False


AGGREGATORS: dict[str, Aggregator] = {
    "ssw": Aggregator(
        segment_side_window_aggregation,
        "segment-side-window box filter with the superpixel cost term, the paper's method (Eq. 7)",
        uses_segments=True,
    ),
    "box": Aggregator(
        lambda cost, guide, *, radius, **_: box_filter(cost, radius=radius),
        "square box mean (Scharstein & Szeliski 2002)",
    ),
    "bf": Aggregator(
        lambda cost, guide, *, radius, **_: bilateral_filter(cost, guide, radius=radius),
        "bilateral / adaptive support weights (Yoon & Kweon 2006)",
    ),
    "gf": Aggregator(
        lambda cost, guide, *, radius, **_: guided_filter(cost, guide, radius=radius),
        "colour guided filter, eps 1e-4 (He et al. 2013; Hosni et al. 2013)",
        radius=9,
    ),
    "igf": Aggregator(
        lambda cost, guide, *, radius, **_: iterated_guided_filter(cost, guide, radius=radius),
        "two guided-filter passes",
        radius=9,
    ),
    "mf": Aggregator(
        lambda cost, guide, *, radius, **_: median_cost_filter(cost, radius=radius),
        "median of each cost slice, 5x5",
        radius=2,
    ),
}
"""Aggregation name (``Params.aggregation``) -> :class:`Aggregator`. The baselines are those of
the paper's Table 1 (BF, GF, iGF, MF) and a plain box; the guided filters and the median run
with the usual radius of local stereo (guided filter r 9 as in Hosni et al. 2013, median 5x5),
box and bilateral with SSW's own radius."""


class Optimizer(NamedTuple):
    """An entry of :data:`OPTIMIZERS`.

    Attributes
    ----------
    fn : callable or None
        ``fn(cost, guide, *, labels, params) -> cost``, a float32 (D, H, W) volume or the
        :class:`~sswjax.stages.sgm.PathSums` that :func:`~sswjax.stages.sgm.as_volume` turns
        into one (the selection reads its planes directly); ``None``: no optimisation.
    summary : str
        One line for the CLI's help and the tables.
    uses_segments : bool
        Whether it uses the superpixels.
    subpixel_on_input : bool
        Whether the sub-pixel parabola fits the aggregated cost the optimiser was given rather
        than its output (whose interpolated coarse term would bias it).
    storage : callable or None
        ``storage(params) -> Quantisation | None``: how ``fn`` takes the aggregated cost
        (:func:`~sswjax.stages.sgm.quantise_cost` of that quantisation, which the pipeline
        applies slice by slice as the volume is built, so the float32 volume is never
        written); None or a None result: float32.
    """

    fn: Callable[..., Any] | None
    summary: str
    uses_segments: bool = False
    subpixel_on_input: bool = False
    storage: Callable[..., Any] | None = None


def _cost_bound(params):
    """The largest aggregated cost of a matching pixel for a quantised ``sgm_dtype`` (else None).

    Each term of Eq. 5 is normalised to [0, 1], the border cost is the weights' sum, and the
    aggregators average: the weights' sum bounds the cost, times ``1 + lambda`` with the segment
    term of Eq. 7 (a filter that is not an average, such as the guided one, may overshoot it
    slightly: the quantisation clips there).
    """
    static, dynamic = params.static, params.dynamic
    if static.sgm_dtype == "float32":
        return None
    bound = abs(dynamic.tad_weight) + abs(dynamic.gradient_weight) + abs(dynamic.census_weight)
    return bound * (1.0 + abs(dynamic.segment_weight)) if static.n_segments else bound


def _quantisation(params):
    """``cost_bound`` and ``cost_levels`` of the semi-global functions for ``Params.sgm_dtype``."""
    levels = 255 if params.static.sgm_dtype == "uint8" else None
    return {"cost_bound": _cost_bound(params), "cost_levels": levels}


def _storage(params):
    """The :class:`~sswjax.stages.sgm.Quantisation` of the aggregated cost for the paths of
    ``params`` (None with ``sgm_dtype="float32"``)."""
    options = _quantisation(params)
    if options["cost_bound"] is None:
        return None
    dynamic = params.dynamic
    return quantisation(paths=params.static.sgm_paths, p1=dynamic.sgm_p1, p2=dynamic.sgm_p2,
                        **options)


def _semi_global(cost, guide, *, labels, params):
    static, dynamic = params.static, params.dynamic
    return semi_global_sums(cost, guide, p1=dynamic.sgm_p1, p2=dynamic.sgm_p2,
                            sigma=dynamic.sgm_sigma, paths=static.sgm_paths, labels=labels,
                            segment_factor=dynamic.sgm_segment_factor,
                            **_quantisation(params))


def _half_resolution_semi_global(cost, guide, *, labels, params):
    static, dynamic = params.static, params.dynamic
    return half_resolution_semi_global(cost, guide, p1=dynamic.sgm_p1, p2=dynamic.sgm_p2,
                                       sigma=dynamic.sgm_sigma, paths=static.sgm_paths,
                                       detail_weight=dynamic.sgm_detail_weight,
                                       **_quantisation(params))


OPTIMIZERS: dict[str, Optimizer] = {
    "none": Optimizer(None, "winner-takes-all directly on the aggregated cost (the paper, Eq. 8)"),
    "sgm": Optimizer(_semi_global, "semi-global optimisation of the aggregated cost, 4 or 8 "
                     "paths, guide-adaptive P2, reduced across superpixels (Hirschmuller 2008)",
                     uses_segments=True, storage=_storage),
    "sgm-half": Optimizer(_half_resolution_semi_global,
                          "semi-global optimisation of the volume halved in space and disparity, "
                          "doubled back onto the aggregated cost (an eighth of the paths' work)",
                          subpixel_on_input=True),
}
"""Optimizer name (``Params.optimizer``) -> :class:`Optimizer`."""


class Fill(NamedTuple):
    """An entry of :data:`FILLS`: ``fn(disparity, valid, *, labels, num_segments, params)``,
    a one-line summary, whether it uses the superpixels and whether it needs the left image
    (then the pipeline passes it as ``guide=``, float32 ``(H, W, C)`` in [0, 1])."""

    fn: Callable[..., Any]
    summary: str
    uses_segments: bool = False
    uses_guide: bool = False


def _background_fill(disparity, valid, *, labels, num_segments, params):
    return fill_invalid(disparity, valid, radius=params.static.fill_radius,
                        median=params.static.fill_median)


def _left_band_fill(disparity, valid, *, labels, num_segments, params):
    return fill_invalid(disparity, valid, radius=params.static.fill_radius, left_band=True,
                        median=params.static.fill_median, band_fit=params.static.fill_band_fit)


def _weighted_median_fill(disparity, valid, *, labels, num_segments, params, guide=None):
    if guide is None:
        raise ValueError("fill 'wmedian' needs the left image (guide=), which the whole "
                         "pipeline passes (select_and_refine alone has none)")
    return weighted_median_fill(disparity, valid, radius=params.static.fill_weight_radius,
                                guide=guide, eps=params.dynamic.fill_eps,
                                quantile=params.dynamic.fill_quantile,
                                source=params.static.fill_source,
                                band_fit=params.static.fill_band_fit)


def _vote_fill(disparity, valid, *, labels, num_segments, params, guide=None):
    if guide is None:
        raise ValueError("fill 'vote' needs the left image (guide=), which the whole "
                         "pipeline passes (select_and_refine alone has none)")
    static = params.static
    return vote_fill(disparity, valid, guide=guide, median_radius=static.fill_radius,
                     radius=static.fill_weight_radius, step=static.vote_step,
                     sigma=params.dynamic.vote_sigma, tolerance=params.dynamic.vote_tolerance,
                     median=static.fill_median, band_fit=static.fill_band_fit)


def _plane_fill(disparity, valid, *, labels, num_segments, params):
    filled = _background_fill(disparity, valid, labels=labels, num_segments=num_segments,
                              params=params)
    if num_segments == 0:
        return filled
    return plane_refine(filled, valid, labels, num_segments=num_segments,
                        min_support=params.dynamic.plane_min_support,
                        inlier_scale=params.dynamic.plane_inlier_scale)


FILLS: dict[str, Fill] = {
    "background": Fill(_background_fill, "the nearer-background valid disparity of the row, then "
                       "a median over the filled pixels (Eq. 9 as we read it)"),
    "left-band": Fill(_left_band_fill, "the background fill, but the surface on the right where "
                      "it has no match at the pixel's column (x < d), the left border's case"),
    "wmedian": Fill(_weighted_median_fill, "the left-band fill, then a weighted median of the "
                    "neighbours' disparities, weighted by the guided filter on the left image "
                    "(Rhemann et al. 2011, Ma et al. 2013)", uses_guide=True),
    "vote": Fill(_vote_fill, "the left-band fill, then a vote among it and the nearest valid "
                 "disparities left and right on the row, by neighbours weighted by intensity "
                 "likeness", uses_guide=True),
    "plane": Fill(_plane_fill, "a robust plane per superpixel through its valid pixels where "
                  "they support it, else the background fill", uses_segments=True),
}
"""Fill name (``Params.fill``) -> :class:`Fill`."""


class Variant(NamedTuple):
    """An entry of :data:`VARIANTS`: parameter changes and a one-line summary."""

    changes: Mapping[str, Any]
    summary: str


VARIANTS: dict[str, Variant] = {
    "ssw-noseg": Variant({"n_segments": 0}, "SSW without the segment term"),
    "ssw-norefine": Variant({"refine_radius": 0}, "SSW without the side-window median refinement"),
    "ssw-nolr": Variant({"lr_check": False}, "SSW without the left-right check and fill"),
    "ssw-guide": Variant({"window_selection": "guide"}, "SSW, windows chosen on the left image"),
    "ssw-tad": Variant({"tad_weight": 1.0, "gradient_weight": 0.0, "census_weight": 0.0},
                       "SSW with the TAD cost alone"),
    "ssw-gm": Variant({"tad_weight": 0.0, "gradient_weight": 1.0, "census_weight": 0.0},
                      "SSW with the gradient cost alone"),
    "ssw-census": Variant({"tad_weight": 0.0, "gradient_weight": 0.0, "census_weight": 1.0},
                          "SSW with the census cost alone"),
}
"""Ablations of SSW: method name -> :class:`Variant` (applied on top of the user's parameters).
Every aggregator of :data:`AGGREGATORS` is a method too, named after it."""


class Preset(NamedTuple):
    """An entry of :data:`PRESETS`: parameter changes from ``Params()`` and a one-line summary."""

    changes: Mapping[str, Any]
    summary: str


# The semi-global presets store the aggregated cost in uint8 for the int16 paths (a quarter of
# float32's bytes through the memory-bound scans; the same errors within 0.03 on every set, see
# the README's design notes). P1 and P2 of each preset, the separable median's width and the
# side-window passes were chosen by the static grids of the README's "Beyond the paper", by the
# rule of benchmarks/held_out.py (lowest mean error relative to the best, over the three sets):
# fast P1 0.12 and P2 0.8, accurate P1 0.16 and P2 1.15, finest P1 0.05 and P2 0.8 (Params()'s).
# The occlusion tests of issue 11 in every semi-global preset: the uniqueness test on costs
# before aggregation, the aggregated cost's right view, and the left band's fitted line.
_OCCLUSIONS = {"uniqueness_gap": 2, "uniqueness_radius": 2, "aggregated_lr_gap": 2,
               "fill_band_fit": 15}
_SGM = {"optimizer": "sgm", "sgm_paths": 4, "sgm_p1": 0.12, "sgm_p2": 0.8, "n_segments": 0,
        "fill_radius": 7, "fill_median": "separable", "fill": "left-band", "sgm_dtype": "uint8",
        **_OCCLUSIONS}
# accurate: one side-window pass, a 19 x 19 separable fill median and the vote fill instead of
# _SGM's three passes, 15 x 15 and left-band fill; fast keeps _SGM's.
_ACCURATE = {**_SGM, "aggregation_iterations": 1, "fill_radius": 9, "fill": "vote",
             "sgm_p1": 0.2, "sgm_p2": 1.15}

PRESETS: dict[str, Preset] = {
    "paper": Preset({}, "the paper's method: SSW aggregation, winner-takes-all, LR check, fill, "
                        "side-window median"),
    "accurate": Preset(_ACCURATE,
                       "one side-window pass without the segment term, then semi-global "
                       "optimisation of the aggregated cost (4 paths), occlusion tests, "
                       "intensity-weighted vote fill"),
    "fast": Preset({**_SGM, "coarse_levels": 1},
                   "the same method on the pair halved (three side-window passes), the map "
                   "doubled back guided by the left image "
                   "(coarse-to-fine): about 5x faster, less precise below 2 pixels"),
    "finest": Preset({**_ACCURATE, "aggregation_iterations": 2, "fill": "wmedian",
                      "sgm_paths": 8, "sgm_p1": 0.05, "sgm_p2": 0.8},
                     "accurate with two side-window passes, 8 paths, P1 0.05 and P2 0.8, and the "
                     "guided weighted-median "
                     "fill of the rejected pixels: the most accurate on occlusions and slanted "
                     "planes, about 2x accurate's time"),
}
"""Preset name -> :class:`Preset`."""

DEFAULT_PRESET = "accurate"
"""The preset of :func:`sswjax.match`, ``match_with_confidence``, the batch functions and the
CLI when no parameters are given (:func:`sswjax.params.default_params`). ``Params()`` itself
holds the paper's values (the ``paper`` preset)."""


class Peer(NamedTuple):
    """An entry of :data:`PEERS`: another project's matcher and a one-line summary."""

    fn: Callable[..., Any]
    summary: str


PEERS: dict[str, Peer] = {
    "bm": Peer(bm_disparity, "OpenCV StereoBM, block 9 on the luma, background fill (extra [bench])"),
    "sgbm": Peer(sgbm_disparity, "OpenCV StereoSGBM 3-way, block 3, background fill (extra [bench])"),
    "sgbm-hh": Peer(functools.partial(sgbm_disparity, mode="hh"),
                    "OpenCV StereoSGBM HH (8 paths, full-size buffers), block 3, background fill "
                    "(extra [bench])"),
    "pandora": Peer(pandora_disparity,
                    "CNES Pandora census 5x5 + SGM, background fill (extra [pandora])"),
}
"""Method name -> :class:`Peer`."""


def variant_changes(name: str) -> Mapping[str, Any]:
    """Parameter changes of the SSW method ``name`` (an aggregator or a variant).

    Raises ``KeyError`` for a name that is neither.

    Examples
    --------
    >>> variant_changes("gf"), variant_changes("ssw")
    ({'aggregation': 'gf'}, {})
    """
    if name in AGGREGATORS:
        return {} if name == "ssw" else {"aggregation": name}
    return VARIANTS[name].changes


def method_names() -> tuple[str, ...]:
    """Every method ``sswjax evaluate --methods`` accepts: aggregators, variants, peers."""
    return (*AGGREGATORS, *VARIANTS, *PEERS)


def preset_summaries() -> dict[str, str]:
    """Preset name -> one-line summary (for the CLI's help)."""
    return {name: entry.summary for name, entry in PRESETS.items()}


def method_summaries() -> dict[str, str]:
    """Method name -> one-line summary (for the CLI's help)."""
    tables: list[Mapping[str, Any]] = [AGGREGATORS, VARIANTS, PEERS]
    return {name: entry.summary for table in tables for name, entry in table.items()}
