"""A bound on the compiled graphs a process keeps alive, the least recently used dropped.

``jax.jit`` keeps every executable it compiles for the life of the process. On the CPU each
compiled graph of sswjax maps about 540 memory regions (LLVM's code and data), so a process
that meets some 120 image shapes (a folder of photos, ``evaluate`` over several data sets, a
notebook, a service) reaches the kernel's default ``vm.max_map_count`` of 65530 and dies
(LLVM's "Cannot allocate memory", then a segfault) with memory to spare. :func:`bounded`
compiles each call signature with a jitted copy of its own and keeps the :data:`LIMIT` most
recently used across every bounded function (:class:`ExecutableCache`); the least recently
used is cleared and dropped, which releases its mappings. A graph met again after its
eviction compiles again, from the persistent compilation cache when that is on
(:mod:`sswjax.runtime.compilation`; ``docs/notes/speed-and-memory.md`` measures both).

The API's entry points (:func:`sswjax.match`, :func:`sswjax.match_with_confidence`, the
batches of :mod:`sswjax.api.batch`) go through it; :func:`sswjax.ssw_disparity` called
directly is ``jax.jit``'s own and keeps what it compiles.

A call that meets a graph this process does not hold (a new image size, range or parameters)
compiles it, seconds of silence: it logs at ``INFO`` on the ``sswjax`` logger before
(:func:`compiling_message`) and after (``compiled in 6.2 s``, the call's first run included).
One whose executable is read from disk (:mod:`sswjax.runtime.stored`, a fraction of a second)
logs nothing. The package gives the logger a ``NullHandler`` only: an application sees the
lines once it configures logging (``logging.basicConfig(level=logging.INFO)``); the command
line shows them on stderr (:mod:`sswjax.cli.app`).
"""

from __future__ import annotations

import collections
import functools
import logging
import os
import time
import types
from collections.abc import Callable, Hashable, Sequence

import jax
import numpy as np

from sswjax.config import PRESETS, Params
from sswjax.runtime.stored import StoredGraph, graph_folder

__all__ = ["DEFAULT_LIMIT", "EXECUTABLES", "BoundedJit", "ExecutableCache", "bounded",
           "compiling_message"]

logging.getLogger("sswjax").addHandler(logging.NullHandler())  # a library's only handler
_LOG = logging.getLogger(__name__)

DEFAULT_LIMIT = 32
"""Compiled graphs kept alive by default (``$SSWJAX_MAX_EXECUTABLES`` changes it): about 17,000
memory mappings at 540 each, a quarter of the kernel's default limit."""


def _fresh(fn: Callable) -> Callable:
    """A new function object with ``fn``'s code, name and defaults: ``jax.jit`` of it has a
    cache of its own (dropping it frees its executables), and the compiled program is the same
    (same module name, so the persistent cache finds it)."""
    copy = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__, fn.__defaults__,
                              fn.__closure__)
    copy.__kwdefaults__ = fn.__kwdefaults__
    return functools.update_wrapper(copy, fn)


def _signature(args: tuple, kwargs: dict, static: Sequence[str]) -> Hashable:
    """What decides a compilation: the pytree structure of the traced arguments, each leaf's
    type, shape and dtype, and the static arguments' values."""
    traced = (args, {k: v for k, v in kwargs.items() if k not in static})
    leaves, treedef = jax.tree_util.tree_flatten(traced)
    kinds = tuple((type(x), np.shape(x), str(getattr(x, "dtype", ""))) for x in leaves)
    return treedef, kinds, tuple((k, kwargs[k]) for k in static if k in kwargs)


def _params_name(params: Params) -> str:
    """A preset's name, or the preset nearest ``params`` with the stages that differ (up to
    three: ``paper (segments off, aggregation changed)``), else ``custom parameters``.
    Parameters being traced (a tracer among their leaves) are not compared."""
    if any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(params)):
        return "custom parameters"
    nearest = None
    for name, entry in PRESETS.items():
        changed = [slot for slot, config in params.stages()
                   if config != getattr(entry.params, slot)]
        if nearest is None or len(changed) < len(nearest[1]):
            nearest = (name, changed)
    if nearest is None or len(nearest[1]) > 3:
        return "custom parameters"
    name, changed = nearest
    if not changed:
        return name
    words = [f"{slot} {'off' if getattr(params, slot) is None else 'changed'}"
             for slot in changed]
    return f"{name} ({', '.join(words)})"


