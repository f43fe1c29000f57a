"""Traced graphs kept on disk (``jax.export``), so that a new process does not trace them again.

XLA's persistent compilation cache (:mod:`sswjax.runtime.compilation`) is keyed by the lowered
program, so a fresh process must still trace and lower the whole graph before it can look the
executable up: about 0.8 s for ``accurate`` on a trainingQ pair, a quarter of a warm-cache
``sswjax match``. This module keeps the lowered program itself, serialized by ``jax.export``
(StableHLO), in ``<compilation cache>/graphs``. A process that finds it deserializes it and
lowers a call to it (a fraction of the trace); XLA's cache then gives the executable.

A stored graph is keyed by everything that decides its trace (:func:`graph_key`): the sswjax
source (a digest of every module of the package, so an edited checkout never reads a graph of
other code), the versions of jax and jaxlib and the backend, the function, the pytree structure
of its traced arguments (the static options and the choice of stages of ``Params`` are pytree
structure), each leaf's shape, dtype and weak type, and the static arguments' values. Its
results are those of ``jax.jit`` of the function, bit for bit (the same StableHLO, compiled by
the same XLA; ``tests/test_stored_graphs.py``).

Nothing is stored when the compilation cache is off (:func:`graph_folder` is ``None``: the
caller then jits as usual) or when serialization is not possible (``flatbuffers`` missing, an
output type without a serialized name: the graph traced in this process is used). A damaged
file is replaced.
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import jax
import jaxlib

__all__ = ["StoredGraph", "graph_folder", "graph_key", "source_digest"]

_SUFFIX = ".jaxexport"


def graph_folder() -> Path | None:
    """Where traced graphs are stored: ``graphs`` inside JAX's persistent compilation cache
    folder (``jax_compilation_cache_dir``), or ``None`` when that cache is off."""
    cache = jax.config.jax_compilation_cache_dir
    return Path(cache) / "graphs" if cache else None


@functools.cache
def source_digest() -> str:
    """SHA-256 of the sswjax package's modules (relative path and bytes, in path order) and of
    the versions of jax and jaxlib: what a stored graph was traced from."""
    package = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256(f"jax {jax.__version__} jaxlib {jaxlib.__version__}".encode())
    for path in sorted(package.rglob("*.py")):
        digest.update(str(path.relative_to(package)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _abstract(leaf) -> jax.ShapeDtypeStruct:
    """A leaf's shape, dtype and weak type (a Python float is a weak float32 under jit)."""
    aval = jax.typeof(leaf)
    return jax.ShapeDtypeStruct(aval.shape, aval.dtype, weak_type=aval.weak_type)


def graph_key(fn: Callable, treedef, specs: Sequence[jax.ShapeDtypeStruct],
              static: dict) -> str:
    """The file name of a stored graph: a digest of :func:`source_digest`, the backend, ``fn``'s
    module and qualified name, the traced arguments' pytree structure ``treedef`` (its repr
    holds the static options of every configuration), their ``specs`` and the ``static``
    arguments' values."""
    text = "\n".join([
        source_digest(), jax.default_backend(), str(jax.config.jax_enable_x64),
        f"{fn.__module__}.{fn.__qualname__}", repr(treedef),
        ";".join(f"{spec.shape}{spec.dtype}{spec.weak_type}" for spec in specs),
        repr(sorted(static.items())),
    ])
    return f"{fn.__name__}-{hashlib.sha256(text.encode()).hexdigest()[:40]}{_SUFFIX}"


def _write_atomically(path: Path, data: bytes) -> None:
    """``data`` to ``path`` through a temporary file renamed into place (concurrent processes
    storing the same graph each write a whole file; the last rename wins)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=".", suffix=".part")
    try:
        with os.fdopen(handle, "wb") as out:
            out.write(data)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _load(path: Path):
    """The stored graph at ``path``, or ``None`` (absent, or damaged: then removed)."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    try:
        return jax.export.deserialize(bytearray(data))
    except Exception:  # noqa: BLE001 - any unreadable file: trace again and store it anew
        path.unlink(missing_ok=True)
        return None


class StoredGraph:
    """``jax.jit(fn, static_argnames=...)`` for one call signature, its trace read from (or
    written to) ``folder``.

    Parameters
    ----------
    fn : callable
        The Python function (not jitted).
    args, kwargs
        A call of the signature: their shapes, dtypes and pytree structure are the graph's.
    static : sequence of str
        The keyword arguments that are static (their values are in the graph).
    folder : Path
        Where graphs are stored (:func:`graph_folder`).

    Attributes
    ----------
    loaded : bool
        The trace was read from ``folder`` (not traced in this process).
    """

    def __init__(self, fn: Callable, args: tuple, kwargs: dict, *, static: Sequence[str],
                 folder: Path):
        fixed = {name: kwargs[name] for name in static if name in kwargs}
        leaves, self._treedef = self._flatten(args, kwargs, static)
        self._static = tuple(static)
        specs = [_abstract(leaf) for leaf in leaves]
        path = folder / graph_key(fn, self._treedef, specs, fixed)
        exported = _load(path)
        self.loaded = exported is not None
        if exported is None:
            treedef = self._treedef

            def flat(*values):
                traced_args, traced_kwargs = jax.tree_util.tree_unflatten(treedef, values)
                return fn(*traced_args, **traced_kwargs, **fixed)

            flat.__name__ = fn.__name__
            exported = jax.export.export(jax.jit(flat))(*specs)
            try:
                _write_atomically(path, bytes(exported.serialize()))
            except (ImportError, ValueError, OSError):
                pass  # flatbuffers missing, an output without a serialized name, a full disk
        call = exported.call

        def named(*values):  # XLA's cache names the entry after the function: jit_<name>-...
            return call(*values)

        named.__name__ = fn.__name__
        self._call = jax.jit(named)

    @staticmethod
    def _flatten(args: tuple, kwargs: dict, static: Sequence[str]):
        traced = (args, {k: v for k, v in kwargs.items() if k not in static})
        return jax.tree_util.tree_flatten(traced)

    def flat(self, *args, **kwargs) -> list:
        """The traced leaves of a call, in the order the stored graph takes them."""
        leaves, treedef = self._flatten(args, kwargs, self._static)
        if treedef != self._treedef:
            raise TypeError("a stored graph was called with another pytree structure")
        return leaves

    def lower(self, *args, **kwargs):
        """``jax.stages.Lowered`` of a call (its ``compile()`` takes :meth:`flat`'s leaves):
        for timing the phases of a first call."""
        return self._call.lower(*self.flat(*args, **kwargs))

    def __call__(self, *args, **kwargs):
        return self._call(*self.flat(*args, **kwargs))

    def clear_cache(self) -> None:
        """Drop the compiled executable (as ``jax.jit``'s ``clear_cache``)."""
        self._call.clear_cache()
