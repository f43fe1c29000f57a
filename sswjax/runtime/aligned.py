"""The vertical alignment of a pair that runs in windows: measured once on the whole pair.

In the graph (:mod:`sswjax.graph.alignment`) the first pass, the offset's measure and the moved
right image are part of the method. A pair matched in strips, tiles or by an engine would
measure its offset window by window, from each window's own first pass; here the first pass
runs under the same plan (windows and all), the offset is measured once on the whole pair and
the right image moved before the method's windows see it, so that every window matches the same
aligned pair.

Array conventions: images float32 ``(H, W, C)`` NumPy arrays in [0, 1]; maps ``(H, W)``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from sswjax.config import Params
from sswjax.graph import ssw_outputs
from sswjax.graph.alignment import alignment_coefficients, halved_levels

__all__ = ["aligned_separately", "execute_aligned"]


def aligned_separately(params: Params, plan) -> bool:
    """Whether :func:`execute_aligned` runs this call: ``params`` align the pair and ``plan``
    cuts it into windows (strips, tiles) or hands it to an engine."""
    return params.alignment is not None and bool(
        plan.engine is not None or plan.strip_rows or plan.tile)


@functools.partial(jax.jit, static_argnames=("limit",))
def _aligned_right(small_left, small_right, right, params: Params, disparity, rejected, *,
                   limit: int):
    """``right`` (float32 (H, W, C), the full pair's) moved by the offset measured on the halved
    pair (``small_left``, ``small_right``: float32 (h, w, C)) at the first pass's ``disparity``
    (float32 (h, w)) where it was not ``rejected`` (bool (h, w)); disparities ``0 .. limit - 1``."""
    coefficients = alignment_coefficients(small_left, small_right, params, disparity, rejected,
                                          limit=limit, scale=2 ** params.alignment.levels)
    return params.alignment.apply(right, coefficients)


def execute_aligned(execute: Callable, graph: Callable, left: np.ndarray, right: np.ndarray, *,
                    params: Params, ndisp: int, plan):
    """``execute(graph, ...)`` (:func:`sswjax.runtime.execute.execute`) on the pair aligned once.

    The first pass (``params.alignment.first_pass(params)`` on the pair halved ``levels``
    times, its map and rejected pixels from :func:`~sswjax.graph.ssw_outputs`) runs under
    ``plan``; the coefficients and the moved right image are computed on the whole pair; the
    method (``params`` without the alignment) then runs under ``plan``.

    Parameters
    ----------
    execute : callable
        :func:`sswjax.runtime.execute.execute`.
    graph : callable
        A jitted function of :mod:`sswjax.graph`.
    left, right : float32 (H, W, C)
    params : Params
        With ``alignment`` set.
    ndisp : int
    plan : ExecutionPlan

    Returns
    -------
    What ``execute(graph, ...)`` returns: numpy.ndarray (H, W) or a NamedTuple of them.
    """
    # A few array operations, op by op: the halved pair and its disparity count.
    small_left, small_right, small_ndisp, _, _ = halved_levels(
        jnp.asarray(left), jnp.asarray(right), int(ndisp), None, params.alignment.levels)
    first = execute(ssw_outputs, np.asarray(small_left), np.asarray(small_right),
                    params=params.alignment.first_pass(params), ndisp=small_ndisp, plan=plan)
    moved = _aligned_right(small_left, small_right, jnp.asarray(right), params,
                           jnp.asarray(first.disparity), jnp.asarray(first.lr_failed),
                           limit=small_ndisp)
    return execute(graph, left, np.asarray(moved), params=params.replace(alignment=None),
                   ndisp=ndisp, plan=plan)
