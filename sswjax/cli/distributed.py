"""``sswjax match ... --workers N`` or ``--scheduler ADDR``: the run on a Dask cluster.

``--workers N`` starts a cluster of N spawned single-threaded worker processes on this machine,
each pinned to a core of its own (N at most the cores here: more are capped, with a note), for
the run (:func:`sswjax.cluster.workers.connect`) and closes it after, quietly;
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

__all__ = ["cache_folder", "capped_workers_note", "cluster_plan", "cluster_session",
           "local_workers", "require_cluster", "wants_cluster", "worker_budget"]


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


def local_workers(args: argparse.Namespace) -> int:
    """The workers ``--workers N`` starts: N, at most the cores this process may use
    (:func:`~sswjax.cluster.cores.usable_cores`): each worker is pinned to a core, and two on
    one core are no faster than one, with the memory of both (and a cluster of many more
    processes than cores is slow to start and to close)."""
    return max(1, min(args.workers, usable_cores()))


def worker_budget(args: argparse.Namespace) -> tuple[int, bool, float | None]:
    """``(share, local, limit_gb)`` of the memory guard for the workers: ``--workers N``
    share this machine's bound (``--max-memory`` or the memory available) among the workers
    started (:func:`local_workers`); the workers of ``--scheduler`` are elsewhere, each bound
    by ``--max-memory`` (and, once connected, by its own memory limit)."""
    if getattr(args, "scheduler", None) is not None:
        return 1, False, args.max_memory
    return local_workers(args), True, args.max_memory


def capped_workers_note(workers: int, cores: int) -> str | None:
    """The line that says ``--workers N`` asks for more workers than the cores here, and how
    many are started (None when it does not).

    Examples
    --------
    >>> capped_workers_note(2, 2) is None
    True
    >>> capped_workers_note(64, 2)
    'sswjax: note: --workers 64 is more than the 2 cores here: using 2'
    """
    if workers <= cores:
        return None
    return f"sswjax: note: --workers {workers} is more than the {cores} cores here: using {cores}"


@contextlib.contextmanager
def cluster_session(args: argparse.Namespace) -> Iterator[object]:
    """A ``distributed.Client`` for the run (``--workers`` or ``--scheduler``), closed after
    it, quietly, with a line on stderr naming its workers and dashboard. ``--workers N`` above
    the cores here starts one worker per core, with a note (:func:`local_workers`)."""
    require_cluster(args)
    workers = None
    if getattr(args, "scheduler", None) is None:
        workers = local_workers(args)
        note = capped_workers_note(args.workers, usable_cores())
        if note:
            print(note, file=sys.stderr)
    with connect(workers=workers, scheduler=getattr(args, "scheduler", None)) as client:
        count = len(client.nthreads())
        link = dashboard(client)
        shown = f"; dashboard {link}" if link else " (no dashboard: pip install bokeh)"
        print(f"sswjax: note: {count} Dask workers at {client.scheduler.address}{shown}",
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
