"""The workers of a Dask cluster as sswjax needs them: spawned processes, each on a core of its
own, the compilation cache they share.

A worker is a process of its own (``processes=True``), started with the ``spawn`` method: a
process forked from one that has imported JAX can deadlock in XLA's thread pools (Dask's
default is already ``spawn``; :func:`local_cluster` sets it whatever the configuration says).
Each worker runs one task at a time (one thread), and the worker process is pinned to one core
(its CPU affinity, :mod:`sswjax.cluster.cores`): XLA CPU sizes its pool of threads by the cores
a process may use, whatever its flags say, so an unpinned worker spread each graph over every
core of the machine (1.6 of this machine's 2) and ``N`` workers contended for them. The workers
of a cluster on one host each take a core that no other holds (a lock per core); a setup
callback pins each worker when it is registered, again when its nanny restarts it, and each
worker that joins later (:func:`pin_workers`, which :func:`connect` calls for the clusters it
starts or joins). The environment of :func:`worker_environment` keeps
Eigen and the BLAS libraries on one thread too. Every task enables the persistent compilation
cache in the folder it is given (:func:`prepare_worker`), once per process: a shape compiled by
one worker is read from the shared folder by the others.

A cluster that :func:`connect` starts is closed quietly: a worker still busy when it closes is
killed by its nanny, and neither that nor the worker's own records reach stderr.

``distributed`` is an optional dependency (``pip install "sswjax[distributed]"``): it is
imported by the functions that need it, and :func:`require_distributed` says what to install.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
from collections.abc import Iterator, Mapping

from sswjax.cluster.cores import pin_worker
from sswjax.runtime.compilation import enable_compilation_cache

__all__ = ["INSTALL", "PINNED_FLAGS", "connect", "dashboard", "local_cluster", "pin_workers",
           "prepare_worker", "require_distributed", "worker_environment", "worker_memory"]

INSTALL = 'pip install "sswjax[distributed]"'
"""What to install for the cluster (Dask distributed)."""

PINNED_FLAGS = ("--xla_cpu_multi_thread_eigen=false",)
"""XLA flags of a worker: Eigen's operations on one thread. (XLA's own pool of threads follows
the process's CPU affinity: :func:`~sswjax.cluster.cores.pin_to_core`.)"""

_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")

_PREPARED: dict[str, object] = {}
"""What :func:`prepare_worker` did in this process (the cache folder), so it is done once."""


def require_distributed():
    """The ``distributed`` module; ``ImportError`` with one line naming :data:`INSTALL`."""
    try:
        import distributed
    except ImportError:
        raise ImportError(f"Dask distributed is not installed: {INSTALL}") from None
    return distributed


