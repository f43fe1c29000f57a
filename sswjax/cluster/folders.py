"""Many pairs as the tasks of a Dask cluster: :func:`match_pairs` and :func:`match_folder`.

Each pair is one task (:func:`sswjax.cluster.tasks.match_pair`): the worker reads the images
and writes the map itself, atomically, on storage the workers share, and gives back a
:class:`~sswjax.cluster.tasks.PairOutcome`. The outcomes arrive here, in the client, as the
tasks complete, so that one process only (the caller's) keeps any record of what is done. A
worker that dies mid-task (killed, out of memory) has its task run again by the scheduler on
another worker (``distributed.scheduler.allowed-failures`` times); a pair that fails on bad
input, or whose task failed every time, is an outcome with its name and why, and the other
pairs go on.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import NamedTuple

from sswjax._files import first_line
from sswjax.api.match import resolve_plan
from sswjax.cluster.pairs import bad_pairs_error, checked_pairs
from sswjax.cluster.tasks import PairJob, PairOutcome, match_pair
from sswjax.cluster.workers import require_distributed
from sswjax.config import Params, check_params, default_params
from sswjax.runtime.plan import ExecutionPlan

__all__ = ["FolderSummary", "match_folder", "match_pairs"]


class FolderSummary(NamedTuple):
    """What :func:`match_folder` did: the names written, failed (name -> why, one line) and
    skipped (asked to)."""

    written: list[str]
    failed: dict[str, str]
    skipped: list[str]


def match_pairs(client, jobs: Sequence[PairJob], ndisp: int, *, min_disp: int = 0,
                params: Params | None = None, plan: ExecutionPlan | None = None,
                cache: str | None = None, retries: int = 1) -> Iterator[PairOutcome]:
    """Every job a task of ``client``'s cluster; their outcomes, in the order they complete.

    Parameters
    ----------
    client : distributed.Client
    jobs : sequence of PairJob
        Submitted in this order (sort them by shape: each worker then meets the shapes one
        after the other).
    ndisp, min_disp, params, plan
        As for :func:`sswjax.match`; the memory is not checked (check it before, for the
        largest pair and one worker: :func:`sswjax.runtime.memory.plan_for_memory`).
    cache : str, optional
        The workers' compilation cache folder (a path they share).
    retries : int
        Times a task that raised (not on bad input: that is an outcome) is run again.

    Yields
    ------
    PairOutcome
        One per job. A task that failed every time gives ``ok=False`` and its error.
        Leaving the loop early (or Ctrl-C) cancels the tasks not yet done.
    """
    distributed = require_distributed()
    params = default_params() if params is None else check_params(params)
    plan = resolve_plan(plan, None)._replace(engine=None)
    token = uuid.uuid4().hex[:12]
    futures = {client.submit(match_pair, job, ndisp=int(ndisp), min_disp=int(min_disp),
                             params=params, plan=plan, cache=cache, retries=retries,
                             key=f"sswjax-pair-{token}-{index}", pure=False): job
               for index, job in enumerate(jobs)}
    try:
        for future in distributed.as_completed(futures):
            job = futures[future]
            try:
                yield future.result()
            except Exception as error:  # noqa: BLE001 (reported with the pair's name)
                yield PairOutcome(job.name, False, f"{type(error).__name__}: "
                                  f"{first_line(error)}", 0.0)
    finally:
        client.cancel([future for future in futures if not future.done()])


def match_folder(client, left_dir, right_dir, out_dir, ndisp: int, *, min_disp: int = 0,
                 params: Params | None = None, plan: ExecutionPlan | None = None,
                 cache: str | None = None, retries: int = 1,
                 skip: Iterable[str] = (), strict: bool = False) -> FolderSummary:
    """The pairs of two folders (the images of the same name,
    :func:`sswjax.cluster.pairs.checked_pairs`) matched on ``client``'s cluster, each map
    written to ``out_dir/<stem>.pfm`` (created) by its worker; a bad pair is named in the
    summary's ``failed`` and the others go on.

    Parameters
    ----------
    client : distributed.Client
    left_dir, right_dir, out_dir : path
        Folders the workers can read and write at these paths.
    ndisp, min_disp, params, plan, cache, retries
        As for :func:`match_pairs`.
    skip : iterable of str
        Names of pairs not to match (done before).
    strict : bool
        Refuse the folders (``InputError``, one line, before any task) when a pair is bad; by
        default a bad pair (an image that cannot be read, two sizes) is in ``failed`` with why
        (``"pair NAME: ..."``) and the others are matched.

    Returns
    -------
    FolderSummary

    Examples
    --------
    >>> from distributed import Client, LocalCluster                     # doctest: +SKIP
    >>> with LocalCluster(n_workers=2, threads_per_worker=1) as cluster, \\
    ...         Client(cluster) as client:                               # doctest: +SKIP
    ...     summary = match_folder(client, "left", "right", "out", 64)
    """
    out = Path(out_dir)
    skip = set(skip)
    pairs, bad = checked_pairs(left_dir, right_dir)
    if bad and strict:
        raise bad_pairs_error(bad)
    out.mkdir(exist_ok=True)
    jobs = [PairJob(p.name, str(p.left), str(p.right), str(out / f"{Path(p.name).stem}.pfm"))
            for p in sorted(pairs, key=lambda p: (p.size, p.name)) if p.name not in skip]
    written, failed = [], {name: why for name, why in bad.items() if name not in skip}
    for outcome in match_pairs(client, jobs, ndisp, min_disp=min_disp, params=params, plan=plan,
                               cache=cache, retries=retries):
        if outcome.ok:
            written.append(outcome.name)
        else:
            failed[outcome.name] = outcome.message
    return FolderSummary(sorted(written), failed,
                         sorted(p.name for p in pairs if p.name in skip))
