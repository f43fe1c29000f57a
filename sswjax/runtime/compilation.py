"""XLA's persistent compilation cache for sswjax processes, and the repair of damaged entries.

Compiling the pipeline for a new shape takes seconds; with the cache on, a second process that
meets the same shape and parameters loads the compiled program from disk instead. JAX never
replaces an entry it cannot read (it compiles again and keeps the damaged file, warning on every
run); :func:`repairing_cache` removes such entries, so the next run writes them anew.
"""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
import zlib
from collections.abc import Iterator
from pathlib import Path

import jax
from jax.experimental.compilation_cache import compilation_cache

__all__ = ["CACHE_BYTES", "cache_settings_restored", "default_cache_dir", "damaged_entries",
           "enable_compilation_cache", "repairing_cache"]

_UNREADABLE = "Error reading persistent compilation cache entry"
"""The start of JAX's warning when an entry cannot be read."""

_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"

CACHE_BYTES = 16 << 30
"""The compilation cache's bound, 16 GiB: thousands of programs (one is 1-10 MB)."""


def default_cache_dir() -> Path:
    """``$SSWJAX_CACHE_DIR``, else ``$XDG_CACHE_HOME/sswjax/xla``, else ``~/.cache/sswjax/xla``."""
    if os.environ.get("SSWJAX_CACHE_DIR"):
        return Path(os.environ["SSWJAX_CACHE_DIR"])
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "sswjax" / "xla"


def enable_compilation_cache(*, path: str | os.PathLike | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache in ``path`` (default :func:`default_cache_dir`).

    Programs that took at least 0.5 s to compile are stored. The cache is bounded
    (:data:`CACHE_BYTES`; beyond it JAX removes the least recently used entries), which is what
    makes JAX lock the folder while it reads or writes an entry: processes sharing it (Dask
    workers, command lines run side by side) never read an entry another one is still writing. This
    sets process-wide JAX configuration, so it is called by entry points (the CLI, benchmarks,
    workers), never by library functions (the command line restores it when it returns:
    :func:`cache_settings_restored`). Returns the folder, or ``None`` when it cannot be
    created (the cache is then left off: it is an optimisation, not a requirement).
    """
    folder = Path(path) if path is not None else default_cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    _apply({"jax_compilation_cache_dir": str(folder),
            "jax_persistent_cache_min_compile_time_secs": 0.5,
            "jax_persistent_cache_min_entry_size_bytes": 0,
            "jax_compilation_cache_max_size": CACHE_BYTES})
    return folder


_SETTINGS = ("jax_compilation_cache_dir", "jax_persistent_cache_min_compile_time_secs",
             "jax_persistent_cache_min_entry_size_bytes", "jax_compilation_cache_max_size")
"""The JAX options :func:`enable_compilation_cache` sets."""


def _apply(settings: dict) -> None:
    """Set these JAX options; where one changes, JAX opens its cache anew at the next
    compilation (it reads them once: ``reset_cache`` of ``jax.experimental.compilation_cache``)."""
    changed = {name: value for name, value in settings.items()
               if getattr(jax.config, name) != value}
    for name, value in changed.items():
        jax.config.update(name, value)
    if changed:
        compilation_cache.reset_cache()


@contextlib.contextmanager
def cache_settings_restored() -> Iterator[None]:
    """After the block, JAX's persistent-cache options (:data:`_SETTINGS`) are as they were
    before it: a process that calls the command line's ``main`` goes on with its own."""
    before = {name: getattr(jax.config, name) for name in _SETTINGS}
    try:
        yield
    finally:
        _apply(before)


def _readable(data: bytes) -> bool:
    """Whether a cache entry's bytes decompress (zlib, or zstd when the package is there)."""
    if data.startswith(_ZSTD_MAGIC):
        try:
            import zstandard  # optional: JAX writes zstd only when it is installed
        except ImportError:
            return True  # cannot tell: leave it
        try:
            zstandard.ZstdDecompressor().decompress(data)
        except zstandard.ZstdError:
            return False
        return True
    try:
        zlib.decompress(data)
    except zlib.error:
        return False
    return True


def damaged_entries(folder: str | os.PathLike) -> list[Path]:
    """The entries of a cache folder that cannot be decompressed (truncated or corrupt).

    Examples
    --------
    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> (folder / "jit_f-1-cache").write_bytes(zlib.compress(b"program"))
    15
    >>> (folder / "jit_f-2-cache").write_bytes(zlib.compress(b"program")[:-4])
    11
    >>> [path.name for path in damaged_entries(folder)]
    ['jit_f-2-cache']
    """
    found = []
    for path in sorted(Path(folder).glob("*-cache")):
        try:
            data = path.read_bytes()
        except OSError:
            continue
        if not _readable(data):
            found.append(path)
    return found


@contextlib.contextmanager
def repairing_cache(folder: str | os.PathLike | None) -> Iterator[None]:
    """Within it, JAX's warning about an unreadable cache entry is replaced by the removal of
    the damaged entries of ``folder`` and one line on stderr: JAX then compiles the program
    and, the damaged file gone, stores it anew. Other warnings are shown as usual. ``None``:
    nothing is done."""
    if folder is None:
        yield
        return
    shown = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if not str(message).startswith(_UNREADABLE):
            return shown(message, category, filename, lineno, file, line)
        for path in damaged_entries(folder):
            path.unlink(missing_ok=True)
            print(f"sswjax: note: removed a damaged entry of the compilation cache ({path}); "
                  "the program is compiled and stored anew", file=sys.stderr)
        return None

    with warnings.catch_warnings():  # restores showwarning and the filters on exit
        warnings.filterwarnings("always", message=_UNREADABLE)
        warnings.showwarning = show
        yield
