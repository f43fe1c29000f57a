"""The vertical alignment of a pair that runs in windows: measured once on the whole pair.

In the graph (:mod:`sswjax.graph.alignment`) the first pass, the offset's measure and the moved
right image are part of the method. A pair matched in strips, tiles or by an engine would
measure its offset window by window, from each window's own first pass; here the first pass
runs once on the halved pair, the offset is measured once on the whole pair and the right image
moved before the method's windows see it, so that every window matches the same aligned pair.

The first pass runs whole, or in carried strips (:mod:`sswjax.runtime.carried`), whatever
windows the method's plan has, when the memory model gives it no more than the method's windows
(:func:`first_pass_plan`), so that a plan the guard chose for the method holds for it too. Under
the method's own tiles its semi-global paths were cut at every tile's edge, the offsets measured
on it moved with the tiles, and so did the whole map: on the 4000 x 3000 pair of
``benchmarks/large_pair.py``, tiles of 512 and of 1024 differed at 19.6 % of the pixels when the
first pass ran in them, and at 0.31 % with it in carried strips (``docs/cluster.md``).

Array conventions: images float32 ``(H, W, C)`` NumPy arrays in [0, 1]; maps ``(H, W)``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from sswjax.config import Params
from sswjax.graph import carries_paths, ssw_outputs
from sswjax.graph.alignment import alignment_coefficients, halved_levels
from sswjax.runtime.memory import STRIP_HEIGHTS, estimate_peak_bytes, worker_peak_bytes
from sswjax.runtime.plan import ExecutionPlan
from sswjax.runtime.tiles import tilings_by_work

__all__ = ["aligned_right", "aligned_separately", "execute_aligned", "first_pass_plan"]


def aligned_separately(params: Params, plan) -> bool:
    """Whether :func:`execute_aligned` runs this call: ``params`` align the pair and ``plan``
    cuts it into windows (strips, tiles) or hands it to an engine."""
    return params.alignment is not None and bool(
        plan.engine is not None or plan.strip_rows or plan.tile)


def first_pass_plan(shape: tuple[int, int, int], small_shape: tuple[int, int, int], *,
                    ndisp: int, small_ndisp: int, params: Params,
                    plan: ExecutionPlan) -> ExecutionPlan:
    """The plan of the alignment's first pass, on the halved pair, of a pair matched in
    windows under ``plan``.

    The first plan whose estimate (:func:`~sswjax.runtime.memory.estimate_peak_bytes`, or
    under an engine :func:`~sswjax.runtime.memory.worker_peak_bytes`) is at most the method's
    under ``plan``, among: the whole halved pair; then its carried strips, when ``plan``
    carries paths and the first pass has them, in the memory guard's order
    (:func:`~sswjax.runtime.tiles.tilings_by_work`: the plan's collar, then the fewest computed
    pixels). None: ``plan`` itself (its windows then cut the first pass's paths). The plan's
    engine, buckets, disparity blocks and collar are kept.

    Parameters
    ----------
    shape, small_shape : (int, int, int)
        ``(H, W, C)`` of the pair and of the pair halved ``params.alignment.levels`` times.
    ndisp, small_ndisp : int
        Their disparity counts.
    params : Params
        The method's, with ``alignment`` set.
    plan : ExecutionPlan
        The method's.

    Returns
    -------
    ExecutionPlan

    Examples
    --------
    >>> from sswjax.config import preset
    >>> first_pass_plan((1988, 2964, 3), (994, 1482, 3), ndisp=280, small_ndisp=141,
    ...                 params=preset("accurate"), plan=ExecutionPlan(strip_rows=512))
    ExecutionPlan(strip_rows=0, strip_overlap=96, buckets=None, disparity_chunk=4, tile=0, \
engine=None, carry_paths=True)
    """
    estimator = worker_peak_bytes if plan.engine is not None else estimate_peak_bytes
    local = plan._replace(engine=None)
    bound = estimator(*shape[:2], ndisp, params=params, plan=local, channels=shape[2])
    first = params.alignment.first_pass(params)
    height, width, channels = small_shape
    trials = [local._replace(strip_rows=0, tile=0)]
    if plan.carry_paths and carries_paths(first):
        trials += [local._replace(strip_rows=tiling.rows, tile=0, strip_overlap=tiling.overlap)
                   for tiling in tilings_by_work(height, width, lead=small_ndisp,
                                                 overlap=plan.strip_overlap, tile_sizes=(),
                                                 strip_heights=STRIP_HEIGHTS, carried=True)]
    for trial in trials:
        if estimator(height, width, small_ndisp, params=first, plan=trial,
                     channels=channels) <= bound:
            return trial._replace(engine=plan.engine)
    return plan


@functools.partial(jax.jit, static_argnames=("limit",))
def _moved_right(small_left, small_right, right, params: Params, disparity, rejected, *,
                 limit: int):
    """``right`` (float32 (H, W, C), the full pair's) moved by the offset measured on the halved
    pair (``small_left``, ``small_right``: float32 (h, w, C)) at the first pass's ``disparity``
    (float32 (h, w)) where it was not ``rejected`` (bool (h, w)); disparities ``0 .. limit - 1``."""
    coefficients = alignment_coefficients(small_left, small_right, params, disparity, rejected,
                                          limit=limit, scale=2 ** params.alignment.levels)
    return params.alignment.apply(right, coefficients)


def aligned_right(execute: Callable, left: np.ndarray, right: np.ndarray, *, params: Params,
                  ndisp: int, plan) -> np.ndarray:
    """``right`` moved onto ``left`` by the offset measured once on the whole pair.

    The first pass (``params.alignment.first_pass(params)`` on the pair halved ``levels``
    times, its map and rejected pixels from :func:`~sswjax.graph.ssw_outputs`) runs under
    :func:`first_pass_plan` of ``plan``, by ``execute``
    (:func:`sswjax.runtime.execute.execute`); the coefficients and the moved image are
    computed on the whole pair.

    Parameters
    ----------
    execute : callable
    left, right : float32 (H, W, C)
    params : Params
        With ``alignment`` set.
    ndisp : int
    plan : ExecutionPlan
        The method's.

    Returns
    -------
    numpy.ndarray float32 (H, W, C)
    """
    # A few array operations, op by op: the halved pair and its disparity count.
    small_left, small_right, small_ndisp, _, _ = halved_levels(
        jnp.asarray(left), jnp.asarray(right), int(ndisp), None, params.alignment.levels)
    first_plan = first_pass_plan(left.shape, small_left.shape, ndisp=int(ndisp),
                                 small_ndisp=small_ndisp, params=params, plan=plan)
    first = execute(ssw_outputs, np.asarray(small_left), np.asarray(small_right),
                    params=params.alignment.first_pass(params), ndisp=small_ndisp,
                    plan=first_plan)
    return np.asarray(_moved_right(small_left, small_right, jnp.asarray(right), params,
                                   jnp.asarray(first.disparity), jnp.asarray(first.lr_failed),
                                   limit=small_ndisp))


def execute_aligned(execute: Callable, graph: Callable, left: np.ndarray, right: np.ndarray, *,
                    params: Params, ndisp: int, plan):
    """``execute(graph, ...)`` (:func:`sswjax.runtime.execute.execute`) on the pair aligned once
    (:func:`aligned_right`): the method (``params`` without the alignment) runs under ``plan``
    on ``left`` and the moved right image.

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
    moved = aligned_right(execute, left, right, params=params, ndisp=ndisp, plan=plan)
    return execute(graph, left, moved, params=params.replace(alignment=None), ndisp=ndisp,
                   plan=plan)
