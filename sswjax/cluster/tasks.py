"""What runs in a worker: one pair of a folder run (read, match, write), one window of a
tiled call. Both are plain functions of picklable arguments, so Dask can send them anywhere
and run them again elsewhere when a worker dies.

A pair's task reads its images from their paths and writes its map atomically
(:func:`sswjax.data.io.write_pfm`) to its output path, both on storage the workers share; it
returns a :class:`PairOutcome`, and a failure on bad input (an unreadable image, a map that
cannot be written: ``ValueError``, ``OSError``) is an outcome too, never an exception, so Dask
does not run it again. A window's task matches two crops with a graph of :mod:`sswjax.graph`
named by :func:`graph_name` and returns the core of its maps; a chain of row strips whose
paths are carried runs as one task (:func:`match_carried`).
"""

from __future__ import annotations

import functools
import time
from typing import NamedTuple

import jax
import numpy as np

from sswjax._files import first_line
from sswjax.api.match import match
from sswjax.cluster.workers import prepare_worker
from sswjax.config import Params
from sswjax.data.io import read_image, write_pfm
from sswjax.graph import ssw_cues, ssw_disparity, ssw_outputs
from sswjax.runtime.carried import in_carried_strips, unwrapped
from sswjax.runtime.executables import bounded
from sswjax.runtime.execute import bind_graph
from sswjax.runtime.memory import MemoryEstimateError
from sswjax.runtime.plan import ExecutionPlan
from sswjax.runtime.tiles import Tiling, Window, core_of

__all__ = ["BAD_INPUT", "GRAPHS", "PairJob", "PairOutcome", "graph_name", "match_carried",
           "match_pair", "match_window"]

BAD_INPUT = (ValueError, OSError, MemoryEstimateError)
"""What a pair's task reports as its failure instead of raising (the command line's user
errors): bad files, bad values, a pair that does not fit."""

GRAPHS = {"ssw_disparity": (ssw_disparity, ("ndisp", "chunk")),
          "ssw_outputs": (ssw_outputs, ("ndisp", "chunk", "measure")),
          "ssw_cues": (ssw_cues, ("ndisp", "chunk"))}
"""The graphs a worker runs by name, with their static arguments."""

_BOUNDED: dict[str, object] = {}
"""The bounded graphs of this process, by name: their executables live in the process's cache
(:mod:`sswjax.runtime.executables`), so every task of one shape reuses one compilation."""


class PairJob(NamedTuple):
    """One pair of a folder run: its name, its images' paths and its map's path."""

    name: str
    left: str
    right: str
    output: str


class PairOutcome(NamedTuple):
    """What a pair's task gives back: its name, whether its map was written, why not (one
    line, ``""`` when it was) and the seconds it took."""

    name: str
    ok: bool
    message: str
    seconds: float


def match_pair(job: PairJob, *, ndisp: int, min_disp: int, params: Params, plan: ExecutionPlan,
               cache: str | None = None) -> PairOutcome:
    """Read a pair, match it (:func:`sswjax.match`, the memory checked before by the caller)
    and write its disparity map (float32 PFM) atomically; ``cache``: the compilation cache
    folder of the worker (:func:`~sswjax.cluster.workers.prepare_worker`)."""
    prepare_worker(cache)
    start = time.perf_counter()
    try:
        left, right = read_image(job.left), read_image(job.right)
        disparity = match(left, right, ndisp, min_disp=min_disp, params=params, plan=plan,
                          check_memory=False)
        write_pfm(job.output, disparity)
    except BAD_INPUT as error:
        return PairOutcome(job.name, False, first_line(error), time.perf_counter() - start)
    return PairOutcome(job.name, True, "", time.perf_counter() - start)


def graph_name(graph) -> tuple[str, dict]:
    """The name in :data:`GRAPHS` of a graph as :func:`sswjax.match` and its kin pass it to
    :func:`~sswjax.runtime.execute.execute` (the bounded or jitted entry point of
    :mod:`sswjax.graph`, or a ``functools.partial`` of one), and the keyword arguments bound.

    Raises ``ValueError`` for another function.

    Examples
    --------
    >>> graph_name(functools.partial(ssw_outputs, measure="pkrn"))
    ('ssw_outputs', {'measure': 'pkrn'})
    """
    function, keywords = unwrapped(graph)
    for name, (known, _) in GRAPHS.items():
        if function is unwrapped(known)[0]:
            return name, keywords
    raise ValueError(f"a Dask engine runs the graphs of sswjax.graph ({', '.join(GRAPHS)}), "
                     f"not {getattr(function, '__name__', function)!r}")


def _graph(name: str):
    """The bounded graph ``name`` of :data:`GRAPHS`, one per process."""
    if name not in _BOUNDED:
        function, static = GRAPHS[name]
        _BOUNDED[name] = bounded(function, static_argnames=static)
    return _BOUNDED[name]


def match_window(name: str, keywords: dict, left: np.ndarray, right: np.ndarray, window: Window,
                 *, params: Params, call: dict, cache: str | None = None):
    """The core of one window's maps: the graph ``name`` (with ``keywords``) on the crops
    ``left, right`` float32 ``(h, w, C)`` with the keyword arguments ``call`` of
    :func:`~sswjax.runtime.execute.graph_call`. Returns ``(window, core)``, the core NumPy
    ``(last - first, stop - start)`` maps (:func:`~sswjax.runtime.tiles.core_of`)."""
    prepare_worker(cache)
    graph = _graph(name)
    if keywords:
        graph = functools.partial(graph, **keywords)
    run = bind_graph(graph, params, call, window=window)
    maps = run(jax.device_put(left), jax.device_put(right))
    return window, core_of(window, maps)


def match_carried(name: str, keywords: dict, left: np.ndarray, right: np.ndarray,
                  tiling: Tiling, *, params: Params, call: dict, cache: str | None = None):
    """The maps of row strips with their paths carried from strip to strip
    (:func:`~sswjax.runtime.carried.in_carried_strips`): the graph ``name`` (with
    ``keywords``) on the whole pair float32 ``(H, W, C)``, a strip at a time, with the keyword
    arguments ``call`` of :func:`~sswjax.runtime.execute.graph_call`. Returns the NumPy
    ``(H, W)`` maps, as :func:`~sswjax.runtime.tiles.assemble` does."""
    prepare_worker(cache)
    graph = _graph(name)
    if keywords:
        graph = functools.partial(graph, **keywords)
    return in_carried_strips(lambda function, window: bind_graph(function, params, call,
                                                                 window=window),
                             graph, left, right, tiling, params=params, ndisp=call["ndisp"])
