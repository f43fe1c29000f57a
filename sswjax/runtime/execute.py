"""A jitted graph run under an execution plan: padded to its bucket, in tiles or strips (the
paths carried where they can be), aligned once first, or handed to an engine.

Array conventions: images float32 ``(H, W, C)`` NumPy arrays, C in {1, 3}, values in [0, 1];
maps ``(H, W)`` NumPy arrays.
"""

from __future__ import annotations

import functools

import jax.numpy as jnp
import numpy as np

from sswjax.config import Params
from sswjax.runtime.aligned import aligned_separately, execute_aligned
from sswjax.runtime.buckets import bucket_shape, pad_to_bucket
from sswjax.runtime.carried import carried_strips, in_carried_strips
from sswjax.runtime.plan import ExecutionPlan, plan_tiling, pyramid_align
from sswjax.runtime.tiles import Window, in_tiles

__all__ = ["bind_graph", "execute", "graph_call"]


def graph_call(left: np.ndarray, right: np.ndarray, ndisp: int, plan: ExecutionPlan
               ) -> tuple[np.ndarray, np.ndarray, dict]:
    """The pair padded to the plan's bucket, and the graph's keyword arguments besides the
    parameters: ``ndisp`` (bucketed), ``chunk`` and, with buckets, ``valid_ndisp`` (an int)
    and ``valid_shape`` (the pair's own ``(H, W)``).

    Parameters
    ----------
    left, right : float32 (H, W, C)
    ndisp : int
    plan : ExecutionPlan

    Returns
    -------
    (float32 (H', W', C), float32 (H', W', C), dict)
    """
    if plan.buckets is None:
        return left, right, {"ndisp": int(ndisp), "chunk": plan.disparity_chunk}
    padded_h, padded_w, padded_ndisp = bucket_shape(left.shape[0], left.shape[1], int(ndisp),
                                                    plan.buckets)
    valid_shape = tuple(left.shape[:2])
    left, right = pad_to_bucket(left, right, padded_h, padded_w)
    return left, right, {"ndisp": padded_ndisp, "valid_ndisp": int(ndisp),
                         "valid_shape": valid_shape, "chunk": plan.disparity_chunk}


def bind_graph(graph, params: Params, call: dict, *, window: Window | None = None):
    """``graph`` with its parameters and the keyword arguments of :func:`graph_call` bound
    (``valid_ndisp`` as the traced int32 scalar the graph takes, ``valid_shape`` as an int32
    (2,) array, of the part of ``window`` (default: the whole image) inside it)."""
    call = dict(call)
    if "valid_ndisp" in call:
        call["valid_ndisp"] = jnp.int32(call["valid_ndisp"])
    if "valid_shape" in call:
        height, width = call["valid_shape"]
        if window is not None:
            height = min(max(height - window.top, 0), window.height)
            width = min(max(width - window.left, 0), window.width)
        call["valid_shape"] = jnp.array([height, width], jnp.int32)
    return functools.partial(graph, params=params, **call)


def execute(graph, left: np.ndarray, right: np.ndarray, *, params, ndisp: int,
            plan: ExecutionPlan):
    """``graph(left, right, params=, ndisp=, chunk=[, valid_ndisp=])`` under ``plan``: padded
    to its bucket, in tiles or strips (:func:`~sswjax.runtime.tiles.in_tiles`), cropped back;
    or by the plan's engine. A pair that is aligned (``params.alignment``) and cut into
    windows is aligned once on the whole pair first (:mod:`sswjax.runtime.aligned`); one too
    small for a tile to be measured (``VerticalAlignment.measurable``) is matched without it.

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
    if params.alignment is not None and not params.alignment.measurable(left.shape[:2]):
        # Too small for a tile to be measured: the offset is 0, and the pair is matched as
        # without the alignment (in strips, as such a method carries its paths).
        params = params.replace(alignment=None)
    if aligned_separately(params, plan):
        if plan.engine is None:
            return execute_aligned(execute, graph, left, right, params=params, ndisp=ndisp,
                                   plan=plan)
        # One session of the engine for the first pass and the windows, and the windows
        # fitted to its workers (or refused) before the first pass runs.
        with plan.engine.session() as engine:
            engine.fit(left, right, params=params.replace(alignment=None), ndisp=ndisp,
                       plan=plan._replace(engine=None))
            return execute_aligned(execute, graph, left, right, params=params, ndisp=ndisp,
                                   plan=plan._replace(engine=engine))
    if plan.engine is not None:
        return plan.engine.execute(graph, left, right, params=params, ndisp=ndisp,
                                   plan=plan._replace(engine=None))
    height, width = left.shape[:2]
    left, right, call = graph_call(left, right, ndisp, plan)
    tiling = plan_tiling(plan, call["ndisp"], align=pyramid_align(params))
    if plan.carry_paths and carried_strips(graph, params, *left.shape[:2], tiling):
        maps = in_carried_strips(lambda function, window: bind_graph(function, params, call,
                                                                     window=window),
                                 graph, left, right, tiling, params=params, ndisp=call["ndisp"])
    else:
        maps = in_tiles(lambda window: bind_graph(graph, params, call, window=window), left,
                        right, tiling, bound=True)
    if isinstance(maps, tuple):
        return type(maps)(*(m[:height, :width] for m in maps))
    return maps[:height, :width]
