"""Errors and atomic writes for user files: the two guarantees every reader and writer gives.

Every problem with a user-supplied file (missing, unreadable, corrupt, truncated, not
writable) raises :class:`InputError`, a ``ValueError`` with a one-line message naming the file;
:func:`first_line` is how a one-line message shows an underlying exception. Writers go through
:func:`atomic_output`: the output either keeps its old content or gets the complete new one.
A set of outputs written together goes through :func:`atomic_outputs`: every file is written
to a temporary file beside it, and all of them are moved into place only once all are written,
so either every output gets its new content or none changes. :func:`same_file` tells whether
two paths name one file (symbolic and hard links included); :func:`input_file` refuses an input
that is not a regular file (a FIFO, a device, a directory) before anything opens it.
"""

from __future__ import annotations

import contextlib
import json
import os
import stat
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

__all__ = ["InputError", "OutputFiles", "atomic_output", "atomic_outputs", "first_line",
           "input_file", "output_file", "reason", "same_file", "write_json"]


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


_NOT_REGULAR = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"),
                (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                (stat.S_ISBLK, "a block device"))


def input_file(path: str | os.PathLike, what: str) -> Path:
    """``path`` as a ``Path`` once it names a regular file (symbolic links followed), else an
    :class:`InputError` of one line: ``<what> not found: PATH``, or ``<what> PATH is not a
    regular file (a FIFO)`` (a directory, a socket, a device). Nothing is opened: opening a
    FIFO waits for a writer, and a device may never end.

    Examples
    --------
    >>> input_file("/dev/null", "image")
    Traceback (most recent call last):
    ...
    sswjax._files.InputError: image /dev/null is not a regular file (a character device)
    """
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError, ValueError):
        raise InputError(f"{what} not found: {path}") from None
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {reason(exc)}") from None
    if not stat.S_ISREG(mode):
        kind = next((name for test, name in _NOT_REGULAR if test(mode)), "a special file")
        raise InputError(f"{what} {path} is not a regular file ({kind})")
    return Path(path)


def _identity(path: str | os.PathLike) -> tuple[str, tuple[int, int] | None]:
    """The path with every symbolic link resolved, and ``(st_dev, st_ino)`` of the file it
    names (None when it does not exist or cannot be examined)."""
    try:
        resolved = os.path.realpath(path)
    except (OSError, ValueError):
        resolved = os.path.abspath(path)
    try:
        status = os.stat(path)
    except (OSError, ValueError):
        return resolved, None
    return resolved, (status.st_dev, status.st_ino)


def same_file(first: str | os.PathLike, second: str | os.PathLike) -> bool:
    """Whether two paths name one file: the same path once symbolic links, ``.`` and ``..``
    are resolved (whether or not it exists), or the same device and inode (hard links).

    Examples
    --------
    >>> same_file("out/../d.pfm", "d.pfm"), same_file("a.pfm", "b.pfm")
    (True, False)
    """
    (first_path, first_inode), (second_path, second_inode) = _identity(first), _identity(second)
    return first_path == second_path or (first_inode is not None and first_inode == second_inode)


def _temporary(path: Path) -> Path:
    """An empty ``.<name>.<random>.tmp`` beside ``path``: proof that ``path`` can be written."""
    try:
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        os.close(fd)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {reason(exc)}") from exc
    return Path(name)


class OutputFiles(dict):
    """What :func:`atomic_outputs` yields: each destination ``Path`` -> its temporary ``Path``."""

    def write(self, path: str | os.PathLike, writer: Callable[[Path], object]) -> None:
        """``writer(temporary)`` for the destination ``path``; an ``OSError`` becomes an
        :class:`InputError` naming ``path``."""
        path = Path(path)
        try:
            writer(self[path])
        except OSError as exc:
            raise InputError(f"cannot write {path}: {reason(exc)}") from exc


