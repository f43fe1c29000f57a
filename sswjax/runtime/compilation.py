"""XLA's persistent compilation cache for sswjax processes.

Compiling the pipeline for a new shape takes seconds; with the cache on, a second process that
meets the same shape and parameters loads the compiled program from disk instead.
"""

from __future__ import annotations

import os
from pathlib import Path

import jax


def default_cache_dir() -> Path:
    """``$SSWJAX_CACHE_DIR``, else ``$XDG_CACHE_HOME/sswjax/xla``, else ``~/.cache/sswjax/xla``."""
    if os.environ.get("SSWJAX_CACHE_DIR"):
        return Path(os.environ["SSWJAX_CACHE_DIR"])
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "sswjax" / "xla"


def enable_compilation_cache(*, path: str | os.PathLike | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache in ``path`` (default :func:`default_cache_dir`).

    Programs that took at least 0.5 s to compile are stored. This sets process-wide JAX
    configuration, so it is called by entry points (the CLI, benchmarks), never by library
    functions. Returns the folder, or ``None`` when it cannot be created (the cache is then
    left off: it is an optimisation, not a requirement).
    """
    folder = Path(path) if path is not None else default_cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return folder
