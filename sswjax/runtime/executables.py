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
(:mod:`sswjax.runtime.compilation`; ``docs/speed-and-memory.md`` measures both).

The API's entry points (:func:`sswjax.match`, :func:`sswjax.match_with_confidence`, the
batches of :mod:`sswjax.api.batch`) go through it; :func:`sswjax.ssw_disparity` called
directly is ``jax.jit``'s own and keeps what it compiles.
"""

from __future__ import annotations

import collections
import functools
import logging
import os
import types
from collections.abc import Callable, Hashable, Sequence

import jax
import numpy as np

from sswjax.runtime.stored import StoredGraph, graph_folder

__all__ = ["COMPILING_UNCACHED", "DEFAULT_LIMIT", "EXECUTABLES", "BoundedJit", "ExecutableCache",
           "bounded"]

_LOG = logging.getLogger(__name__)
COMPILING_UNCACHED = ("compiling the graph for this image size and these parameters: seconds "
                      "(the compilation cache is off: again in every process)")
"""The note logged (``logging.INFO``) when a stored function meets a new signature with the
persistent cache off: the call compiles it."""

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

    def _jit(self, args: tuple, kwargs: dict) -> Callable:
        folder = graph_folder() if self._stored else None
        if folder is None:
            if self._stored:
                _LOG.info(COMPILING_UNCACHED)
            return jax.jit(_fresh(self._fn), static_argnames=self._static)
        return StoredGraph(self._fn, args, kwargs, static=self._static, folder=folder)

    def __call__(self, *args, **kwargs):
        key = (self._fn, _signature(args, kwargs, self._static))
        jitted = self._cache.jitted(key, lambda: self._jit(args, kwargs))
        return jitted(*args, **kwargs)


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