def _commit(outputs: OutputFiles) -> None:
    """Move every temporary file onto its destination. If one move fails (or Ctrl-C), the
    moves before it are undone: a file they created is removed, a file they replaced is put
    back from the hard link kept of it meanwhile (where the file system has hard links)."""
    backups: dict[Path, Path] = {}
    placed: list[Path] = []  # the destinations that did not exist before are removed again
    path = None
    try:
        for path, tmp in outputs.items():
            os.chmod(tmp, _FILE_MODE)
        for path, tmp in outputs.items():
            existed = os.path.lexists(path)
            if existed and len(outputs) > 1:
                with contextlib.suppress(OSError, NotImplementedError):  # no hard links here
                    os.link(path, tmp.with_suffix(".old"), follow_symlinks=False)
                    backups[path] = tmp.with_suffix(".old")
            os.replace(tmp, path)
            if not existed or path in backups:
                placed.append(path)
    except BaseException as exc:
        for done in placed:
            with contextlib.suppress(OSError):
                if done in backups:
                    os.replace(backups.pop(done), done)
                else:
                    os.unlink(done)
        if isinstance(exc, OSError):
            raise InputError(f"cannot write {path}: {reason(exc)}") from exc
        raise
    finally:
        for backup in backups.values():
            with contextlib.suppress(OSError):
                os.unlink(backup)


@contextlib.contextmanager
def atomic_outputs(paths: Iterable[str | os.PathLike]) -> Iterator[OutputFiles]:
    """Write a set of files all or nothing: a temporary file beside each of ``paths``, all
    moved onto their destinations once the body has written them.

    The temporary files (``.<name>.<random>.tmp``) are created on entry, so a destination that
    cannot be written fails before the body runs. If the body raises (Ctrl-C included), no
    destination changes and every temporary file is removed.

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        The destinations, distinct files.

    Yields
    ------
    OutputFiles
        Each destination (as a ``pathlib.Path``) -> its temporary file, which exists (empty)
        and may be overwritten; ``OutputFiles.write(path, writer)`` runs ``writer(temporary)``.

    Raises
    ------
    InputError
        If two paths name the same file, or a temporary file cannot be created or moved.

    Examples
    --------
    >>> with atomic_outputs(["a.txt", "b.txt"]) as files:  # doctest: +SKIP
    ...     files.write("a.txt", lambda tmp: tmp.write_text("a"))
    ...     files.write("b.txt", lambda tmp: tmp.write_text("b"))
    """
    paths = [Path(path) for path in paths]
    for i, path in enumerate(paths):
        for other in paths[:i]:
            if same_file(path, other):
                raise InputError(f"outputs {other} and {path} are the same file")
    outputs = OutputFiles()
    try:
        for path in paths:
            outputs[path] = _temporary(path)
        yield outputs
        _commit(outputs)
    finally:
        for tmp in outputs.values():
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)


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
        If the temporary file cannot be created, written or moved (e.g. missing directory).

    Examples
    --------
    >>> with atomic_output("out.txt") as tmp:  # doctest: +SKIP
    ...     tmp.write_text("hello")
    """
    path = Path(path)
    with atomic_outputs([path]) as outputs:
        try:
            yield outputs[path]
        except OSError as exc:
            raise InputError(f"cannot write {path}: {reason(exc)}") from exc


def output_file(path: str | os.PathLike, *, atomic: bool = True
                ) -> contextlib.AbstractContextManager[Path]:
    """Where a writer writes ``path``: :func:`atomic_output`'s temporary file, or with
    ``atomic=False`` ``path`` itself (already a temporary file of :func:`atomic_outputs`)."""
    return atomic_output(path) if atomic else contextlib.nullcontext(Path(path))


def write_json(path: str | os.PathLike, data) -> None:
    """Write ``data`` (JSON-ready) to ``path`` as indented JSON, atomically."""
    with atomic_output(path) as tmp, open(tmp, "w") as handle:
        json.dump(data, handle, indent=1)
        handle.write("\n")
