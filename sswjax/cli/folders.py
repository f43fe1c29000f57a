"""``sswjax match LEFT_DIR RIGHT_DIR --ndisp N -o OUT_DIR``: every pair of two folders.

The image files of the same name in both folders are pairs (:func:`folder_pairs`); each gives
``OUT_DIR/<stem>.pfm``. Everything that can fail on the user's input is checked before the
first pair runs, from the files' headers: the folders, the names, each pair's images (readable,
of one size), ``ndisp`` against every width, the output folder (neither LEFT_DIR nor
RIGHT_DIR, and no other run's: the run holds its lock, :func:`sswjax.cli.record.lock_folder`),
and the memory estimate of the largest shape (:mod:`sswjax.cli.guard`). A bad pair is named
on a line of its own and the good ones are matched (``--strict``: the run is refused); what is
wrong with the run as a whole is refused in one line before anything is written. Pairs run
sorted by shape (the bucketed shape with ``--bucket``), so each shape compiles once; each map
is written atomically as soon as it is done, so Ctrl-C keeps the finished ones and ``--resume``
skips those written with the same settings. A pair that fails on its files later (a truncated
image, say) is named too and the others go on; the summary says how many were written, kept
and failed, and any failure ends the run with one line ``N of M maps written; K pairs failed:
a.png, ...`` (exit status 2).

With ``--workers N`` or ``--scheduler ADDR`` each pair is a task of a Dask cluster
(:mod:`sswjax.cli.distributed`): the workers write the maps, this process alone the run's
record, as the outcomes arrive; a worker that dies has its pair matched by another.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import os
import sys
import time
from pathlib import Path

from tqdm import tqdm

from sswjax._files import InputError, first_line, same_file
from sswjax._version import __version__
from sswjax.api.images import check_image_size
from sswjax.api.match import match
from sswjax.cli.common import Interrupted, command_line, raise_if_interrupted, resume_command
from sswjax.cli.distributed import (
    cache_folder,
    cluster_session,
    require_cluster,
    wants_cluster,
    worker_budget,
)
from sswjax.cli.guard import guard_memory
from sswjax.cli.options import params_from_args, plan_from_args
from sswjax.cli.record import RunRecord, describe_holder, lock_folder
from sswjax.cli.rectify import rectify_images
from sswjax.cluster.folders import match_pairs
from sswjax.cluster.pairs import (IMAGE_SUFFIXES, FolderPair, bad_pairs_error, checked_pairs,
                                  folder_pairs, image_size)
from sswjax.cluster.tasks import BAD_INPUT, PairJob, PairOutcome
from sswjax.cluster.workers import worker_memory
from sswjax.data.io import read_image, read_pfm, write_pfm
from sswjax.runtime.buckets import ShapeBuckets, bucket_shape

__all__ = ["IMAGE_SUFFIXES", "FolderPair", "folder_pairs", "image_size", "match_folders"]

_SINGLE_OUTPUTS = ("png", "confidence", "validity", "depth", "ply", "kitti_png")
"""``sswjax match`` options that name one output file (refused with folders)."""


def _finished(path: Path, size) -> bool:
    """Whether ``path`` holds a readable PFM of the pair's size (what ``--resume`` keeps)."""
    if not path.is_file():
        return False
    try:
        return read_pfm(path).shape == tuple(size[:2])
    except (InputError, OSError):
        return False


AUTO_BUCKETS = 8
"""Distinct image sizes above which a folder run pads its pairs to shape buckets unless told
``--no-bucket``: each size is a compilation (seconds each), each bucket one."""


def _buckets(args: argparse.Namespace, pairs: list[FolderPair]) -> ShapeBuckets | None:
    """The shape buckets of a folder run: ``--bucket``, ``--no-bucket``, or, by default,
    buckets when the pairs come in more than :data:`AUTO_BUCKETS` sizes (said on stderr)."""
    if args.bucket is not None:
        return ShapeBuckets() if args.bucket else None
    sizes = {pair.size[:2] for pair in pairs}
    if len(sizes) <= AUTO_BUCKETS:
        return None
    print(f"sswjax: note: {len(sizes)} image sizes: padding them to shape buckets to compile "
          "fewer graphs (--no-bucket keeps every size)", file=sys.stderr)
    return ShapeBuckets()