def compiling_message(fn: Callable, args: tuple, kwargs: dict) -> str:
    """The line logged before a call compiles: what (the parameters, :func:`_params_name`),
    for which image size (``W x H`` of the first image among ``args``, a batch ``(B, H, W,
    C)`` as ``a batch of B pairs``) and range (``ndisp``); ``fn``'s name when the call holds
    no parameters.

    Examples
    --------
    >>> import numpy as np
    >>> image = np.zeros((375, 450, 3), np.float32)
    >>> compiling_message(None, (image, image), {"params": Params(), "ndisp": 64})
    'compiling paper for 450x375, ndisp 64 (first call for this shape; cached for the next)'
    """
    values = [*args, *kwargs.values()]
    params = next((value for value in values if isinstance(value, Params)), None)
    what = getattr(fn, "__name__", "a graph") if params is None else _params_name(params)
    image = next((value for value in args if len(np.shape(value)) in (2, 3, 4)), None)
    words = [what]
    if image is not None:
        shape = np.shape(image)
        height, width = (shape[1:3] if len(shape) == 4 else shape[:2])
        batch = f"a batch of {shape[0]} pairs of " if len(shape) == 4 else ""
        words.append(f"for {batch}{width}x{height}")
    if isinstance(kwargs.get("ndisp"), int):
        words[-1] += f", ndisp {kwargs['ndisp']}"
    return f"compiling {' '.join(words)} (first call for this shape; cached for the next)"


class ExecutableCache:
    """The jitted copies of the bounded functions, one per call signature, least recently used
    first; at most ``limit`` of them.

    Parameters
    ----------
    limit : int >= 1
    """

    def __init__(self, limit: int):
        self._entries: collections.OrderedDict = collections.OrderedDict()
        self.limit = limit

    @property
    def limit(self) -> int:
        """How many compiled graphs are kept; setting it evicts what is above it."""
        return self._limit

    @limit.setter
    def limit(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"the executables' limit must be an integer >= 1, got {value!r}")
        self._limit = value
        self._evict()

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, key: Hashable) -> bool:
        return key in self._entries

    def jitted(self, key: Hashable, make: Callable[[], Callable]) -> Callable:
        """The entry of ``key`` (made by ``make()`` on a miss), now the most recently used."""
        entry = self._entries.pop(key, None)
        self._entries[key] = make() if entry is None else entry
        self._evict()
        return self._entries[key]

    def clear(self) -> None:
        """Drop every entry (their executables with them)."""
        while self._entries:
            self._entries.popitem(last=False)[1].clear_cache()

    def _evict(self) -> None:
        while len(self._entries) > self._limit:
            self._entries.popitem(last=False)[1].clear_cache()


def _limit_from_environment() -> int:
    text = os.environ.get("SSWJAX_MAX_EXECUTABLES", "")
    try:
        value = int(text) if text else DEFAULT_LIMIT
    except ValueError:
        value = DEFAULT_LIMIT
    return value if value >= 1 else DEFAULT_LIMIT


EXECUTABLES = ExecutableCache(_limit_from_environment())
"""The process's cache of every bounded function (set ``EXECUTABLES.limit`` to change it)."""


class BoundedJit:
    """``jax.jit(fn, static_argnames=...)`` whose compiled graphs live in :data:`EXECUTABLES`.

    Called like the jitted function; each distinct call signature gets a jitted copy of ``fn``
    of its own, kept while it is among the most recently used. With ``stored``, and the
    persistent compilation cache on, each signature's trace is kept on disk
    (:class:`sswjax.runtime.stored.StoredGraph`), so another process skips tracing it.
    """

    def __init__(self, fn: Callable, *, static_argnames: Sequence[str],
                 cache: ExecutableCache | None = None, stored: bool = False):
        self._fn = getattr(fn, "__wrapped__", fn)  # a jitted function: the Python one under it
        self._static = tuple(static_argnames)
        self._cache = EXECUTABLES if cache is None else cache
        self._stored = stored
        functools.update_wrapper(self, self._fn)

    def _jit(self, args: tuple, kwargs: dict, announce: Callable[[], None]) -> Callable:
        """A new entry: ``jax.jit`` of a copy, or a :class:`StoredGraph`; ``announce()`` is
        called before anything is traced or compiled (not for an executable read from disk)."""
        folder = graph_folder() if self._stored else None
        if folder is None:
            announce()
            return jax.jit(_fresh(self._fn), static_argnames=self._static)
        return StoredGraph(self._fn, args, kwargs, static=self._static, folder=folder,
                           announce=announce)

    def __call__(self, *args, **kwargs):
        key = (self._fn, _signature(args, kwargs, self._static))
        if key in self._cache:
            return self._cache.jitted(key, None)(*args, **kwargs)
        started = []

        def announce() -> None:
            _LOG.info(compiling_message(self._fn, args, kwargs))
            started.append(time.perf_counter())

        jitted = self._cache.jitted(key, lambda: self._jit(args, kwargs, announce))
        result = jitted(*args, **kwargs)
        if started:
            _LOG.info("compiled in %.1f s", time.perf_counter() - started[0])
        return result


def bounded(fn: Callable, *, static_argnames: Sequence[str], stored: bool = False
            ) -> BoundedJit:
    """``fn`` (a Python function, or a ``jax.jit`` of one) jitted with its executables bounded
    by :data:`EXECUTABLES`; ``stored``: its traces kept on disk beside the persistent
    compilation cache, when that is on (:mod:`sswjax.runtime.stored`).

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> double = bounded(lambda x, *, n: x * n, static_argnames=("n",))
    >>> [float(double(jnp.ones(k), n=2).sum()) for k in (1, 2, 3)]
    [2.0, 4.0, 6.0]
    """
    return BoundedJit(fn, static_argnames=static_argnames, stored=stored)
