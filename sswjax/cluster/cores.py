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
import os
from collections.abc import Mapping

__all__ = ["core_slots", "pin_to_core", "pin_worker", "usable_cores"]


def core_slots(workers: Mapping[str, Mapping]) -> dict[str, int]:
    """Each worker's slot among the workers of its host: 0, 1, ... in the order of their names.

    ``workers`` as a scheduler lists them (``client.scheduler_info()["workers"]``: address ->
    a mapping with ``"host"`` and ``"name"``); the result maps each worker's name (as a
    string) to its slot, the core :func:`pin_to_core` gives it.

    Examples
    --------
    >>> core_slots({"tcp://a:1": {"host": "a", "name": 1}, "tcp://a:2": {"host": "a", "name": 0},
    ...             "tcp://b:1": {"host": "b", "name": "b-0"}})
    {'0': 0, '1': 1, 'b-0': 0}
    """
    hosts: dict[str, list[str]] = {}
    for address, info in workers.items():
        hosts.setdefault(str(info.get("host", address)), []).append(
            str(info.get("name", address)))
    return {name: slot for names in hosts.values()
            for slot, name in enumerate(sorted(names, key=_name_order))}


def _name_order(name: str) -> tuple:
    """Numbers in their order (2 before 10), other names after them as text."""
    return (0, int(name), "") if name.isdigit() else (1, 0, name)


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


def pin_worker(slots: Mapping[str, int], dask_worker) -> int | None:
    """A Dask worker's setup callback (``functools.partial(pin_worker, slots)`` given to
    ``Client.register_worker_callbacks``, which runs it in every worker now and in every worker
    that starts later): pins ``dask_worker``'s process to the core of its slot in ``slots``
    (worker name as a string -> slot, :func:`core_slots`). Returns the core, or None for a
    worker not named in ``slots`` (left as it is) or a system without CPU affinity."""
    slot = slots.get(str(dask_worker.name))
    return None if slot is None else pin_to_core(slot)