def _in_process(jobs: list[PairJob], *, ndisp: int, min_disp: int, params, plan, bar, rectify):
    """The outcome of each job matched here, one after the other (the name on the bar);
    ``rectify(left, right)`` gives the pair matched (with ``--rectify`` the rectified one,
    else the pair as read)."""
    for job in jobs:
        bar.set_postfix_str(job.name)
        start = time.perf_counter()
        try:
            left, right = rectify(read_image(job.left), read_image(job.right))
            disparity = match(left, right, ndisp, min_disp=min_disp, params=params, plan=plan,
                              check_memory=False)  # guard_memory checked it
            write_pfm(job.output, disparity)
        except BAD_INPUT as error:
            yield PairOutcome(job.name, False, first_line(error), time.perf_counter() - start)
            continue
        yield PairOutcome(job.name, True, "", time.perf_counter() - start)


def _check_arguments(args: argparse.Namespace) -> Path:
    """The checks of the folders and the output folder; returns ``-o OUT_DIR``."""
    if os.path.isdir(args.left) != os.path.isdir(args.right):
        folder, other = (args.left, args.right) if os.path.isdir(args.left) else (args.right, args.left)
        raise InputError(f"LEFT and RIGHT must be two image files or two folders: {folder} is a "
                         f"folder, {other} is not")
    given = [f"--{name.replace('_', '-')}" for name in _SINGLE_OUTPUTS
             if getattr(args, name, None) is not None]
    if given:
        raise ValueError(f"{given[0]} names one file: with folders only -o OUT_DIR is written")
    out = args.output
    for name, folder in (("LEFT_DIR", args.left), ("RIGHT_DIR", args.right)):
        if same_file(out, folder):
            raise ValueError(f"-o {out} is the same folder as {name} {folder}: the maps go to "
                             "a folder of their own")
    if out.exists() and not out.is_dir():
        raise ValueError(f"output {out} is a file: with folders -o names a folder")
    if not out.parent.is_dir():
        raise ValueError(f"output folder does not exist: {out.parent}")
    if wants_cluster(args):
        if getattr(args, "rectify", None) is not None:
            raise ValueError("--rectify matches folders in this process: drop --workers / "
                             "--scheduler, or rectify the pairs first with sswjax rectify")
        require_cluster(args)
    return out


def _guard(args, pairs, params, plan, min_disp, client=None):
    """The plan that fits the largest pair, in this process or in each worker."""
    sizes = [p.size for p in pairs]
    if not wants_cluster(args):
        return guard_memory(sizes, args.ndisp, params=params, plan=plan,
                            limit_gb=args.max_memory, min_disp=min_disp)
    share, local, limit_gb = worker_budget(args)
    if client is not None and not local:
        own = worker_memory(client)
        if own is not None:
            limit_gb = own / 1e9 if limit_gb is None else min(limit_gb, own / 1e9)
    return guard_memory(sizes, args.ndisp, params=params, plan=plan, limit_gb=limit_gb,
                        min_disp=min_disp, share=share, local=local)


def _refuse_narrow(args, pairs, min_disp, params) -> None:
    """``ndisp`` must fit the narrowest pair: a setting of the run, refused as a whole (after
    the census window, which the smallest pair must hold: an image 1 pixel wide is too small,
    not a reason for an empty range)."""
    smallest = min(pairs, key=lambda p: min(p.size[:2]))
    check_image_size(smallest.size[1], smallest.size[0], params, where=f"pair {smallest.name}: ")
    narrowest = min(pairs, key=lambda p: p.size[1])
    given = min_disp == 0 or getattr(args, "depth_range", None) is None  # --ndisp N
    if given and not 1 <= args.ndisp < narrowest.size[1]:
        raise ValueError(f"ndisp must be in [1, {narrowest.size[1] - 1}] for the narrowest pair "
                         f"{narrowest.name}, got {args.ndisp}")


def _name_bad_pairs(bad: dict[str, str]) -> None:
    """Each bad pair on a line of its own (stderr), the run going on without them."""
    for name in sorted(bad):
        print(f"sswjax: error: {bad[name]}", file=sys.stderr)


def _summary_error(saved: int, total: int, failed: dict[str, str]) -> InputError:
    """The run's last line when pairs failed: how many maps are there, which pairs failed."""
    names = sorted(failed)
    return InputError(f"{saved} of {total} maps written; {len(names)} "
                      f"pair{'s' if len(names) > 1 else ''} failed: {', '.join(names)} "
                      "(--resume matches the failed ones again)")


