"""Traced graphs and their executables kept on disk, so that a new process neither traces,
lowers nor compiles them again.

XLA's persistent compilation cache (:mod:`sswjax.runtime.compilation`) is keyed by the lowered
program, so a fresh process must still trace and lower the whole graph before it can look the
executable up: about 0.8 s for ``accurate`` on a trainingQ pair, a quarter of a warm-cache
``sswjax match``. This module keeps two files per graph in ``<compilation cache>/graphs``:

- the lowered program, serialized by ``jax.export`` (StableHLO, ``.jaxexport``): a process that
  finds it deserializes it and lowers a call to it (a fraction of the trace); XLA's cache then
  gives the executable;
- the compiled executable itself (``.xlaexec``, :mod:`jax.experimental.serialize_executable`),
  written by the process in which XLA compiled it (not read it from XLA's cache:
  :func:`compile_lowered`), keyed further by the host
  (:func:`~sswjax.runtime.graph_keys.host_digest`: the backend and its version, the devices, ``XLA_FLAGS`` and the CPU's model and instruction sets, which XLA
  compiles for): a process that finds it loads it directly, and skips the lowering as well
  (0.1-0.2 s of a warm first call). ``SSWJAX_STORE_EXECUTABLES=0`` turns this off
  (:func:`executables_stored`). A test worker once crashed (a segmentation fault) in the first
  run of such an executable: it called LAPACK (the ``plane`` fill solves with it) and nothing
  in that process had registered LAPACK's kernels, which lowering a call does. The file says
  whether its executable calls LAPACK (:func:`calls_lapack`), and the kernels are
  registered before it is loaded (:func:`register_lapack`). The executable is compressed
  (zlib: 1.8 MB to 0.33 MB for ``accurate`` on a trainingQ pair, 4 ms to expand). It is used
  for calls on concrete arrays of the default device; a call under a transformation (a tracer
  among the arguments) or with arrays on another device goes through the lowered program as
  above. The first run
  of a loaded executable waits for its result, so that one that fails to run is removed and
  the call goes through the lowered program. The file is a pickle that loads machine code:
  like XLA's own cache, the folder must be one only trusted users write to.

A stored graph is keyed by everything that decides its trace
(:func:`~sswjax.runtime.graph_keys.graph_key`): the sswjax source (a digest of every module of the package, so an edited checkout never reads a graph of
other code), the versions of jax and jaxlib and the backend, the function, the pytree structure
of its traced arguments (the static options and the choice of stages of ``Params`` are pytree
structure), each leaf's shape, dtype and weak type, and the static arguments' values. Its
results are those of ``jax.jit`` of the function, bit for bit (the same StableHLO, compiled by
the same XLA; ``tests/test_stored_graphs.py``).

Nothing is stored when the compilation cache is off (:func:`graph_folder` is ``None``: the
caller then jits as usual) or when serialization is not possible (``flatbuffers`` missing, an
output type without a serialized name: the graph traced in this process is used). A damaged
file is replaced. The folder is bounded, the least recently used files removed first
(:mod:`sswjax.runtime.folder_bound`, 8 GiB).
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
import tempfile
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
from jax.experimental import serialize_executable

from sswjax.runtime.folder_bound import touch, trim
from sswjax.runtime.graph_keys import graph_key, host_digest

__all__ = ["StoredGraph", "calls_lapack", "compile_lowered", "executables_stored", "graph_folder",
           "register_lapack"]

_EXECUTABLE_SUFFIX = ".xlaexec"


def executables_stored() -> bool:
    """Whether compiled executables are stored and read: yes, unless
    ``SSWJAX_STORE_EXECUTABLES=0`` (the traces and XLA's own cache are used either way)."""
    return os.environ.get("SSWJAX_STORE_EXECUTABLES", "1") != "0"


def graph_folder() -> Path | None:
    """Where traced graphs are stored: ``graphs`` inside JAX's persistent compilation cache
    folder (``jax_compilation_cache_dir``), or ``None`` when that cache is off."""
    cache = jax.config.jax_compilation_cache_dir
    return Path(cache) / "graphs" if cache else None


def _abstract(leaf) -> jax.ShapeDtypeStruct:
    """A leaf's shape, dtype and weak type (a Python float is a weak float32 under jit)."""
    aval = jax.typeof(leaf)
    return jax.ShapeDtypeStruct(aval.shape, aval.dtype, weak_type=aval.weak_type)


def _write_atomically(path: Path, data: bytes) -> None:
    """``data`` to ``path`` through a temporary file renamed into place (concurrent processes
    each write a whole file; the last rename wins), then the folder trimmed to its bound."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=".", suffix=".part")
    try:
        with os.fdopen(handle, "wb") as out:
            out.write(data)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    trim(path.parent)


def _load(path: Path, read: Callable):
    """``read(bytes)`` of the file at ``path``, marked used now; ``None`` if absent or damaged."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    try:
        value = read(data)
    except Exception:  # noqa: BLE001 - any unreadable file: made again and stored anew
        path.unlink(missing_ok=True)
        return None
    touch(path)
    return value


def calls_lapack(exported: jax.export.Exported) -> bool:
    """Whether the module of ``exported`` calls a LAPACK kernel (a custom call whose target
    starts with ``lapack_``, as jaxlib names them; ``jnp.linalg``, the ``plane`` fill); a module
    that cannot be read says True.

    Examples
    --------
    >>> spec = jax.ShapeDtypeStruct((3, 3), jnp.float32)
    >>> calls_lapack(jax.export.export(jax.jit(lambda a: a @ a))(spec))
    False
    >>> calls_lapack(jax.export.export(jax.jit(jnp.linalg.inv))(spec))
    True
    """
    try:
        text = exported.mlir_module()
    except Exception:  # noqa: BLE001 - unreadable: register the kernels
        return True
    return "lapack_" in text


@functools.cache
def register_lapack() -> None:
    """Register LAPACK's kernels in this process, as lowering a call to one does (it lowers
    one, ``jnp.linalg.inv`` of a 1 x 1 matrix; nothing is compiled), once per process. An
    executable loaded from a file that calls them, where nothing registered them, dies on its
    first run with a segmentation fault."""
    jax.jit(jnp.linalg.inv).lower(jax.ShapeDtypeStruct((1, 1), jnp.float32))


def _flagged(lapack: bool, body: bytes) -> bytes:
    """``L`` if the program calls LAPACK (:func:`calls_lapack`), else ``N``, then ``body``."""
    return (b"L" if lapack else b"N") + body


def _unflagged(data: bytes) -> tuple[bool, bytes]:
    """Whether a file of :func:`_flagged` calls LAPACK, and its body."""
    if data[:1] not in (b"L", b"N"):
        raise ValueError("not a stored graph file")
    return data[:1] == b"L", data[1:]


def _read_graph(data: bytes) -> tuple[jax.export.Exported, bool]:
    """The trace of a file ``_flagged(lapack, exported.serialize())``, and ``lapack``."""
    lapack, body = _unflagged(data)
    return jax.export.deserialize(bytearray(body)), lapack


def _executable_bytes(compiled: jax.stages.Compiled, lapack: bool) -> bytes:
    """The file of an executable: the SHA-256 of the rest, then :func:`_flagged` the zlib
    of the pickle of ``serialize_executable.serialize(compiled)`` (its code and trees)."""
    data = _flagged(lapack, zlib.compress(pickle.dumps(serialize_executable.serialize(compiled))))
    return hashlib.sha256(data).digest() + data


def _read_executable(data: bytes) -> jax.stages.Compiled:
    """The executable of a file of :func:`_executable_bytes` on the default device, LAPACK's
    kernels registered first if it calls them (without, its first run is a segmentation
    fault); a damaged file (digest) raises before any byte is unpickled."""
    digest, data = data[:32], data[32:]
    if hashlib.sha256(data).digest() != digest:
        raise ValueError("a damaged stored executable")
    lapack, body = _unflagged(data)
    if lapack:
        register_lapack()
    payload, in_tree, out_tree = pickle.loads(zlib.decompress(body))
    return serialize_executable.deserialize_and_load(
        payload, in_tree, out_tree, execution_devices=jax.devices()[:1])


def compile_lowered(lowered: jax.stages.Lowered) -> tuple[jax.stages.Compiled, bool]:
    """``lowered.compile()``, and whether XLA compiled it in this call: False when it came from
    XLA's persistent cache (the ``/jax/compilation_cache/cache_hits`` event of
    :mod:`jax.monitoring`, listened to during the call only). On jaxlib 0.10.2 an executable
    read from that cache serializes without some of its fused functions, and running what it
    serialized to fails (``NOT_FOUND: Function ... not found``); a fresh one is whole."""
    hits = []

    def listen(event: str, **_) -> None:
        if event == "/jax/compilation_cache/cache_hits":
            hits.append(event)

    jax.monitoring.register_event_listener(listen)
    try:
        compiled = lowered.compile()
    finally:
        jax.monitoring.unregister_event_listener(listen)
    return compiled, not hits


def _runs_here(leaves: Sequence, device) -> bool:
    """Whether a stored executable can take these leaves: no tracer among them, and every
    array on ``device`` (NumPy arrays and Python numbers go to the default device)."""
    return all(not isinstance(leaf, jax.core.Tracer) and
               (not isinstance(leaf, jax.Array) or leaf.devices() == {device})
               for leaf in leaves)


class StoredGraph:
    """``jax.jit(fn, static_argnames=...)`` for one call signature, its trace and its executable
    read from (or written to) ``folder``.

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
    announce : callable, optional
        Called (no arguments) before the graph is traced or compiled, i.e. unless its
        executable is read from ``folder``: the caller's "compiling" log line.

    Attributes
    ----------
    loaded : bool
        The executable or the trace was read from ``folder`` (nothing traced in this process).
    executable_loaded : bool
        The executable was read from ``folder`` (nothing lowered or compiled either).
    """

    def __init__(self, fn: Callable, args: tuple, kwargs: dict, *, static: Sequence[str],
                 folder: Path, announce: Callable[[], None] | None = None):
        self._fn = fn
        self._fixed = {name: kwargs[name] for name in static if name in kwargs}
        leaves, self._treedef = self._flatten(args, kwargs, static)
        self._static = tuple(static)
        self._specs = [_abstract(leaf) for leaf in leaves]
        self._path = folder / graph_key(fn, self._treedef, self._specs, self._fixed)
        self._executable_path = self._path.with_name(
            f"{self._path.stem}-{host_digest()[:16]}{_EXECUTABLE_SUFFIX}"
        ) if executables_stored() else None
        self._device = jax.devices()[0]
        self._call, self._compiled, self._trace_read, self._lapack = None, None, False, True
        self.executable_loaded = self._read_executable()
        if not self.executable_loaded:
            if announce is not None:
                announce()
            self._traced()
        self.loaded = self.executable_loaded or self._trace_read

    def _read_executable(self) -> bool:
        """Take the stored executable, if there is a readable one; it is unproven until its
        first run (:meth:`__call__`)."""
        self._compiled = None if self._executable_path is None else _load(
            self._executable_path, _read_executable)
        self._unproven = self._compiled is not None
        return self._unproven

    def _traced(self) -> Callable:
        """The jitted call of the stored trace (read, or traced here and stored), made once."""
        if self._call is not None:
            return self._call
        stored = _load(self._path, _read_graph)
        self._trace_read = stored is not None
        if stored is not None:
            exported, self._lapack = stored
        else:
            treedef, fixed, fn = self._treedef, self._fixed, self._fn

            def flat(*values):
                traced_args, traced_kwargs = jax.tree_util.tree_unflatten(treedef, values)
                return fn(*traced_args, **traced_kwargs, **fixed)

            flat.__name__ = fn.__name__
            exported = jax.export.export(jax.jit(flat))(*self._specs)
            self._lapack = calls_lapack(exported)
            try:
                _write_atomically(self._path, _flagged(self._lapack, bytes(exported.serialize())))
            except (ImportError, ValueError, OSError):
                pass  # flatbuffers missing, an output without a serialized name, a full disk
        call = exported.call

        def named(*values):  # XLA's cache names the entry after the function: jit_<name>-...
            return call(*values)

        named.__name__ = self._fn.__name__
        self._call = jax.jit(named)
        return self._call

    def _through_trace(self, leaves: Sequence, *, lower: bool = False):
        """Call (or with ``lower``, lower) the jitted stored trace on ``leaves``."""
        call = self._traced()
        return call.lower(*leaves) if lower else call(*leaves)

    def _executable(self, leaves: Sequence) -> jax.stages.Compiled:
        """The compiled graph: kept, else read from ``folder``, else lowered and compiled
        (through XLA's persistent cache) and stored when XLA compiled it here."""
        if self._compiled is None and not self._read_executable():
            compiled, fresh = compile_lowered(self._through_trace(leaves, lower=True))
            self.keep(compiled, fresh=fresh)
        return self._compiled

    def keep(self, compiled: jax.stages.Compiled, *, fresh: bool) -> None:
        """Make ``compiled`` (of :meth:`lower`, through :func:`compile_lowered`) the signature's
        executable, and store it in ``folder`` if ``fresh`` (compiled by XLA in this process:
        one read from XLA's persistent cache serializes without some of its functions). Nothing
        is stored where the backend cannot serialize it or the disk refuses: it is compiled
        again in the next process."""
        self._compiled, self._unproven = compiled, False
        if not fresh or self._executable_path is None:
            return
        try:
            _write_atomically(self._executable_path,
                              _executable_bytes(compiled, self._lapack))
        except (ValueError, TypeError, NotImplementedError, pickle.PicklingError, OSError):
            pass

    def compiled(self, *args, **kwargs) -> jax.stages.Compiled:
        """The executable of a call (kept, read from ``folder``, or compiled and stored); it
        takes :meth:`flat`'s leaves."""
        return self._executable(self.flat(*args, **kwargs))

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
        """``jax.stages.Lowered`` of a call through the stored trace (its ``compile()`` takes
        :meth:`flat`'s leaves): for timing the phases of a first call."""
        return self._through_trace(self.flat(*args, **kwargs), lower=True)

    def __call__(self, *args, **kwargs):
        leaves = self.flat(*args, **kwargs)
        if not _runs_here(leaves, self._device):
            return self._through_trace(leaves)
        compiled = self._executable(leaves)
        if not self._unproven:
            return compiled(*leaves)
        # The first run of an executable read from a file waits for its result: one that
        # lacks a function fails there (XLA's NOT_FOUND), and is then removed and replaced by
        # the trace's; any other error is raised again by that second run.
        self._unproven = False
        try:
            return jax.block_until_ready(compiled(*leaves))
        except jax.errors.JaxRuntimeError:
            self._compiled = None
            self._executable_path.unlink(missing_ok=True)
            return self._through_trace(leaves)

    def clear_cache(self) -> None:
        """Drop the compiled executable (as ``jax.jit``'s ``clear_cache``)."""
        self._compiled = None
        if self._call is not None:
            self._call.clear_cache()
