"""One pair's tiles as the tasks of a Dask cluster: :class:`DaskEngine` and :func:`match_tiles`.

``ExecutionPlan(tile=512, engine=DaskEngine(client))`` given to :func:`sswjax.match` (or
``match_with_confidence``, or ``match_graph`` with a graph of :mod:`sswjax.graph`) runs the
call through the API's front door as ever (the checks, the range, the validity bits), and
only its windows elsewhere: each window of the tiling (:mod:`sswjax.runtime.tiles`) is a task
that gets its two crops and gives back its core, stitched here as they arrive. The tasks
carry their crops (no scattered data), so the scheduler can run a task again on another
worker when its worker dies; a bounded number of them is in flight at a time, so the
scheduler holds a few windows, not the image. Row strips whose semi-global paths are
carried from strip to strip (:mod:`sswjax.runtime.carried`) wait for each other: their chain
is one task. An aligned pair's right image is moved first, in this process (one call on the
whole pair), and the engine runs the method's call. Before any task, every window is estimated
against the workers' memory limit (:func:`sswjax.runtime.memory.worker_peak_bytes`): a plan
without tiles gets the tiles that fit a worker, and a tiling that does not fit is refused.

Array conventions: images float32 ``(H, W, C)``; maps NumPy ``(H, W)``.
"""

from __future__ import annotations

import contextlib
import itertools
import sys
import uuid

from tqdm import tqdm

from sswjax._files import first_line
from sswjax.api.match import match, match_with_confidence
from sswjax.cluster.tasks import graph_name, match_carried, match_window
from sswjax.cluster.workers import require_distributed, worker_memory
from sswjax.runtime.carried import carried_strips
from sswjax.runtime.memory import plan_for_memory
from sswjax.runtime.plan import ExecutionPlan, plan_tiling, pyramid_align
from sswjax.runtime.tiles import assemble, tile_windows

__all__ = ["DaskEngine", "TileFailed", "match_tiles"]


class TileFailed(OSError):
    """A tile's task failed every time (its worker died, or it raised): the pair has no map.

    An ``OSError`` (the processes' failure, not the input's): the command line says it in one
    line, with how many tiles were done."""