def match_folders(args: argparse.Namespace) -> int:
    """``sswjax match LEFT_DIR RIGHT_DIR --ndisp N -o OUT_DIR [--resume] [--bucket] [--strict]
    [--workers N | --scheduler ADDR]``; returns the exit status (0; when a pair failed, the
    others written, it raises ``InputError``: exit status 2).

    The pairs are checked first (:func:`~sswjax.cluster.pairs.checked_pairs`): a bad pair (an
    image that cannot be read, two sizes) is named on a line of its own and the good ones are
    matched; ``--strict`` refuses the whole run instead, before anything is written. What is
    wrong with the run as a whole (the folders, the names, ``ndisp`` against the narrowest
    pair, the memory, the output folder, another run holding it) is refused in one line.
    """
    out = _check_arguments(args)
    params = params_from_args(args)
    min_disp = getattr(args, "min_disp", 0) or 0
    pairs, bad = checked_pairs(args.left, args.right)
    if bad and getattr(args, "strict", False):
        raise bad_pairs_error(bad)
    total = len(pairs) + len(bad)
    buckets = _buckets(args, pairs)
    plan = plan_from_args(args, buckets=buckets)
    settings = {"command": "match", "version": __version__, "params": params.to_dict(),
                "ndisp": args.ndisp, "min_disp": min_disp, "strip_rows": plan.strip_rows,
                "strip_overlap": plan.strip_overlap,
                "buckets": None if buckets is None else list(buckets)}
    if plan.tile:
        settings["tile"] = plan.tile
    if not plan.carry_paths:
        settings["carry_paths"] = False
    if getattr(args, "rectify", None) is not None:
        settings["rectify"] = [str(path) for path in args.rectify]
    remote = getattr(args, "scheduler", None) is not None
    if pairs:
        _refuse_narrow(args, pairs, min_disp, params)
        if not remote:  # a remote cluster's memory is known once connected
            plan = _guard(args, pairs, params, plan, min_disp)
    if not pairs:
        _name_bad_pairs(bad)
        raise _summary_error(0, total, bad)

    def shape(pair):
        height, width = pair.size[:2]
        return (bucket_shape(height, width, args.ndisp, buckets) if buckets else (height, width),
                pair.name)

    pairs.sort(key=shape)
    out.mkdir(exist_ok=True)
    with lock_folder(out) as lock:
        if lock.stale is not None:
            print(f"sswjax: note: {out} was locked by a run that is no longer running "
                  f"({describe_holder(lock.stale)}): taking the lock over", file=sys.stderr)
        _name_bad_pairs(bad)  # once the run is sure to go on
        return _run(args, out, pairs, bad, total, settings, shape, params=params, plan=plan,
                    min_disp=min_disp, remote=remote)


def _run(args, out, pairs, bad, total, settings, shape, *, params, plan, min_disp, remote):
    """The pairs matched into ``out`` (locked), the record kept, the summary said."""
    record = (RunRecord.resume if args.resume else RunRecord.start)(out, settings)
    jobs = [PairJob(p.name, str(p.left), str(p.right), str(out / f"{Path(p.name).stem}.pfm"))
            for p in pairs]
    todo = [job for job, pair in zip(jobs, pairs)
            if not (record.done(Path(job.output).name) and _finished(Path(job.output), pair.size))]
    start, resumed, failed = time.perf_counter(), len(pairs) - len(todo), dict(bad)
    saved, workers = resumed, 0
    session = cluster_session(args) if wants_cluster(args) and todo else contextlib.nullcontext()
    try:
        with session as client, tqdm(total=total, initial=resumed + len(bad), desc="pairs",
                                     unit="pair", file=sys.stderr) as bar:
            if client is None:
                outcomes = _in_process(todo, ndisp=args.ndisp, min_disp=min_disp, params=params,
                                       plan=plan, bar=bar,
                                       rectify=functools.partial(rectify_images, args))
            else:
                workers = len(client.nthreads())
                if remote:
                    plan = _guard(args, pairs, params, plan, min_disp, client)
                outcomes = match_pairs(client, todo, args.ndisp, min_disp=min_disp,
                                       params=params, plan=plan, cache=cache_folder(args))
            for outcome in outcomes:
                if outcome.ok:
                    record.finished(f"{Path(outcome.name).stem}.pfm")
                    saved += 1
                else:
                    failed[outcome.name] = f"pair {outcome.name}: {outcome.message}"
                    bar.write(f"sswjax: error: {failed[outcome.name]}", file=sys.stderr)
                bar.update(1)
                raise_if_interrupted()  # a Ctrl-C that JAX's gc callback dropped
    except KeyboardInterrupt:
        raise Interrupted(f"interrupted; {saved} of {total} disparity maps are saved in "
                          f"{out}; continue with: {resume_command(command_line(args))}") from None
    note = f", {resumed} kept from before" if resumed else ""
    note += f", {len(failed)} failed" if failed else ""
    where = f" on {workers} workers" if workers else ""
    print(f"wrote {saved - resumed} disparity maps to {out}{note} "
          f"({len({shape(p)[0] for p in pairs})} shapes, {time.perf_counter() - start:.1f} s"
          f"{where})")
    if failed:
        raise _summary_error(saved, total, failed)
    return 0
