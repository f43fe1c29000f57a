"""Row strips whose semi-global paths run on from one strip into the next.

A strip's window sees ``overlap`` rows above and below its core, and its paths along the rows
(vertical, and with 8 paths the diagonals) would start afresh at the window's edges: where the
cost says nothing (a sky, a wall), a path carries one disparity across hundreds of rows, and a
restart changes the map far inside the core (``docs/cluster.md``, "The seams, measured"). Here
each window takes its neighbours' path states instead (:mod:`sswjax.stages.paths`):

1. A sweep down the strips runs the cost, the aggregation and the optimiser of each window
   (:func:`sswjax.graph.ssw_carried`) with the forward states the window above left, and keeps
   the forward states it leaves for the window below.
2. A sweep up runs the whole graph of each window, in its seeded form
   (:func:`sswjax.graph.ssw_disparity_seeded`, :func:`~sswjax.graph.ssw_outputs_seeded`),
   with those forward states and with the backward states the window below left in this
   sweep, and keeps its core.

A seed enters ``overlap // 2`` rows into the window (where the cost is the whole image's) and
is the state the neighbour reached one row before that row, inside its own exact part. From
there on the window's paths are the whole image's, so the strips give the whole image's maps
except where a stage after the optimiser reaches from the core past that row (the fill, the
medians and the smoothing: fewer rows than the collar's half at the default 96). The price is
the first sweep, about the cost, the aggregation and the paths of every window again.

Array conventions: images float32 ``(H, W, C)`` NumPy arrays; a window's run returns a map
``(h, w)`` (or a NamedTuple of maps) and the :class:`~sswjax.stages.paths.Seeds` it leaves.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from sswjax.config import Params
from sswjax.graph import (carries_paths, ssw_carried, ssw_disparity, ssw_disparity_seeded,
                          ssw_outputs, ssw_outputs_seeded)
from sswjax.graph.volume import cost_bound
from sswjax.runtime.executables import bounded
from sswjax.runtime.tiles import Tiling, assemble, core_of, tile_windows, to_numpy
from sswjax.stages.paths import Seeds, no_seeds

__all__ = ["carried_strips", "in_carried_strips", "seed_entry", "seeded", "unwrapped"]

_LINES = bounded(ssw_carried, static_argnames=("ndisp", "chunk"))

_SEEDED = {ssw_disparity: bounded(ssw_disparity_seeded, static_argnames=("ndisp", "chunk"),
                                  stored=True),
           ssw_outputs: bounded(ssw_outputs_seeded, static_argnames=("ndisp", "chunk", "measure"),
                                stored=True)}
"""The graphs whose windows can take the seeds of carried paths, and their seeded forms."""


def unwrapped(graph: Callable) -> tuple[Callable, dict]:
    """The Python function under a graph as the API passes it (jitted, bounded, or a
    ``functools.partial`` of keyword arguments), and those keyword arguments."""
    keywords = {}
    if isinstance(graph, functools.partial) and not graph.args:
        keywords, graph = dict(graph.keywords), graph.func
    return getattr(graph, "__wrapped__", graph), keywords


def seeded(graph: Callable) -> Callable | None:
    """The seeded form of ``graph`` (:func:`~sswjax.graph.ssw_disparity_seeded` for
    :func:`~sswjax.graph.ssw_disparity`, and so on; the keyword arguments bound to ``graph``
    bound to it), returning ``(maps, carried)``; None for a graph that has none."""
    function, keywords = unwrapped(graph)
    for plain, form in _SEEDED.items():
        if function is unwrapped(plain)[0]:
            return functools.partial(form, **keywords)
    return None


def carried_strips(graph: Callable, params: Params, height: int, width: int,
                   tiling: Tiling) -> bool:
    """Whether :func:`in_carried_strips` runs this call: row strips (no columns cut) of more
    than one window, a method whose paths can be carried and a graph with a seeded form."""
    return (tiling.cols == 0 and len(tile_windows(height, width, tiling)) > 1
            and carries_paths(params) and seeded(graph) is not None)


def seed_entry(tiling: Tiling) -> int:
    """The row of a window (counted from its edge) before which a neighbour's seed enters:
    half the collar, where the cost is the whole image's.

    >>> seed_entry(Tiling(rows=256, cols=0, overlap=96, lead=64))
    48
    """
    return tiling.overlap // 2


def in_carried_strips(bind: Callable[[Callable, object], Callable], graph: Callable,
                      left: np.ndarray, right: np.ndarray, tiling: Tiling, *, params: Params,
                      ndisp: int):
    """``graph`` over the row strips of ``tiling`` with the paths carried from strip to strip
    (module docstring), the cores stitched.

    Parameters
    ----------
    bind : callable
        ``bind(function, window)``: a graph function with its parameters and keyword
        arguments bound for that :class:`~sswjax.runtime.tiles.Window`
        (:func:`sswjax.runtime.execute.bind_graph`); called ``(left, right, seeds=)``.
    graph : callable
        A graph with a seeded form (:func:`seeded`), which runs the windows.
    left, right : float32 (H, W, C)
    tiling : Tiling
        Strips (``cols == 0``).
    params : Params
        With :func:`~sswjax.graph.carries_paths`.
    ndisp : int
        Planes of the volume the graph runs (the bucketed count with buckets).

    Returns
    -------
    numpy.ndarray (H, W) of the map's dtype, or the same NamedTuple of them
    """
    graph = seeded(graph)
    height, width = left.shape[:2]
    windows = tile_windows(height, width, tiling)
    last, enter = len(windows) - 1, seed_entry(tiling)
    count, dtype = params.optimizer.seed_lines(cost_bound(params))
    zero = no_seeds((ndisp, width), count, dtype)

    def pair(window):
        rows = slice(window.top, window.top + window.height)
        return jax.device_put(left[rows]), jax.device_put(right[rows])

    def gap(k):  # rows from window k's top to window k + 1's
        return windows[k + 1].top - windows[k].top

    def steps(forward, backward):
        return jnp.array([forward, backward], jnp.int32)

    handed_down = []  # the forward states window k leaves for window k + 1
    forward = zero.forward
    for k in range(last):
        seeds = zero._replace(forward=forward, entry=steps(enter if k else 0, 0),
                              capture=steps(gap(k) + enter - 1, 0))
        forward = bind(_LINES, windows[k])(*pair(windows[k]), seeds=seeds).forward
        handed_down.append(forward)
    pieces, backward = [], zero.backward
    for k in range(last, -1, -1):
        seeds = Seeds(handed_down[k - 1] if k else zero.forward, backward,
                      steps(enter if k else 0, enter if k < last else 0),
                      steps(0, gap(k - 1) + enter - 1 if k else 0))
        maps, carried = bind(graph, windows[k])(*pair(windows[k]), seeds=seeds)
        backward = carried.backward
        pieces.append((windows[k], core_of(windows[k], to_numpy(maps))))
    return assemble(height, width, pieces)
