"""The record a folder run keeps beside its outputs, so that ``--resume`` continues that run,
and the lock that keeps a second run out of the folder while it runs.

A run that writes into a folder (``sswjax match LEFT_DIR RIGHT_DIR -o OUT_DIR``, ``sswjax
evaluate -o OUT``) starts ``OUT/.sswjax-run.json`` with its settings (the command, the
version, the parameters, the range, what changes results of the plan) and their digest
(:func:`settings_digest`), and adds each output's name as it is written, with the digest of
the settings that wrote it. ``--resume`` refuses a record whose settings differ from the new
command's, naming what changed, and keeps only the outputs the record lists with the digest of
these settings: a folder never ends up holding maps of two configurations.

``sswjax match`` holds :func:`lock_folder` on its output folder for the whole run
(``OUT/.sswjax-run.lock``): a second run into the folder is refused in one line naming the
first (its process and when it started) rather than mixing its maps with the first's.
"""

from __future__ import annotations

import contextlib
import datetime
import errno
import hashlib
import json
import os
import socket
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import NamedTuple

from sswjax._files import atomic_output

try:
    import fcntl
except ImportError:  # Windows: the lock is the file alone (O_EXCL), never taken over
    fcntl = None

__all__ = ["LOCK_NAME", "RECORD_NAME", "FolderLock", "RunRecord", "describe_holder",
           "differences", "lock_folder", "settings_digest"]

RECORD_NAME = ".sswjax-run.json"
"""The record's file name in the run's folder."""

LOCK_NAME = ".sswjax-run.lock"
"""The lock's file name in the run's folder (there while a run holds it)."""

_SHOWN = 4
"""Differences named in a refusal (the rest are counted)."""


def differences(old, new, prefix: str = "") -> list[str]:
    """What changed from the settings ``old`` to ``new``, one ``"key NEW (was OLD)"`` each,
    mappings compared key by key (a stage turned on or off is one difference).

    Examples
    --------
    >>> differences({"ndisp": 16, "params": {"coarse": None, "fill": {"kind": "vote"}}},
    ...             {"ndisp": 32, "params": {"coarse": {"levels": 1}, "fill": {"kind": "vote"}}})
    ['ndisp 32 (was 16)', 'params.coarse {...} (was null)']
    """
    if isinstance(old, Mapping) and isinstance(new, Mapping):
        out = []
        for key in sorted(set(old) | set(new)):
            out += differences(old.get(key), new.get(key), f"{prefix}.{key}" if prefix else key)
        return out
    return [] if old == new else [f"{prefix} {_show(new)} (was {_show(old)})"]


def _show(value) -> str:
    return "{...}" if isinstance(value, Mapping) else json.dumps(value)


