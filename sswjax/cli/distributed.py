"""``sswjax match ... --workers N`` or ``--scheduler ADDR``: the run on a Dask cluster.

``--workers N`` starts a cluster of N spawned single-threaded worker processes on this machine,
each pinned to a core of its own, for the run (:func:`sswjax.cluster.workers.connect`) and
closes it after;
``--scheduler tcp://HOST:8786`` uses a running one (``dask scheduler`` and ``dask worker``,
or dask-jobqueue on PBS or SLURM), whose workers read the inputs and write the outputs at the
same paths. The pairs of two folders are its tasks (:mod:`sswjax.cli.folders`, through
:func:`sswjax.cluster.match_pairs`); for one pair, :func:`cluster_plan` gives the plan a
:class:`sswjax.cluster.DaskEngine`, so the pair's tiles are (``--tile``, or the tiles that
fit a worker; a pair that fits is one task). The dashboard's link is printed on stderr.
Without Dask these options say in one line what to install (exit status 2).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import sys
from collections.abc import Iterator

from sswjax._files import InputError
from sswjax.cluster import DaskEngine
from sswjax.cluster.cores import usable_cores
from sswjax.cluster.workers import INSTALL, connect, dashboard, require_distributed
from sswjax.runtime.compilation import default_cache_dir
from sswjax.runtime.plan import ExecutionPlan

__all__ = ["cache_folder", "cluster_plan", "cluster_session", "require_cluster",
           "shared_cores_note", "wants_cluster", "worker_budget"]


def wants_cluster(args: argparse.Namespace) -> bool:
    """Whether ``--workers`` or ``--scheduler`` was given."""
    return getattr(args, "workers", None) is not None or \
        getattr(args, "scheduler", None) is not None


def require_cluster(args: argparse.Namespace) -> None:
    """``InputError`` (one line, exit 2) naming what to install when Dask is missing."""
    try:
        require_distributed()
    except ImportError:
        option = "--scheduler" if getattr(args, "scheduler", None) else "--workers"
        raise InputError(f"{option} runs on Dask, which is not installed: {INSTALL}") from None


def cache_folder(args: argparse.Namespace) -> str | None:
    """The compilation cache folder the workers share (None with ``--no-cache``); on a cluster
    of several machines, ``$SSWJAX_CACHE_DIR`` should name a shared path."""
    return None if getattr(args, "no_cache", False) else str(default_cache_dir())


def worker_budget(args: argparse.Namespace) -> tuple[int, bool, float | None]:
    """``(share, local, limit_gb)`` of the memory guard for the workers: ``--workers N``
    share this machine's bound (``--max-memory`` or the memory available) N ways; the
    workers of ``--scheduler`` are elsewhere, each bound by ``--max-memory`` (and, once
    connected, by its own memory limit)."""
    if getattr(args, "scheduler", None) is not None:
        return 1, False, args.max_memory
    return args.workers, True, args.max_memory


def shared_cores_note(workers: int, cores: int) -> str | None:
    """The line that says ``--workers N`` asks for more workers than the machine has cores
    (None when it does not). Each worker is pinned to a core (the slots wrap around), so two
    on one core share it: no faster than one per core, and with the memory of both.

    Examples
    --------
    >>> shared_cores_note(2, 2) is None
    True
    >>> shared_cores_note(3, 2)
    'sswjax: note: --workers 3 on 2 cores: some workers share a core, no faster than --workers 2'
    """
    if workers <= cores:
        return None
    return (f"sswjax: note: --workers {workers} on {cores} cores: some workers share a core, "
            f"no faster than --workers {cores}")


@contextlib.contextmanager
def cluster_session(args: argparse.Namespace) -> Iterator[object]:
    """A ``distributed.Client`` for the run (``--workers`` or ``--scheduler``), closed after
    it, with a line on stderr naming its workers and dashboard."""
    require_cluster(args)
    if getattr(args, "scheduler", None) is None:
        note = shared_cores_note(args.workers, usable_cores())
        if note:
            print(note, file=sys.stderr)
    with connect(workers=getattr(args, "workers", None),
                 scheduler=getattr(args, "scheduler", None)) as client:
        workers = len(client.nthreads())
        link = dashboard(client)
        shown = f"; dashboard {link}" if link else " (no dashboard: pip install bokeh)"
        print(f"sswjax: note: {workers} Dask workers at {client.scheduler.address}{shown}",
              file=sys.stderr)
        yield client


def cluster_plan(args: argparse.Namespace, plan: ExecutionPlan) -> ExecutionPlan:
    """``plan`` as given without ``--workers`` / ``--scheduler``; with either, the plan whose
    tiles are the cluster's tasks (a :class:`~sswjax.cluster.DaskEngine` that starts or
    joins the cluster when the pair is matched, fits the windows to the workers' memory and
    shows a bar over the tiles). Raises ``InputError`` when Dask is missing."""
    if not wants_cluster(args):
        return plan
    require_cluster(args)
    share, _, limit_gb = worker_budget(args)
    limit = None if limit_gb is None else limit_gb * 1e9 / share
    if not plan.tile and not plan.strip_rows:
        print("sswjax: note: the pair is one task unless it does not fit a worker; --tile SIZE "
              "spreads its tiles over the workers", file=sys.stderr)
    engine = DaskEngine(connect=functools.partial(cluster_session, args), cache=cache_folder(args),
                        progress=True, memory_limit=limit)
    return plan._replace(engine=engine)