def worker_environment(*, environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment variables of a worker: ``XLA_FLAGS`` with :data:`PINNED_FLAGS` added to
    those of ``environ`` (default ``os.environ``), and one thread for OpenMP, MKL and OpenBLAS.

    Examples
    --------
    >>> worker_environment(environ={"XLA_FLAGS": "--xla_dump_to=/tmp/x"})["XLA_FLAGS"]
    '--xla_dump_to=/tmp/x --xla_cpu_multi_thread_eigen=false'
    """
    environ = os.environ if environ is None else environ
    flags = environ.get("XLA_FLAGS", "").split()
    names = {flag.split("=")[0] for flag in flags}
    flags += [flag for flag in PINNED_FLAGS if flag.split("=")[0] not in names]
    return {"XLA_FLAGS": " ".join(flags), **{name: "1" for name in _THREAD_VARIABLES}}


def local_cluster(n_workers: int, *, memory_limit="auto", dashboard_address: str | None = ":0",
                  **options):
    """A ``distributed.LocalCluster`` of ``n_workers`` spawned single-threaded processes on this
    machine with the environment of :func:`worker_environment` (:func:`pin_workers` then puts
    each on a core of its own).

    Parameters
    ----------
    n_workers : int >= 1
    memory_limit : as LocalCluster's (default ``"auto"``: the memory shared evenly); a worker
        beyond it is restarted by its nanny and its task retried elsewhere.
    dashboard_address : str or None
        Where the dashboard listens (default any free port; None: no dashboard).
    **options
        More keyword arguments of ``LocalCluster``.
    """
    distributed = require_distributed()
    import dask

    with dask.config.set({"distributed.worker.multiprocessing-method": "spawn"}):
        return distributed.LocalCluster(
            n_workers=n_workers, threads_per_worker=1, processes=True, memory_limit=memory_limit,
            dashboard_address=dashboard_address, env=worker_environment(), **options)


def _worker_flags() -> str:
    """``XLA_FLAGS`` of the process (run on each worker by :func:`pin_workers`)."""
    return os.environ.get("XLA_FLAGS", "")


def pin_workers(client) -> list[str]:
    """Make sure every worker of ``client`` has the environment of :func:`worker_environment`
    and a core of its own; returns the addresses of the workers that had to be restarted for
    the environment (through their nannies).

    The cores: a setup callback (:func:`~sswjax.cluster.cores.pin_worker`) pins each worker
    now, whenever it starts again, and each worker that joins later, to a core that no other
    worker of this cluster (named by its scheduler's address) holds on its host
    (:func:`~sswjax.cluster.cores.claim_core`).
    """
    require_distributed()
    from distributed.diagnostics.plugin import Environ

    flags = client.run(_worker_flags)
    unpinned = [address for address, value in flags.items()
                if not all(flag in value.split() for flag in PINNED_FLAGS)]
    if unpinned:
        client.register_plugin(Environ(worker_environment()), name="sswjax-pinned-threads")
        client.wait_for_workers(len(flags))
    client.register_worker_callbacks(
        setup=functools.partial(pin_worker, client.scheduler_info()["address"]))
    return unpinned


def worker_memory(client) -> int | None:
    """The smallest memory limit of the workers of ``client`` in bytes (None: none has one)."""
    limits = [info.get("memory_limit") or 0
              for info in client.scheduler_info(n_workers=-1)["workers"].values()]
    limits = [limit for limit in limits if limit > 0]
    return min(limits) if limits else None


def dashboard(client) -> str | None:
    """The link of the cluster's dashboard, or None when it has none (``bokeh`` missing)."""
    services = client.scheduler_info().get("services", {})
    return client.dashboard_link if "dashboard" in services else None


@contextlib.contextmanager
def connect(*, workers: int | None = None, scheduler: str | None = None,
            timeout: float = 30) -> Iterator[object]:
    """A ``distributed.Client`` of a running cluster at ``scheduler``, or of a
    :func:`local_cluster` of ``workers`` processes started for the block and closed after it;
    either way its workers pinned, each to a core of its own (:func:`pin_workers`).

    Raises ``ImportError`` without Dask, ``OSError`` (one line) when the scheduler cannot be
    reached in ``timeout`` seconds.
    """
    distributed = require_distributed()
    if scheduler is not None:
        try:
            client = distributed.Client(scheduler, timeout=timeout)
        except (OSError, TimeoutError) as error:
            raise OSError(f"cannot reach the Dask scheduler {scheduler}: "
                          f"{str(error).splitlines()[0] if str(error) else type(error).__name__}"
                          ) from None
        try:
            pin_workers(client)
            yield client
        finally:
            client.close()
        return
    cluster = local_cluster(workers)
    try:
        client = distributed.Client(cluster)
        try:
            client.wait_for_workers(workers, timeout=timeout * 4)
            pin_workers(client)
            yield client
        finally:
            with _quiet_close(client):
                client.close()
    finally:
        with _quiet_close(None):
            cluster.close()


def _silence_logs() -> None:
    """In a worker about to be closed: no more log records (run by :func:`_quiet_close`)."""
    logging.disable(logging.CRITICAL)


@contextlib.contextmanager
def _quiet_close(client) -> Iterator[None]:
    """The closing of a cluster this process started, without its log records on stderr: a
    worker still busy (Ctrl-C, an error, a task cancelled) is killed by its nanny after a few
    seconds, and the nanny here and the worker there each log it (with many workers on few
    cores, hundreds of lines and tracebacks). The workers of ``client`` (None: none left to
    tell) stop logging, and this process's records are dropped during the block."""
    if client is not None:
        with contextlib.suppress(Exception):  # a worker gone already: nothing to silence
            client.run(_silence_logs)
    before = logging.root.manager.disable
    logging.disable(logging.CRITICAL)
    try:
        yield
    finally:
        logging.disable(before)


def prepare_worker(cache: str | None) -> None:
    """In a worker, before its first graph: the persistent compilation cache in ``cache``
    (None: left as it is). Done once per process; cheap after."""
    if _PREPARED.get("cache", False) == cache:
        return
    if cache is not None:
        enable_compilation_cache(path=cache)
    _PREPARED["cache"] = cache
