"""A process on one core, and the cores of a cluster's workers: the pins of Dask workers.

XLA CPU runs a graph on a pool of threads as large as the number of cores its process may use
(its CPU affinity), whatever ``XLA_FLAGS`` says: a Dask worker with one task thread still
spread each graph over every core of its machine (on this 2-core machine, ``accurate`` on KITTI
2012 kept 1.6 cores busy: 5.7 s of user and 0.9 s of system time in 4.1 s), so a second worker
found little left to use (2 workers over 1: 1.23x, ``docs/cluster.md``). A process pinned to
one core before XLA starts its pool gets a pool of one thread. Linux only
(``os.sched_setaffinity``); elsewhere the processes are left as they are.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
from pathlib import Path

try:
    import fcntl
except ImportError:  # Windows has none: its processes are left as they are
    fcntl = None

__all__ = ["claim_core", "pin_to_core", "pin_worker", "usable_cores"]

_HELD: dict[str, tuple[int | None, int | None]] = {}
"""The core this process claimed per namespace, and the lock's file descriptor (kept open: the
lock lasts as long as the process)."""


def usable_cores() -> int:
    """The cores this process may use: its CPU affinity where the system has one, else all."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def pin_to_core(slot: int) -> int | None:
    """Pin every thread of this process to one core: the ``slot``-th (modulo their count) of
    the cores it may use now. Threads started later inherit it, XLA's pool included, which is
    then sized for one core when it starts after this (a pool started before keeps its threads,
    all on the one core).

    Returns the core, or None where the system has no CPU affinity (it is Linux's).
    """
    if not hasattr(os, "sched_setaffinity") or not os.path.isdir("/proc/self/task"):
        return None
    cores = sorted(os.sched_getaffinity(0))
    core = cores[slot % len(cores)]
    for thread in os.listdir("/proc/self/task"):
        with contextlib.suppress(OSError):      # a thread that has ended since the listing
            os.sched_setaffinity(int(thread), {core})
    return core


def claim_core(namespace: str, *, folder: Path | None = None) -> int | None:
    """Pin this process to a core that no other process of ``namespace`` on this host holds.

    The cores are those this process may use now; each has a lock file in ``folder`` (default
    a folder of this user's under the system's temporary folder) per ``namespace``, and the
    process takes the first it can lock (``fcntl.flock``, without waiting). It keeps the lock
    while it lives, and the system releases it when the process ends, so a process started
    later (a restarted or a late worker) takes a core that is free again. When every core is
    held, the process shares one (its pid modulo their count). A process claims once per
    namespace: a second call returns the same core.

    Returns the core, or None where the system has no CPU affinity or no ``flock`` (Linux has
    both); the process is then left as it is.
    """
    if namespace in _HELD:
        return _HELD[namespace][0]
    if fcntl is None or not hasattr(os, "sched_getaffinity") or \
            not os.path.isdir("/proc/self/task"):
        return None
    cores = sorted(os.sched_getaffinity(0))
    folder = Path(folder) if folder is not None else _lock_folder()
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    key = hashlib.sha256(namespace.encode()).hexdigest()[:16]
    for slot, core in enumerate(cores):
        handle = os.open(folder / f"{key}-{core}.lock", os.O_RDWR | os.O_CREAT, 0o600)
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(handle)
            continue
        _HELD[namespace] = (pin_to_core(slot), handle)
        return _HELD[namespace][0]
    _HELD[namespace] = (pin_to_core(os.getpid()), None)
    return _HELD[namespace][0]


def _lock_folder() -> Path:
    """This user's folder of core locks under the system's temporary folder (POSIX, as
    ``fcntl``)."""
    return Path(tempfile.gettempdir()) / f"sswjax-cores-{os.getuid()}"


def pin_worker(namespace: str, dask_worker) -> int | None:
    """A Dask worker's setup callback (``functools.partial(pin_worker, namespace)`` given to
    ``Client.register_worker_callbacks``, which runs it in every worker now and in every worker
    that starts later, a restarted or a late one): pins the worker's process to a core no other
    worker of ``namespace`` (its cluster: the scheduler's address) holds on its host
    (:func:`claim_core`). Returns the core, or None on a system without CPU affinity."""
    return claim_core(namespace)
