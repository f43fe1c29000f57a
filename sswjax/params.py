"""The SSW parameter pytree: static (shape-changing) fields apart from dynamic (continuous) ones.

``Params`` is one immutable value. It is a JAX pytree whose only leaves are the continuous fields
of :class:`DynamicParams` (weights, truncations, blending, tolerances): these are traced by
``jax.jit`` and differentiated by the optax search. The fields of :class:`StaticParams` (radii,
census window, superpixel count, iterations, switches) change array shapes or the graph, so they
live in the pytree's metadata: changing one recompiles, and they are never differentiated.

Units: image intensities are in [0, 1], so truncations are fractions of the full intensity range;
disparities are in pixels.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Mapping
from typing import Any, NamedTuple

import jax

from sswjax.registry import AGGREGATORS, DEFAULT_PRESET, FILLS, OPTIMIZERS, PREPROCESSORS, PRESETS
from sswjax.stages.aggregation import WINDOW_SELECTIONS
from sswjax.stages.fill import SOURCES as FILL_SOURCES
from sswjax.stages.refinement import MEDIANS as FILL_MEDIANS
from sswjax.stages.sgm import PATH_COUNTS, SGM_DTYPES


class StaticParams(NamedTuple):
    """Fields that fix shapes or the structure of the graph (hashable; recompiles on change).

    Attributes
    ----------
    census_height, census_width : int
        Census window, odd sizes (Eq. 4). Default 7 x 9.
    n_segments : int
        Requested SLIC superpixel count (Eq. 6); 0 disables the segment term.
    slic_iterations : int
        Fixed number of SLIC assignment/update rounds.
    aggregation_radius : int
        Side-window radius r of the cost aggregation (Eq. 7).
    aggregation_iterations : int
        Number of side-window filtering passes over the cost volume.
    aggregation : str
        A key of :data:`sswjax.registry.AGGREGATORS`: ``"ssw"`` (segment-side-window, the
        method) or a baseline aggregator that replaces it, everything else unchanged.
    window_selection : str
        ``"guide"``: each pixel's side window is chosen on the left image and shared by all
        disparities; ``"slice"``: chosen independently on every cost slice (Yin et al. 2019).
        Default ``"slice"``: with the segment term it scored 10.7 / 16.9 weighted bad 2.0
        (nonocc / all) on trainingQ against 11.0 / 17.7 for ``"guide"`` (README, design notes).
    subpixel : bool
        Parabola fit around the winner-takes-all minimum (Eq. 8 refined).
    lr_check : bool
        Left-right consistency check and filling of the pixels it rejects.
    uniqueness_gap : int
        ``g > 0``: with ``lr_check``, a pixel is also rejected when another pixel of its row
        whose disparity differs by ``g`` or more claims the same right pixel at a lower matching
        cost before aggregation (:func:`sswjax.stages.refinement.uniqueness_violations`): the
        occluded pixels that took the foreground's disparity. 0 (default): off.
    aggregated_lr_gap : int
        ``g > 0``: with ``lr_check`` and an optimiser, a pixel is also rejected where the right
        view of the aggregated cost *before* the optimiser (its winner-takes-all) disagrees
        with the pixel's disparity by ``g`` or more: the optimiser spreads a foreground over
        the occlusion beside it in the left view and in the right view derived from the same
        volume alike, so the final views agree there; the aggregated cost's right view
        does not. 0 (default): off.
    uniqueness_radius : int
        The claims' costs of ``uniqueness_gap`` are box means over ``(2r+1)^2`` pixels (each
        at its own disparity); 0: each pixel's own cost.
    fill_radius : int
        Radius of the median over filled pixels (Eq. 9): at most 5 with ``fill_median="square"``,
        15 with ``"separable"``.
    fill_median : str
        ``"square"``: the exact median of the ``(2r+1)^2`` window; ``"separable"``: the median of
        its column medians, far cheaper for wide windows
        (:data:`sswjax.stages.refinement.MEDIANS`).
    refine_radius : int
        Radius of the side-window median applied to the disparity map (0 disables it).
    refine_iterations : int
        Passes of that side-window median.
    disparity_chunk : int
        K > 0 (default 4): disparities K at a time with a running minimum, memory for about
        ``3 K`` slices; 0: the whole cost volume at once. Same result either way; K = 4 was
        fastest on XLA CPU (2x faster than the whole volume: the blocks stay in cache).
    optimizer : str
        A key of :data:`sswjax.registry.OPTIMIZERS`: ``"none"`` (winner-takes-all on the
        aggregated cost, the paper) or ``"sgm"`` (semi-global optimisation of the aggregated
        volume before the selection, :mod:`sswjax.stages.sgm`; ``"sgm-half"``, the same at half
        resolution added back to the aggregated cost).
    sgm_paths : int
        4 or 8 paths of the semi-global optimisation.
    sgm_dtype : str
        ``"int16"`` (default): the paths run on the volume quantised to int16, as OpenCV's SGBM
        does, 1.5-3x faster on XLA CPU; ``"uint8"``: the same paths on the volume stored in 255
        levels, block by block as the aggregation builds it (half the bytes again);
        ``"float32"``: exact and differentiable (the parameter search uses it).
        :data:`sswjax.stages.sgm.SGM_DTYPES`.
    fill : str
        A key of :data:`sswjax.registry.FILLS`: how the pixels the left-right check rejects
        are filled (``"background"``, Eq. 9; ``"plane"``, superpixel planes first;
        ``"wmedian"``, a guided weighted median, :mod:`sswjax.stages.fill`).
    fill_weight_radius : int
        Window radius of the guided weights of ``fill="wmedian"``, and of the sampled window
        of ``fill="vote"``.
    vote_step : int
        Sampling step of the window of ``fill="vote"`` (:func:`sswjax.stages.fill.vote_fill`).
    fill_band_fit : int
        ``k > 0``: with ``fill="left-band"`` or ``"wmedian"``, the band left of each row's first
        valid pixel takes a straight line fitted to the valid pixels of the next ``k`` columns
        (:func:`sswjax.stages.refinement.fill_background`'s ``band_fit``); 0 (default): the
        constant of the left-band rule.
    fill_source : str
        What the weighted median of ``fill="wmedian"`` counts: ``"filled"``, every pixel of the
        background-filled map, or ``"valid"``, the pixels that passed the check.
    preprocess : str
        A key of :data:`sswjax.registry.PREPROCESSORS`: what the cost sees of the images
        (``"none"``; ``"lcn"``, local contrast normalisation, :mod:`sswjax.stages.preprocess`).
    lcn_radius : int
        Window radius of the local contrast normalisation.
    strip_rows, strip_overlap : int
        ``strip_rows > 0``: :func:`sswjax.match` runs the pair in horizontal strips of that
        many rows, each seen with ``strip_overlap`` more rows above and below
        (:func:`sswjax.api.in_strips`): memory follows the strip, not the image. 0 (default):
        the whole image at once.
    coarse_levels : int
        0 (default): the method runs on the images as given. ``L > 0``: coarse-to-fine, it runs
        on the pair halved ``L`` times (:func:`~sswjax.stages.pyramid.halve_image`, ``ndisp``
        halved too), and the map is doubled back ``L`` times by
        :func:`~sswjax.stages.upsampling.upsample_disparity` guided by the left image: about
        ``8 ** L`` times less volume work (the ``fast`` preset).
    upsample_radius : int
        Radius of the side-window median (``refine_iterations`` passes) after each doubling of
        ``coarse_levels``; 0 disables it.
    """

    census_height: int = 7
    census_width: int = 9
    n_segments: int = 2000
    slic_iterations: int = 10
    aggregation_radius: int = 4
    aggregation_iterations: int = 3
    aggregation: str = "ssw"
    window_selection: str = "slice"
    subpixel: bool = True
    lr_check: bool = True
    fill_radius: int = 2
    refine_radius: int = 2
    refine_iterations: int = 2
    disparity_chunk: int = 4
    optimizer: str = "none"
    sgm_paths: int = 8
    sgm_dtype: str = "int16"
    fill: str = "background"
    fill_weight_radius: int = 9
    fill_band_fit: int = 0
    vote_step: int = 4
    fill_source: str = "filled"
    fill_median: str = "square"
    preprocess: str = "none"
    lcn_radius: int = 7
    strip_rows: int = 0
    strip_overlap: int = 32
    coarse_levels: int = 0
    upsample_radius: int = 1
    uniqueness_gap: int = 0
    uniqueness_radius: int = 2
    aggregated_lr_gap: int = 0


class DynamicParams(NamedTuple):
    """Continuous fields: pytree leaves, traced by ``jit`` and searched by optax.

    Defaults: the exact values of ``tuning/params/tuned.json`` (the truncations and the segment
    weight found by the optax search of ``tuning/search.py``; the weights and the rest as set by
    hand in ``tuning/params/hand.json``, stored as the search's float32 values).

    Attributes
    ----------
    tad_weight, gradient_weight, census_weight : float
        alpha, beta, gamma of Eq. (5), applied to the normalised terms (each in [0, 1]).
    tad_truncation : float
        tau of Eq. (2) on the channel-mean absolute difference, intensities in [0, 1].
    gradient_truncation : float
        Truncation of the Sobel gradient-magnitude difference (Eq. 3).
    segment_weight : float
        lambda of the segment term: the filter sees ``C + lambda * S`` (Eq. 7 as we read it).
    slic_compactness : float
        m of Eq. (6).
    lr_tolerance : float
        Largest left/right disagreement, in pixels, that the consistency check accepts.
    sgm_p1, sgm_p2 : float
        Semi-global penalties for a disparity change of one and of more, in the units of the
        aggregated cost (``optimizer="sgm"`` only).
    sgm_sigma : float
        Guide intensity change that halves P2 (:func:`sswjax.stages.sgm.path_penalties`).
    sgm_segment_factor : float, in [0, 1]
        Factor of both penalties across superpixel boundaries (1: no effect).
    sgm_detail_weight : float
        ``optimizer="sgm-half"``: weight of the full-resolution aggregated cost added to the
        doubled half-resolution paths.
    plane_min_support : float, in [0, 1]
        Share of a superpixel's pixels that must be valid inliers for its plane to fill it.
    plane_inlier_scale : float
        Residual (pixels) up to which a pixel keeps full weight in the robust plane fit.
    lcn_eps : float
        Added to the local standard deviation by the local contrast normalisation.
    fill_eps : float > 0
        Guided-filter regularisation of the weights of ``fill="wmedian"`` (intensities in
        [0, 1]): colour edges with a variance well above it separate the weights.
    fill_quantile : float, in (0, 1]
        The weighted quantile ``fill="wmedian"`` takes: 0.5 the median, less leans towards the
        background (smaller disparities).
    upsample_jump : float
        ``coarse_levels > 0``: largest spread (fine pixels) of the four coarse neighbours'
        disparities that a doubled pixel interpolates; beyond it the pixel takes the neighbour
        of the nearest colour (:func:`~sswjax.stages.upsampling.upsample_disparity`).
    vote_sigma : float > 0
        ``fill="vote"``: the intensity difference (in [0, 1] units) at which a neighbour's vote
        weighs a quarter of an identical one's.
    vote_tolerance : float
        ``fill="vote"``: how close (pixels) a neighbour's disparity must be to a candidate to
        vote for it.
    """

    tad_weight: Any = 0.05000000074505806
    gradient_weight: Any = 0.15000000596046448
    census_weight: Any = 0.800000011920929
    tad_truncation: Any = 0.04221818596124649
    gradient_truncation: Any = 0.015484430827200413
    segment_weight: Any = 0.5996789336204529
    slic_compactness: Any = 10.0
    lr_tolerance: Any = 0.0
    sgm_p1: Any = 0.05
    sgm_p2: Any = 0.4
    sgm_sigma: Any = 0.05
    sgm_segment_factor: Any = 1.0
    sgm_detail_weight: Any = 1.0
    plane_min_support: Any = 0.25
    plane_inlier_scale: Any = 1.0
    lcn_eps: Any = 4 / 255
    fill_eps: Any = 1e-3
    fill_quantile: Any = 0.5
    upsample_jump: Any = 3.0
    vote_sigma: Any = 0.2
    vote_tolerance: Any = 2.0


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Params:
    """All SSW parameters: ``static`` in the pytree metadata, ``dynamic`` as its leaves.

    Examples
    --------
    >>> from sswjax import Params
    >>> p = Params()
    >>> p.static.aggregation_radius
    4
    >>> p2 = p.replace(census_weight=0.5, aggregation_radius=6)
    >>> (p2.dynamic.census_weight, p2.static.aggregation_radius)
    (0.5, 6)
    """

    dynamic: DynamicParams = dataclasses.field(default_factory=DynamicParams)
    static: StaticParams = dataclasses.field(
        default_factory=StaticParams, metadata=dict(static=True)
    )

    def replace(self, **changes) -> Params:
        """Return a copy with the named fields (static or dynamic) changed."""
        unknown = set(changes) - set(StaticParams._fields) - set(DynamicParams._fields)
        if unknown:
            raise ValueError(f"unknown parameter(s): {', '.join(sorted(unknown))}")
        static = self.static._replace(**{k: v for k, v in changes.items() if k in StaticParams._fields})
        dynamic = self.dynamic._replace(
            **{k: v for k, v in changes.items() if k in DynamicParams._fields}
        )
        return Params(dynamic=dynamic, static=static)

    def to_dict(self) -> dict:
        """Plain JSON-able dict ``{"static": {...}, "dynamic": {...}}``."""
        return {
            "static": dict(self.static._asdict()),
            "dynamic": {k: float(v) for k, v in self.dynamic._asdict().items()},
        }


# Upper bounds a user value must respect (inclusive); lower bounds are in ``_check_value``.
_INT_FIELDS = {
    "census_height": (1, 15),
    "census_width": (1, 15),
    "n_segments": (0, 1_000_000),
    "slic_iterations": (1, 100),
    "aggregation_radius": (1, 50),
    "aggregation_iterations": (0, 20),
    # The medians run a sorting network over every window value: kept at <= 128 inputs (the
    # (2r + 1)^2 square of the fill, the (r + 1)(2r + 1) side windows of the refinement), as a
    # 512-input network took over 20 GB to compile. The separable fill median's networks have
    # 2r + 1 inputs (the square's bound is _check_combination's).
    "fill_radius": (0, 15),
    "refine_radius": (0, 7),
    "refine_iterations": (0, 20),
    "disparity_chunk": (0, 100_000),
    "lcn_radius": (1, 50),
    "fill_weight_radius": (1, 50),
    "fill_band_fit": (0, 100_000),
    "vote_step": (1, 50),
    "strip_rows": (0, 1_000_000),
    "strip_overlap": (0, 10_000),
    "coarse_levels": (0, 4),
    "upsample_radius": (0, 7),
    "uniqueness_gap": (0, 100_000),
    "uniqueness_radius": (0, 50),
    "aggregated_lr_gap": (0, 100_000),
}
_BOOL_FIELDS = ("subpixel", "lr_check")
_CHOICE_FIELDS = {"aggregation": AGGREGATORS, "window_selection": WINDOW_SELECTIONS,
                  "optimizer": OPTIMIZERS, "sgm_paths": PATH_COUNTS, "sgm_dtype": SGM_DTYPES,
                  "fill": FILLS,
                  "preprocess": PREPROCESSORS, "fill_source": FILL_SOURCES,
                  "fill_median": FILL_MEDIANS}
_UNIT_FIELDS = ("sgm_segment_factor", "plane_min_support", "fill_quantile")
_POSITIVE_FIELDS = ("tad_truncation", "gradient_truncation", "slic_compactness", "sgm_sigma",
                    "plane_inlier_scale", "lcn_eps", "fill_eps", "fill_quantile", "vote_sigma")


def _check_value(name: str, value) -> Any:
    """Validate one field's value from a user; return it with its canonical Python type."""
    if name in _INT_FIELDS:
        low, high = _INT_FIELDS[name]
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"parameter {name} must be an integer, got {value!r}")
        if not low <= value <= high:
            raise ValueError(f"parameter {name} must be in [{low}, {high}], got {value}")
        if name in ("census_height", "census_width") and value % 2 == 0:
            raise ValueError(f"parameter {name} must be odd, got {value}")
        return value
    if name in _BOOL_FIELDS:
        if not isinstance(value, bool):
            raise ValueError(f"parameter {name} must be true or false, got {value!r}")
        return value
    if name in _CHOICE_FIELDS:
        choices = tuple(_CHOICE_FIELDS[name])
        if not isinstance(value, type(choices[0])) or isinstance(value, bool) or value not in choices:
            raise ValueError(f"parameter {name} must be one of {choices}, got {value!r}")
        return value
    # dynamic: finite, non-negative reals; truncations and compactness strictly positive
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"parameter {name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value < 0 or (name in _POSITIVE_FIELDS and value == 0):
        bound = "> 0" if name in _POSITIVE_FIELDS else ">= 0"
        raise ValueError(f"parameter {name} must be a finite number {bound}, got {value}")
    if name in _UNIT_FIELDS and value > 1:
        raise ValueError(f"parameter {name} must be in [0, 1], got {value}")
    return value


_SQUARE_FILL_RADIUS = 5  # a (2r + 1)^2 <= 128-input network, as above


def _check_combination(static: StaticParams) -> None:
    """Rules between static fields: the square fill median's radius bound."""
    if static.fill_median == "square" and static.fill_radius > _SQUARE_FILL_RADIUS:
        raise ValueError(f"parameter fill_radius must be in [0, {_SQUARE_FILL_RADIUS}] with "
                         f"fill_median 'square', got {static.fill_radius}")


def check_params(params) -> Params:
    """Validate a ``Params`` value given to the Python API; return it unchanged.

    Applies the rules of :func:`params_from_dict` (types, ranges, odd census sizes, finite and
    non-negative dynamic values) to a ``Params`` built in code, e.g. with :meth:`Params.replace`,
    which does not check. Dynamic values may be Python or NumPy/JAX scalars; traced values
    (inside ``jax.jit`` or ``jax.grad``) are not inspected.

    Raises
    ------
    TypeError
        If ``params`` is not a ``Params``.
    ValueError
        On the first bad field, with a one-line message naming it.
    """
    if not isinstance(params, Params):
        raise TypeError(
            f"params must be a sswjax.Params (see sswjax.load_params), got {type(params).__name__}"
        )
    for name, value in params.static._asdict().items():
        if name in _INT_FIELDS or name in _BOOL_FIELDS or name in _CHOICE_FIELDS:
            _check_value(name, value)
    _check_combination(params.static)
    for name, value in params.dynamic._asdict().items():
        if isinstance(value, jax.core.Tracer):
            continue
        if not isinstance(value, (bool, int, float)) and hasattr(value, "shape"):
            if tuple(value.shape) != ():
                raise ValueError(f"parameter {name} must be a scalar, got shape {tuple(value.shape)}")
            kind = getattr(getattr(value, "dtype", None), "kind", "")
            if kind not in ("i", "u", "f"):
                raise ValueError(f"parameter {name} must be a number, got {value!r}")
            value = float(value)
        _check_value(name, value)
    return params


def params_from_dict(data: Mapping) -> Params:
    """Build validated ``Params`` from ``{"static": {...}, "dynamic": {...}}`` (missing keys default).

    A flat mapping of field names is accepted too. Extra top-level keys ``"provenance"`` and
    ``"comment"`` are ignored; any other unknown key raises ``ValueError``.
    """
    if not isinstance(data, Mapping):
        raise ValueError(f"parameters must be a JSON object, got {type(data).__name__}")
    flat: dict = {}
    for key, value in data.items():
        if key in ("static", "dynamic") and isinstance(value, Mapping):
            fields = StaticParams._fields if key == "static" else DynamicParams._fields
            for name, item in value.items():
                if name not in fields:
                    raise ValueError(f"unknown {key} parameter {name!r}")
                flat[name] = item
        elif key in ("provenance", "comment"):
            continue
        elif key in StaticParams._fields or key in DynamicParams._fields:
            flat[key] = value
        else:
            raise ValueError(f"unknown parameter {key!r}")
    params = Params().replace(**{name: _check_value(name, value) for name, value in flat.items()})
    _check_combination(params.static)
    return params


def preset(name: str) -> Params:
    """The parameters of a named preset of :data:`sswjax.registry.PRESETS`.

    Examples
    --------
    >>> from sswjax import preset
    >>> preset("accurate").static.optimizer
    'sgm'
    """
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    return Params().replace(**PRESETS[name].changes)


def default_params() -> Params:
    """The parameters used when none are given: the :data:`sswjax.registry.DEFAULT_PRESET`
    preset (``accurate``), chosen across data sets; ``Params()`` is the paper's method.

    Examples
    --------
    >>> from sswjax.params import default_params
    >>> default_params() == preset("accurate")
    True
    """
    return preset(DEFAULT_PRESET)


def load_params(path: str | os.PathLike) -> Params:
    """Read parameters from a JSON file written by :func:`save_params` (or by hand).

    Raises ``ValueError`` with a one-line message for a missing file, invalid JSON, unknown keys,
    wrong types or out-of-range values.
    """
    try:
        with open(path, encoding="utf-8") as handle:
            data = json.load(handle)
    except FileNotFoundError:
        raise ValueError(f"parameter file not found: {path}") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"cannot read parameter file {path}: {error}") from None
    try:
        return params_from_dict(data)
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from None


def save_params(path: str | os.PathLike, params: Params, *, provenance: Mapping | None = None) -> None:
    """Write ``params`` (and optional provenance) as JSON, atomically."""
    from sswjax.data.io import atomic_output

    data = params.to_dict()
    if provenance is not None:
        data["provenance"] = dict(provenance)
    with atomic_output(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as handle:
            json.dump(data, handle, indent=2)
            handle.write("\n")
