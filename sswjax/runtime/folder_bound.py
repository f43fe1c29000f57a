"""A bound on the bytes of a folder of files that can be made again: the least recently used go.

The stored graphs (:mod:`sswjax.runtime.stored`: each graph's trace, about 0.1 MB, and its
executable, 0.3-0.5 MB compressed) are kept in ``<compilation cache>/graphs``, one pair of files
per image size, parameters and host. XLA's own cache beside them is bounded by JAX
(:data:`sswjax.runtime.compilation.CACHE_BYTES`); this bounds the graphs the same way: a file's
modification time is its last use (:func:`touch` when read), and each time a file is written
(:func:`trim`, after a compilation of seconds) the oldest are removed until the folder is
within its bound. Another process may be reading a removed file: it reads on (POSIX), or finds
it gone and makes it again.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

__all__ = ["GRAPHS_BYTES", "touch", "trim"]

GRAPHS_BYTES = 8 << 30
"""The bound of the stored graphs' folder, 8 GiB: some 15,000 graphs."""


def touch(path: Path) -> None:
    """Mark ``path`` as used now (its modification time); a file that is gone is left so."""
    with contextlib.suppress(OSError):
        os.utime(path)


def trim(folder: Path, *, bound: int | None = None) -> list[Path]:
    """Remove the least recently used files of ``folder`` (by modification time) until their
    bytes are within ``bound`` (default :data:`GRAPHS_BYTES`); returns the removed paths.
    Hidden files (a write in progress, ``.NAME.part``) are neither counted nor removed; a
    folder that cannot be read is left as it is.

    Examples
    --------
    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> for i, name in enumerate(["old", "mid", "new"]):
    ...     _ = (folder / name).write_bytes(bytes(10))
    ...     os.utime(folder / name, (i, i))
    >>> [p.name for p in trim(folder, bound=20)]
    ['old']
    """
    try:
        entries = [(entry.stat().st_mtime, entry.stat().st_size, Path(entry.path))
                   for entry in os.scandir(folder)
                   if entry.is_file() and not entry.name.startswith(".")]
    except OSError:
        return []
    bound = GRAPHS_BYTES if bound is None else bound
    total = sum(size for _, size, _ in entries)
    removed = []
    for _, size, path in sorted(entries):
        if total <= bound:
            break
        with contextlib.suppress(OSError):
            path.unlink()
            removed.append(path)
        total -= size
    return removed
