"""A jitted graph run under an execution plan: padded to its bucket, aligned first when the
parameters say so (one call of :func:`~sswjax.graph.align_right` on the whole pair), then in
tiles or strips (the paths carried where they can be), here or by an engine.

Array conventions: images float32 ``(H, W, C)`` NumPy arrays, C in {1, 3}, values in [0, 1];
maps ``(H, W)`` NumPy arrays.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from sswjax.config import Params
from sswjax.graph.alignment import METHODS, align_right, ssw_aligned
from sswjax.runtime.buckets import bucket_shape, pad_to_bucket
from sswjax.runtime.carried import carried_strips, in_carried_strips, unwrapped
from sswjax.runtime.executables import bounded
from sswjax.runtime.plan import ExecutionPlan, plan_tiling, pyramid_align
from sswjax.runtime.tiles import Window, in_tiles, tile_count

__all__ = ["align", "aligned_whole", "bind_graph", "execute", "graph_call", "run_windows"]

_ALIGN = bounded(align_right, static_argnames=("ndisp", "chunk"), stored=True)
_ALIGNED = bounded(ssw_aligned, static_argnames=("method", "ndisp", "chunk", "options"),
                   stored=True)
"""The alignment's graphs, alone and followed by the method, their executables bounded and
their traces stored as the entry points' (:mod:`sswjax.api.match`)."""


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


def align(left: np.ndarray, right: np.ndarray, *, params: Params, call: dict) -> np.ndarray:
    """The right image moved onto the left (:func:`~sswjax.graph.align_right`, one call on the
    whole pair as :func:`graph_call` padded it, ``call`` its keyword arguments).

    Parameters
    ----------
    left, right : float32 (H', W', C)
    params : Params
        With ``alignment`` set.
    call : dict

    Returns
    -------
    numpy.ndarray float32 (H', W', C)
    """
    moved, _ = bind_graph(_ALIGN, params, call)(jax.device_put(left), jax.device_put(right))
    return np.asarray(moved)


def aligned_whole(graph):
    """``graph`` (a method of :data:`sswjax.graph.alignment.METHODS`, jitted, bounded or with
    keyword arguments bound) preceded by the alignment in one program
    (:func:`~sswjax.graph.alignment.ssw_aligned`), called as ``graph`` is; None for another
    graph."""
    function, keywords = unwrapped(graph)
    for name, method in METHODS.items():
        if function is unwrapped(method)[0]:
            return functools.partial(_ALIGNED, method=name,
                                     options=tuple(sorted(keywords.items())))
    return None


def run_windows(graph, left: np.ndarray, right: np.ndarray, *, params: Params, call: dict,
                plan: ExecutionPlan):
    """``graph`` on the pair as :func:`graph_call` padded it, in the tiles or strips of
    ``plan`` (:func:`~sswjax.runtime.tiles.in_tiles`; the paths carried from strip to strip
    where they can be, :mod:`sswjax.runtime.carried`), in this process. An engine's
    ``execute`` has this signature.

    Parameters
    ----------
    graph : callable
        A jitted function of :mod:`sswjax.graph` returning the disparity float32 ``(H', W')``
        or a NamedTuple of ``(H', W')`` maps.
    left, right : float32 (H', W', C)
    params : Params
        Without ``alignment``.
    call : dict
        The keyword arguments of :func:`graph_call`.
    plan : ExecutionPlan
        Without an engine.

    Returns
    -------
    numpy.ndarray (H', W'), or the same NamedTuple of them
    """
    tiling = plan_tiling(plan, call["ndisp"], align=pyramid_align(params))
    if plan.carry_paths and carried_strips(graph, params, *left.shape[:2], tiling):
        return in_carried_strips(lambda function, window: bind_graph(function, params, call,
                                                                     window=window),
                                 graph, left, right, tiling, params=params, ndisp=call["ndisp"])
    return in_tiles(lambda window, *pair: bind_graph(graph, params, call, window=window)(*pair),
                    left, right, tiling)


def execute(graph, left: np.ndarray, right: np.ndarray, *, params, ndisp: int,
            plan: ExecutionPlan):
    """``graph(left, right, params=, ndisp=, chunk=[, valid_ndisp=, valid_shape=])`` under
    ``plan``: padded to its bucket (:func:`graph_call`); with ``params.alignment``, the right
    image moved first by one call of :func:`~sswjax.graph.align_right` on the whole padded
    pair (left out on a pair too small for a tile to be measured,
    ``VerticalAlignment.measurable``); then the method (``params`` without the alignment) in
    tiles or strips, here (:func:`run_windows`) or by the plan's engine (its ``execute``, the
    same signature); cropped back. A pair matched whole here runs the alignment and the method
    in one program (:func:`aligned_whole`).

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
    left, right, call = graph_call(left, right, ndisp, plan)
    run = run_windows if plan.engine is None else plan.engine.execute
    if params.alignment is not None and params.alignment.measurable((height, width)):
        tiling = plan_tiling(plan, call["ndisp"], align=pyramid_align(params))
        whole = plan.engine is None and tile_count(*left.shape[:2], tiling) == 1
        composed = aligned_whole(graph) if whole else None
        if composed is not None:
            maps = bind_graph(composed, params, call)(jax.device_put(left),
                                                      jax.device_put(right))
            return _cropped(maps, height, width)
        right = align(left, right, params=params, call=call)
    params = params.replace(alignment=None)
    maps = run(graph, left, right, params=params, call=call, plan=plan._replace(engine=None))
    return _cropped(maps, height, width)


def _cropped(maps, height: int, width: int):
    """``maps`` (a map or a NamedTuple of them) cropped to ``height x width``, as NumPy."""
    if isinstance(maps, tuple):
        return type(maps)(*(np.asarray(m)[:height, :width] for m in maps))
    return np.asarray(maps)[:height, :width]