class DaskEngine:
    """Where the windows of a call run: the workers of a Dask cluster.

    Parameters
    ----------
    client : distributed.Client, optional
        A client of a running cluster (left open).
    connect : callable, optional
        Instead of ``client``: a function of no argument returning a context manager that
        yields a client for one call (:func:`sswjax.cluster.workers.connect`, as the command
        line starts a cluster for its one pair).
    cache : str, optional
        The workers' compilation cache folder (a path they share); None: theirs as it is.
    retries : int
        Times a task that raised is run again (a dead worker's task is run again by the
        scheduler in any case, up to ``distributed.scheduler.allowed-failures``).
    progress : bool
        A bar over the tiles on stderr.
    in_flight : int, optional
        Tasks submitted at a time (default twice the workers' threads, plus one).
    check_memory : bool
        Fit the windows to the workers' memory (default): their own limit (Dask's
        ``memory_limit``) and ``memory_limit``.
    memory_limit : float, optional
        Bytes a worker may use, besides its own limit.
    """

    def __init__(self, client=None, *, connect=None, cache: str | None = None, retries: int = 1,
                 progress: bool = False, in_flight: int | None = None, check_memory: bool = True,
                 memory_limit: float | None = None):
        if (client is None) == (connect is None):
            raise ValueError("DaskEngine takes a client or connect, one of them")
        self.client, self.connect = client, connect
        self.cache, self.retries, self.progress = cache, int(retries), progress
        self.in_flight, self.check_memory = in_flight, check_memory
        self.memory_limit = memory_limit

    def _session(self):
        if self.client is not None:
            return contextlib.nullcontext(self.client)
        return self.connect()

    def execute(self, graph, left, right, *, params, call: dict, plan: ExecutionPlan):
        """:func:`sswjax.runtime.execute.run_windows` with each window a task (its arguments
        and returns the same: the method's call on the pair padded to its bucket, and aligned,
        ``call`` the keyword arguments of :func:`~sswjax.runtime.execute.graph_call`; ``plan``
        without its engine). The windows are fitted to the workers' memory, or refused, before
        any task runs."""
        name, keywords = graph_name(graph)
        with self._session() as client:
            plan = self._fitted(client, left.shape, call["ndisp"], params, plan)
            tiling = plan_tiling(plan, call["ndisp"], align=pyramid_align(params))
            if plan.carry_paths and carried_strips(graph, params, *left.shape[:2], tiling):
                return self._chain(client, name, keywords, left, right, tiling, params, call)
            windows = tile_windows(left.shape[0], left.shape[1], tiling)
            pieces = self._pieces(client, name, keywords, left, right, windows, params, call)
            return assemble(left.shape[0], left.shape[1], pieces)

    def _fitted(self, client, shape, ndisp, params, plan):
        """``plan`` (of the padded pair: no buckets) fitted to the workers' memory limit."""
        if not self.check_memory:
            return plan
        limits = [b for b in (worker_memory(client), self.memory_limit) if b is not None]
        if not limits:
            return plan
        limit = min(limits)
        return plan_for_memory(shape[0], shape[1], ndisp, params=params, channels=shape[2],
                               plan=plan._replace(buckets=None), limit=limit, local=False,
                               worker_tiles=True)

    def _chain(self, client, name, keywords, left, right, tiling, params, call):
        """The maps of carried strips: each strip waits for its neighbours' paths, so their
        chain is one task (run again elsewhere if its worker dies)."""
        future = client.submit(match_carried, name, keywords, left, right, tiling, params=params,
                               call=call, cache=self.cache, retries=self.retries, pure=False,
                               key=f"sswjax-strips-{uuid.uuid4().hex[:12]}")
        try:
            return future.result()
        except Exception as error:
            raise TileFailed(f"the task of the strips failed: {type(error).__name__}: "
                             f"{first_line(error)} (a worker that dies every time is out of "
                             "memory: thinner strips)") from error

    def _pieces(self, client, name, keywords, left, right, windows, params, call):
        """``(window, core)`` of every window, as the tasks complete."""
        distributed = require_distributed()
        token = uuid.uuid4().hex[:12]

        def submit(index, window):
            rows = slice(window.top, window.top + window.height)
            cols = slice(window.left, window.left + window.width)
            return client.submit(match_window, name, keywords, left[rows, cols],
                                 right[rows, cols], window, params=params, call=call,
                                 cache=self.cache, key=f"sswjax-tile-{token}-{index}",
                                 retries=self.retries, pure=False)

        todo = enumerate(windows)
        width = self.in_flight or 2 * max(1, sum(client.nthreads().values())) + 1
        submitted = [submit(*item) for item in itertools.islice(todo, width)]
        arriving = distributed.as_completed(submitted)
        bar = tqdm(total=len(windows), desc="tiles", unit="tile", file=sys.stderr,
                   disable=not self.progress)
        done = 0
        try:
            for future in arriving:
                try:
                    piece = future.result()
                except Exception as error:
                    index = int(future.key.rsplit("-", 1)[1])
                    window = windows[index]
                    raise TileFailed(
                        f"tile {index + 1} of {len(windows)} (rows "
                        f"{window.first}-{window.last}, columns {window.start}-{window.stop}) "
                        f"failed: {type(error).__name__}: {first_line(error)}; {done} were done "
                        "(a worker that dies every time is out of memory: smaller tiles)"
                    ) from error
                done += 1
                yield piece
                bar.update(1)
                following = next(todo, None)
                if following is not None:
                    submitted.append(submit(*following))
                    arriving.add(submitted[-1])
        finally:
            bar.close()
            client.cancel([future for future in submitted if not future.done()])


def match_tiles(client, left, right, ndisp: int, *, min_disp: int = 0, params=None,
                plan: ExecutionPlan | None = None, confidence: bool = False,
                cache: str | None = None, progress: bool = False, **options):
    """:func:`sswjax.match` (or, with ``confidence``, :func:`sswjax.match_with_confidence`)
    of one pair with its tiles as the tasks of ``client``'s cluster.

    Parameters
    ----------
    client : distributed.Client
    left, right, ndisp, min_disp, params
        As for :func:`sswjax.match`.
    plan : ExecutionPlan, optional
        Its tiles (``tile`` or ``strip_rows``) become the tasks; without, the tiles that fit
        a worker, or the whole pair as one task.
    confidence : bool
        Return :class:`sswjax.Matched` (disparity, confidence, validity) instead of the map.
    cache, progress
        As for :class:`DaskEngine`.
    **options
        More keyword arguments of ``match`` / ``match_with_confidence`` (``low_confidence``,
        ``measure``, ``check_memory``: this process's own check, default on).

    Returns
    -------
    numpy.ndarray float32 (H, W), or Matched

    Examples
    --------
    >>> from distributed import Client                       # doctest: +SKIP
    >>> with Client("tcp://scheduler:8786") as client:       # doctest: +SKIP
    ...     d = match_tiles(client, left, right, 256, plan=sswjax.ExecutionPlan(tile=1024))
    """
    plan = ExecutionPlan() if plan is None else plan
    plan = plan._replace(engine=DaskEngine(client, cache=cache, progress=progress))
    run = match_with_confidence if confidence else match
    return run(left, right, ndisp, min_disp=min_disp, params=params, plan=plan, **options)
