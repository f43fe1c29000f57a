"""Errors and atomic writes for user files: the two guarantees every reader and writer gives.

Every problem with a user-supplied file (missing, unreadable, corrupt, truncated, not
writable) raises :class:`InputError`, a ``ValueError`` with a one-line message naming the file;
:func:`first_line` is how a one-line message shows an underlying exception. Writers go through
:func:`atomic_output`: the output either keeps its old content or gets the complete new one.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["InputError", "atomic_output", "first_line", "reason"]


class InputError(ValueError):
    """A user file is missing, unreadable, corrupt or truncated (or cannot be written)."""


def _read_umask() -> int:
    umask = os.umask(0)  # the only portable way to read it; done once, at import
    os.umask(umask)
    return umask


# mkstemp creates files as 0o600; outputs get what a plain open(path, "w") would give.
_FILE_MODE = 0o666 & ~_read_umask()


def first_line(error: BaseException | str) -> str:
    """The first line of an error's message (or the exception's type name when it has none):
    what a one-line error message shows of an underlying exception.

    Examples
    --------
    >>> first_line(OSError("disk full\\nmore detail"))
    'disk full'
    >>> first_line(KeyError())
    'KeyError'
    """
    text = str(error).strip()
    if text:
        return text.splitlines()[0]
    return type(error).__name__ if isinstance(error, BaseException) else ""


def reason(error: BaseException | str) -> str:
    """Why a file operation failed, to follow the file's name in a message: an OSError's bare
    reason (``Permission denied``, without the errno and path the message already names), else
    :func:`first_line`."""
    return first_line(getattr(error, "strerror", None) or error)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path`` and move it onto ``path`` on success.

    The temporary file (``.<name>.<random>.tmp`` in the same directory) is removed if the
    body raises, so an existing ``path`` is left untouched and no debris remains.

    Parameters
    ----------
    path : str or os.PathLike
        Final output file.

    Yields
    ------
    pathlib.Path
        Temporary file to write; it already exists (empty) and may be overwritten.

    Raises
    ------
    InputError
        If the temporary file cannot be created or moved (e.g. missing directory).

    Examples
    --------
    >>> with atomic_output("out.txt") as tmp:  # doctest: +SKIP
    ...     tmp.write_text("hello")
    """
    path = Path(path)
    try:
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        os.close(fd)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {reason(exc)}") from exc
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise InputError(f"cannot write {path}: {reason(exc)}") from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