def settings_digest(settings: Mapping) -> str:
    """16 hex digits of a SHA-256 of ``settings`` (as JSON, keys sorted): what the record
    keeps of the settings that wrote each output.

    Examples
    --------
    >>> settings_digest({"ndisp": 16, "command": "match"}) == \\
    ...     settings_digest({"command": "match", "ndisp": 16})
    True
    >>> len(settings_digest({"ndisp": 16}))
    16
    """
    text = json.dumps(settings, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


class RunRecord:
    """The settings of a folder run and the outputs it has written, each with the digest of
    the settings that wrote it (:func:`settings_digest`).

    Use :meth:`start` for a new run and :meth:`resume` for ``--resume``; then :meth:`done` says
    whether an output belongs to the run (written with its settings) and :meth:`finished` adds
    one (written at once). The file holds ``{"settings": ..., "digest": ..., "maps": {name:
    digest}}``; a record of an older version (``"finished": [name, ...]``) reads as outputs
    written with its settings.
    """

    def __init__(self, folder: Path, settings: Mapping, maps: Mapping[str, str] | None = None):
        self.folder = Path(folder)
        self.settings = json.loads(json.dumps(dict(settings)))  # as it reads back
        self.digest = settings_digest(self.settings)
        self._maps = dict(maps or {})

    @property
    def path(self) -> Path:
        """The record's file."""
        return self.folder / RECORD_NAME

    @classmethod
    def start(cls, folder: Path, settings: Mapping) -> RunRecord:
        """A new run's record, written (an older record in ``folder`` is replaced)."""
        record = cls(folder, settings)
        record._write()
        return record

    @classmethod
    def resume(cls, folder: Path, settings: Mapping) -> RunRecord:
        """The record of the run to continue; ``ValueError`` (one line) when there is none or
        its settings differ from ``settings``."""
        path = Path(folder) / RECORD_NAME
        try:
            stored = json.loads(path.read_text(encoding="utf-8"))
            old = stored["settings"]
            if "maps" in stored:
                maps = {str(name): str(digest) for name, digest in stored["maps"].items()}
            else:  # an older version's record: its outputs, all of its settings
                maps = dict.fromkeys(map(str, stored["finished"]), settings_digest(old))
        except FileNotFoundError:
            raise ValueError(f"cannot --resume {folder}: it holds no record of the settings it "
                             f"was made with ({RECORD_NAME}); run without --resume") from None
        except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError,
                AttributeError) as error:
            raise ValueError(f"cannot --resume {folder}: its record {path} is unreadable "
                             f"({type(error).__name__}); run without --resume") from None
        record = cls(folder, settings, maps)
        changed = differences(old, record.settings)
        if changed:
            listed = "; ".join(changed[:_SHOWN])
            more = f" and {len(changed) - _SHOWN} more" if len(changed) > _SHOWN else ""
            raise ValueError(f"cannot --resume {folder} with other settings than it was made "
                             f"with: {listed}{more}; run without --resume to start again")
        return record

    def done(self, name: str) -> bool:
        """Whether the output ``name`` was written by this run: recorded, with the digest of
        this run's settings."""
        return self._maps.get(name) == self.digest

    def finished(self, name: str) -> None:
        """Add the output ``name`` (written with this run's settings) to the record, at once."""
        if self._maps.get(name) != self.digest:
            self._maps[name] = self.digest
            self._write()

    def _write(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        with atomic_output(self.path) as tmp:
            tmp.write_text(json.dumps({"settings": self.settings, "digest": self.digest,
                                       "maps": self._maps}, indent=1) + "\n",
                           encoding="utf-8")


class FolderLock(NamedTuple):
    """A folder's lock as :func:`lock_folder` holds it: its file, and what the lock file said
    of a run that ended without releasing it (None when there was none): ``{"pid": ...,
    "host": ..., "started": ...}``, ``{}`` when it said nothing readable."""

    path: Path
    stale: dict | None


def _holder(text: str) -> dict:
    """What a lock file says of its run (``{}`` when it says nothing readable)."""
    try:
        holder = json.loads(text)
    except ValueError:
        return {}
    return holder if isinstance(holder, dict) else {}


def describe_holder(holder: Mapping) -> str:
    """``"pid N, started YYYY-MM-DD HH:MM:SS"`` of a lock's run (``"pid unknown"`` when the
    lock file names none; the host too when it is another).

    Examples
    --------
    >>> describe_holder({"pid": 12, "host": socket.gethostname(), "started": "2026-12-07 10:00:00"})
    'pid 12, started 2026-12-07 10:00:00'
    >>> describe_holder({})
    'pid unknown'
    """
    words = f"pid {holder.get('pid', 'unknown')}"
    if holder.get("host") not in (None, socket.gethostname()):
        words += f" on {holder['host']}"
    if holder.get("started"):
        words += f", started {holder['started']}"
    return words


def _in_use(folder: Path, holder: Mapping) -> ValueError:
    return ValueError(f"{folder} is in use by another sswjax run ({describe_holder(holder)}): "
                      "wait for it or choose another -o")


def _read_holder(handle: int) -> dict:
    """The lock file's words, read from its descriptor; a run that has just taken the lock
    writes them a moment later, so an empty file is read again a few times."""
    for _ in range(20):
        os.lseek(handle, 0, os.SEEK_SET)
        holder = _holder(os.read(handle, 4096).decode("utf-8", "replace"))
        if holder:
            return holder
        time.sleep(0.01)
    return {}


@contextlib.contextmanager
def lock_folder(folder: str | os.PathLike) -> Iterator[FolderLock]:
    """Hold ``folder``'s run lock (``folder/.sswjax-run.lock``, the folder must exist) for the
    block: the file names this process, its host and when it started, and is removed at the
    end (Ctrl-C included).

    The lock is the kernel's (``fcntl.flock``) on the file, taken without waiting: the system
    releases it when the process ends, however it ends, so the lock of a run that was killed
    is taken over (:attr:`FolderLock.stale` says what its file said: the command line notes
    it). On a system without ``flock`` (Windows) the lock is the file alone, created
    exclusively, and a killed run's file is left to remove by hand.

    Raises
    ------
    ValueError
        One line when another run holds the lock: ``OUT is in use by another sswjax run (pid N,
        started ...): wait for it or choose another -o``.
    OSError
        When the lock file cannot be created (a folder not writable).

    Examples
    --------
    >>> with lock_folder("out") as lock:                 # doctest: +SKIP
    ...     ...                                          # the run: a second one is refused
    """
    folder = Path(folder)
    path = folder / LOCK_NAME
    words = {"pid": os.getpid(), "host": socket.gethostname(),
             "started": datetime.datetime.now().strftime("%Y-%m-%d %H:%M:%S")}
    text = json.dumps(words) + "\n"
    if fcntl is None:
        try:
            handle = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            raise _in_use(folder, _holder(path.read_text("utf-8", "replace"))) from None
        try:
            os.write(handle, text.encode())
        finally:
            os.close(handle)
        try:
            yield FolderLock(path, None)
        finally:
            with contextlib.suppress(OSError):
                path.unlink()
        return
    while True:
        handle = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            if error.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                os.close(handle)
                raise
            holder = _read_holder(handle)
            os.close(handle)
            raise _in_use(folder, holder) from None
        try:  # the file a run ending just now removed is not the lock: take the new file's
            same = os.stat(path).st_ino == os.fstat(handle).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(handle)
    try:
        before = os.read(handle, 4096).decode("utf-8", "replace")
        os.lseek(handle, 0, os.SEEK_SET)
        os.ftruncate(handle, 0)
        os.write(handle, text.encode())
        yield FolderLock(path, _holder(before) if before.strip() else None)
    finally:
        with contextlib.suppress(OSError):
            path.unlink()  # before the lock goes: a run that opened this file tries again
        os.close(handle)
