"""How a call runs, apart from what it computes: the execution plan.

An :class:`ExecutionPlan` is passed beside the parameters, never inside the jitted pytree:
row strips (memory follows the strip), shape buckets (pairs of nearby sizes share a compiled
graph) and the disparity blocks of the volume's scans. :func:`execute` runs a jitted graph of
:mod:`sswjax.graph` under a plan. The memory guard (:mod:`sswjax.runtime.memory`) chooses or
refuses plans.

Array conventions: images float32 ``(H, W, C)`` NumPy arrays, C in {1, 3}, values in [0, 1];
maps ``(H, W)`` NumPy arrays.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from sswjax.config import Params
from sswjax.graph import DEFAULT_CHUNK
from sswjax.runtime.buckets import ShapeBuckets, bucket_shape, pad_to_bucket
from sswjax.runtime.strips import in_strips

__all__ = ["ExecutionPlan", "check_plan", "execute", "split_settings"]

_BOUNDS = {"strip_rows": 1_000_000, "strip_overlap": 10_000, "disparity_chunk": 100_000}


class ExecutionPlan(NamedTuple):
    """How one call of the graph is executed; none of it is a parameter of the method.

    Attributes
    ----------
    strip_rows : int
        ``R > 0``: match the pair in horizontal strips of ``R`` rows, each seen with
        ``strip_overlap`` more rows above and below (:func:`~sswjax.runtime.strips.in_strips`):
        memory follows the strip, not the image. 0 (default): the whole image at once. The
        memory guard chooses strips when the whole pair does not fit.
    strip_overlap : int
        Rows of context above and below each strip (default 32).
    buckets : ShapeBuckets or None
        Pad the pair to a bucketed shape so that pairs of nearby sizes reuse one compilation
        (results near the bottom and right borders can change slightly); None: exact shape.
    disparity_chunk : int
        K > 0 (default 4): the volume is built and folded K disparities at a time, memory for
        about ``3 K`` slices; 0: the whole volume at once. The same result either way.
    """

    strip_rows: int = 0
    strip_overlap: int = 32
    buckets: ShapeBuckets | None = None
    disparity_chunk: int = DEFAULT_CHUNK


def check_plan(plan) -> ExecutionPlan:
    """Validate an execution plan given to the API; return it unchanged.

    Raises ``TypeError`` for another type and ``ValueError`` with a one-line message naming
    the field for a bad value.
    """
    if not isinstance(plan, ExecutionPlan):
        raise TypeError(f"plan must be a sswjax.ExecutionPlan, got {type(plan).__name__}")
    for name, high in _BOUNDS.items():
        value = getattr(plan, name)
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
                or not 0 <= value <= high:
            raise ValueError(f"plan.{name} must be an integer in [0, {high}], got {value!r}")
    if plan.buckets is not None:
        if not isinstance(plan.buckets, ShapeBuckets):
            raise TypeError(f"plan.buckets must be a sswjax.ShapeBuckets, got "
                            f"{type(plan.buckets).__name__}")
        for name in ShapeBuckets._fields:
            value = getattr(plan.buckets, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"buckets.{name} must be an integer >= 1, got {value!r}")
    return plan


def split_settings(params, changes: Mapping) -> tuple[Params, ExecutionPlan]:
    """``params`` with the parameter changes of ``changes`` applied, and the plan of its
    execution names: one mapping of both, as old flat configurations (and benchmark
    ``--config`` strings) list them.

    Examples
    --------
    >>> from sswjax.config import preset
    >>> params, plan = split_settings(preset("paper"), {"strip_rows": 64, "fill_radius": 3})
    >>> plan.strip_rows, params.fill.median_radius
    (64, 3)
    """
    execution = {k: v for k, v in changes.items() if k in ExecutionPlan._fields}
    rest = {k: v for k, v in changes.items() if k not in execution}
    return params.replace(**rest), check_plan(ExecutionPlan(**execution))


def execute(graph, left: np.ndarray, right: np.ndarray, *, params, ndisp: int,
            plan: ExecutionPlan):
    """``graph(left, right, params=, ndisp=, chunk=[, valid_ndisp=])`` under ``plan``: padded
    to its bucket, in strips, cropped back.

    Parameters
    ----------
    graph : callable
        A jitted function of :mod:`sswjax.graph` returning the disparity float32 ``(H', W')``
        or a NamedTuple of ``(H', W')`` maps.
    left, right : float32 (H, W, C)
    params : Params
    ndisp : int
    plan : ExecutionPlan

    Returns
    -------
    numpy.ndarray (H, W), or the same NamedTuple of them
    """
    height, width = left.shape[:2]
    if plan.buckets is None:
        run = functools.partial(graph, params=params, ndisp=int(ndisp),
                                chunk=plan.disparity_chunk)
    else:
        padded_h, padded_w, padded_ndisp = bucket_shape(height, width, int(ndisp), plan.buckets)
        left, right = pad_to_bucket(left, right, padded_h, padded_w)
        run = functools.partial(graph, params=params, ndisp=padded_ndisp,
                                valid_ndisp=jnp.int32(ndisp), chunk=plan.disparity_chunk)
    maps = in_strips(run, left, right, rows=plan.strip_rows, overlap=plan.strip_overlap)
    if isinstance(maps, tuple):
        return type(maps)(*(m[:height, :width] for m in maps))
    return maps[:height, :width]
