"""The NumPy front door: check a user's pair, plan the call, run the jitted graph.

Array conventions (whole module): user images are NumPy-like ``(H, W)`` or ``(H, W, 1|3|4)``
arrays of uint8, uint16 or floats in [0, 1] (:mod:`sswjax.api.images`); results come back as
NumPy ``(H, W)`` maps, the disparity float32 in pixels.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from sswjax.api.auto_range import estimate_range
from sswjax.api.images import checked_images, checked_pair
from sswjax.api.ranges import check_disparity_range, from_range_frame, range_frame
from sswjax.config import Params, check_params, default_params
from sswjax.graph import ssw_disparity, ssw_outputs
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.runtime.executables import bounded
from sswjax.runtime.execute import execute
from sswjax.runtime.memory import plan_for_memory
from sswjax.runtime.plan import ExecutionPlan, check_plan
from sswjax.stages.confidence import DEFAULT_MEASURE, DEFAULT_THRESHOLD, MEASURES, validity_mask

__all__ = ["Matched", "match", "match_graph", "match_with_confidence", "resolve_plan"]

_DISPARITY = bounded(ssw_disparity, static_argnames=("ndisp", "chunk"), stored=True)
_OUTPUTS = bounded(ssw_outputs, static_argnames=("ndisp", "chunk", "measure"), stored=True)
"""The graphs of the entry points, their executables bounded (:mod:`sswjax.runtime.executables`)
and, with the compilation cache on, their traces stored (:mod:`sswjax.runtime.stored`)."""


def match(
    left, right, ndisp: int | None, *, min_disp: int = 0, params: Params | None = None,
    buckets: ShapeBuckets | None = None, plan: ExecutionPlan | None = None,
    check_memory: bool = True,
) -> np.ndarray:
    """Dense disparity map of a rectified stereo pair with the SSW method.

    Parameters
    ----------
    left, right : array_like (H, W) or (H, W, 1|3|4), uint8, uint16 or float in [0, 1]
        Rectified pair; the left image is the reference view.
    ndisp : int or None
        Disparities searched: 0 .. ndisp - 1 (Middlebury ``calib.txt`` ``ndisp``); 1 <= ndisp < W.
        None: the range (``min_disp`` too) is estimated from a coarse pass over the pair
        (:func:`sswjax.api.auto_range.estimate_range`; call it to see the range it picks).
    min_disp : int, optional
        First disparity searched (default 0; may be negative): the range is ``min_disp ..
        min_disp + ndisp - 1`` and must meet ``-(W - 1) .. W - 1`` (see :mod:`sswjax.api.ranges`).
    params : Params, optional
        Defaults to the ``accurate`` preset (:func:`sswjax.config.default_params`; the paper's
        method is ``sswjax.preset("paper")``, which is ``Params()``); see
        :func:`sswjax.load_params`.
    buckets : ShapeBuckets, optional
        Pad the pair to a bucketed shape so that pairs of nearby sizes reuse one compilation
        (results near the bottom and right borders can change slightly); default: exact shape.
        The same as ``plan=ExecutionPlan(buckets=...)``.
    plan : ExecutionPlan, optional
        How the call runs: strips, buckets, disparity blocks (default ``ExecutionPlan()``).
    check_memory : bool
        Before running, compare the estimated peak memory of the call
        (:func:`sswjax.runtime.memory.estimate_peak_bytes`) with the available memory: strips
        are chosen when the whole pair does not fit and the plan has none, and
        :class:`sswjax.runtime.memory.MemoryEstimateError` (a ``MemoryError``) is raised when
        nothing fits (default); ``False`` runs the plan as given.

    Returns
    -------
    numpy.ndarray, float32 (H, W)
        Disparity of every left pixel in pixels (dense, no invalid values).

    Examples
    --------
    >>> import numpy as np, sswjax
    >>> rng = np.random.default_rng(0)
    >>> right = rng.random((40, 64, 3), dtype=np.float32)
    >>> left = np.roll(right, 5, axis=1)          # the scene moved 5 px: disparity 5
    >>> d = sswjax.match(left, right, ndisp=16)
    >>> round(float(np.median(d[:, 16:])), 2)
    5.0
    """
    return match_graph(left, right, ndisp, graph=_DISPARITY, min_disp=min_disp, params=params,
                       buckets=buckets, plan=plan, check_memory=check_memory)


class Matched(NamedTuple):
    """What :func:`match_with_confidence` returns, all NumPy ``(H, W)``.

    Attributes
    ----------
    disparity : float32
        The dense map of :func:`match` (filled values included).
    confidence : float32 in [0, 1]
        Higher = more reliable (:mod:`sswjax.stages.confidence`).
    validity : uint8
        Bit mask, 0 = valid: bit 0 (1) failed the checks and filled, bit 1 (2) left band
        (``x - d < 0``: no match in the right image), bit 2 (4) confidence below the
        threshold.
    """

    disparity: np.ndarray
    confidence: np.ndarray
    validity: np.ndarray


def match_with_confidence(
    left, right, ndisp: int | None, *, min_disp: int = 0, params: Params | None = None,
    buckets: ShapeBuckets | None = None, plan: ExecutionPlan | None = None,
    check_memory: bool = True, low_confidence: float = DEFAULT_THRESHOLD,
    measure: str = DEFAULT_MEASURE,
) -> Matched:
    """:func:`match` with the confidence and the validity bits of every pixel.

    One run of the jitted graph (:func:`sswjax.graph.ssw_outputs`); the disparity is
    bit-identical to :func:`match`'s with the same options.

    Parameters
    ----------
    left, right, ndisp, min_disp, params, buckets, plan, check_memory
        As for :func:`match`.
    low_confidence : float in [0, 1]
        Confidence below it sets validity bit 2 (default
        :data:`sswjax.stages.confidence.DEFAULT_THRESHOLD`; 0 never sets it).
    measure : str
        Confidence measure, a key of :data:`sswjax.stages.confidence.MEASURES`.

    Returns
    -------
    Matched
        disparity float32 (H, W), confidence float32 (H, W), validity uint8 (H, W).

    Examples
    --------
    >>> import numpy as np, sswjax
    >>> rng = np.random.default_rng(0)
    >>> right = rng.random((40, 64, 3), dtype=np.float32)
    >>> left = np.roll(right, 5, axis=1)
    >>> out = sswjax.match_with_confidence(left, right, ndisp=16)
    >>> round(float(np.median(out.disparity[:, 16:])), 2)
    5.0
    >>> float(((out.validity[:, :4] & 2) > 0).mean()) > 0.9   # bit 1: no match left of x = d
    True
    """
    if measure not in MEASURES:
        raise ValueError(f"unknown confidence measure {measure!r}; choose from {', '.join(MEASURES)}")
    if isinstance(low_confidence, bool) or not isinstance(low_confidence, (int, float, np.floating)) \
            or not 0.0 <= float(low_confidence) <= 1.0:
        raise ValueError(f"low_confidence must be a number in [0, 1], got {low_confidence!r}")
    outputs = match_graph(left, right, ndisp, graph=functools.partial(_OUTPUTS, measure=measure),
                          min_disp=min_disp, params=params, buckets=buckets, plan=plan,
                          check_memory=check_memory)
    validity = validity_mask(outputs.disparity, outputs.confidence, outputs.lr_failed,
                             threshold=float(low_confidence), ambiguous=outputs.ambiguous)
    return Matched(outputs.disparity, outputs.confidence, np.asarray(validity))


def resolve_plan(plan: ExecutionPlan | None, buckets: ShapeBuckets | None) -> ExecutionPlan:
    """The checked plan of a call from its ``plan`` and ``buckets`` arguments."""
    plan = ExecutionPlan() if plan is None else check_plan(plan)
    if buckets is not None:
        if plan.buckets is not None and plan.buckets != buckets:
            raise ValueError("buckets and plan.buckets differ: give the buckets once")
        plan = check_plan(plan._replace(buckets=buckets))
    return plan


def match_graph(left, right, ndisp, *, graph, min_disp: int = 0, params: Params | None = None,
                buckets: ShapeBuckets | None = None, plan: ExecutionPlan | None = None,
                check_memory: bool = True):
    """The one body of :func:`match` and :func:`match_with_confidence`, for any graph: check
    the pair, move it to the range's frame, plan the call (strips if memory is short), run
    ``graph`` under the plan, and map the result back.

    Parameters
    ----------
    left, right, ndisp, min_disp, params, buckets, plan, check_memory
        As for :func:`match`.
    graph : callable
        A jitted function of :mod:`sswjax.graph` (``graph(left, right, params=, ndisp=,
        chunk=[, valid_ndisp=])``) returning the disparity float32 ``(H', W')`` or a
        NamedTuple of maps whose first is the disparity.

    Returns
    -------
    The same structure as ``graph``'s, every map NumPy ``(H, W)`` in the pair's frame (only
    the disparity is shifted by ``min_disp``).
    """
    params = default_params() if params is None else check_params(params)
    plan = resolve_plan(plan, buckets)
    if ndisp is None:  # estimated: sswjax.api.auto_range
        if min_disp:
            raise ValueError("min_disp goes with a count of disparities: ndisp=None estimates "
                             "both")
        checked_images(left, right, params)  # a pair too small is refused as such, first
        min_disp, ndisp = estimate_range(left, right)
    left, right = checked_pair(left, right, ndisp, params)
    check_disparity_range(left.shape[1], ndisp, min_disp)
    true_width = left.shape[1]
    left, right = range_frame(left, right, min_disp=min_disp)
    height, width = left.shape[:2]
    if check_memory:
        plan = plan_for_memory(height, width, int(ndisp), params=params, plan=plan,
                               channels=left.shape[-1])
    maps = execute(graph, left, right, params=params, ndisp=int(ndisp), plan=plan)
    if not isinstance(maps, tuple):
        return from_range_frame(maps, min_disp=min_disp, width=true_width)
    # The range's frame widens the pair by P = max(-min_disp, 0) columns on the left.
    pad = max(-int(min_disp), 0)
    return type(maps)(from_range_frame(maps[0], min_disp=min_disp, width=true_width),
                      *(m[:, pad:pad + true_width] for m in maps[1:]))
