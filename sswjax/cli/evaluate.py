"""``sswjax evaluate``: methods over a data folder; tables, CSV, figure, disparities.

The folder's layout (:func:`sswjax.data.layouts.detect_layout`: MiddEval3, KITTI, older
Middlebury, ETH3D) sets the metrics and their summary (:data:`sswjax.evaluation.runner.SCORINGS`):
MiddEval3's weighted averages and Table 1, elsewhere means over scenes with bad 3.0 (and D1
for KITTI). ``--ndisp`` replaces every scene's disparity count; ``--ndisp auto`` has the SSW
methods search the range estimated from each pair, the default where the layout's files carry
no search range (:attr:`~sswjax.data.layouts.Layout.estimates_range`: ETH3D), and ``--ndisp
layout`` the layout's own range there too.

Every scene is loaded and checked before any is matched (:mod:`sswjax.cli.scenes`): when some
cannot be scored the run refuses with one line naming each and why, unless ``--skip-bad``
scores the others (MiddEval3's weights then renormalised over them) and reports the skipped.

With ``-o``, each scene's disparity and time are written as soon as the scene is done, so
Ctrl-C keeps the finished scenes and ``--resume`` continues without recomputing them (their
disparities are read back and their metrics recomputed). A folder that is not empty is refused
without ``--resume`` (an earlier run's method folders would stay beside the new tables) or
``--overwrite``, which removes first what the earlier run's record lists and its summaries
(:data:`SUMMARIES`), never other files. The optional packages the options need (matplotlib for
``--figure``, a peer's) are checked before any scene is read. With ``--bucket`` the SSW methods
are :class:`~sswjax.evaluation.methods.BucketedSSW`: their scenes run grouped by bucket, one
pair per JAX device per call, and a scene's time is its call's time divided by the pairs in it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from sswjax._files import InputError, atomic_output, first_line
from sswjax._version import __version__
from sswjax.cli.common import (Interrupted, command_line, raise_if_interrupted, resume_command,
                               uninterrupted)
from sswjax.cli.options import add_parameter_options, params_from_args
from sswjax.cli.record import RECORD_NAME, RunRecord
from sswjax.cli.scenes import Problems, checked_scenes, ndisp_line, skipped_markdown
from sswjax.data.io import read_pfm, write_pfm
from sswjax.data.layouts import StereoScene, detect_layout, find_data_root
from sswjax.evaluation.figures import check_matplotlib, comparison_figure
from sswjax.evaluation.methods import (check_dependencies, make_method, method_summaries,
                                       submission_name)
from sswjax.evaluation.runner import (SCORINGS, SceneResult, Scoring, evaluate_scene,
                                      iter_evaluate_scenes, markdown_table, summary_markdown,
                                      table1_markdown, write_metrics_csv)
from sswjax.runtime.buckets import ShapeBuckets

__all__ = ["SUMMARIES", "add_evaluate_command", "run_evaluate"]

SUMMARIES = ("results.md", "metrics.csv", "comparison.png")
"""What a run with ``-o`` writes at its end, beside its record's scene results."""


def _methods_help() -> str:
    """``--methods`` help from the catalogue: every method name with its one-line summary."""
    listed = "; ".join(f"{name}: {summary}" for name, summary in method_summaries().items())
    return f"comma-separated method names (default ssw). {listed}".replace("%", "%%")


def _ndisp_option(text: str):
    """``--ndisp``: a positive count, ``auto`` or ``layout``."""
    if text in ("auto", "layout"):
        return text
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a count, 'auto' or 'layout', got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def add_evaluate_command(commands) -> None:
    """Add the ``evaluate`` sub-command to ``commands`` (argparse's sub-parsers)."""
    parser = commands.add_parser("evaluate", help="score methods on MiddEval3 scenes")
    parser.add_argument("--data", type=Path, help="data folder: MiddEval3, KITTI 2012/2015, "
                        "Middlebury 2001/2003/2005/2006 or ETH3D two-view, told by its files "
                        "(default: $SSWJAX_DATA, then ../shared/data/MiddEval3 beside the project)")
    parser.add_argument("--split", default="trainingQ", help="sub-folder of the data (trainingQ)")
    parser.add_argument("--ndisp", type=_ndisp_option,
                        help="disparities searched in every scene, 0..N-1; auto: the SSW "
                             "methods search the range estimated from each pair (as match "
                             "--ndisp auto; the peers keep the layout's), scored over the "
                             "layout's range; layout: the layout's range (calib.txt for "
                             "MiddEval3; elsewhere the smallest multiple of 8 >= max GT + 2). "
                             "Default: auto for ETH3D, whose files carry no range; elsewhere "
                             "layout")
    parser.add_argument("--scenes", nargs="+", help="only these scenes")
    parser.add_argument("--methods", default="ssw", help=_methods_help())
    add_parameter_options(parser, "the base")
    parser.add_argument("-o", "--output", type=Path,
                        help="folder for disparities (MiddEval3 layout), results.md, metrics.csv")
    parser.add_argument("--figure", action="store_true",
                        help="also write comparison.png (needs matplotlib)")
    parser.add_argument("--bucket", action="store_true",
                        help="pad pairs to a few bucketed shapes: fewer compilations (3 for "
                             "trainingQ), the same maps, slower warm runs; SSW methods then run "
                             "one pair per JAX device per call, over all devices (a scene's time: "
                             "its call's time / its pairs)")
    parser.add_argument("--skip-bad", action="store_true",
                        help="score the scenes that can be scored and list the others with why "
                             "(on stderr and in results.md); by default a run with any scene "
                             "that cannot be scored (broken or missing file, no known ground "
                             "truth) is refused, naming them all")
    parser.add_argument("--resume", action="store_true",
                        help="continue an interrupted run: keep the scenes already in -o "
                             "(disparity and time files) instead of recomputing them")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an earlier run in -o: first remove what its record "
                             f"({RECORD_NAME}) lists and its {', '.join(SUMMARIES)}, never "
                             "other files (without it or --resume, a folder that is not empty "
                             "is refused)")
    parser.set_defaults(run=run_evaluate)


def _write_scene_result(folder: Path, tag: str, result: SceneResult) -> None:
    """Atomically write one scene's ``disp0<TAG>.pfm`` and ``time<TAG>.txt``.

    The disparity goes first: ``--resume`` needs both files, so an interruption between the two
    writes costs a recomputation but never pairs a new time with an old disparity map.
    """
    folder.mkdir(parents=True, exist_ok=True)
    write_pfm(folder / f"disp0{tag}.pfm", result.disparity)
    with atomic_output(folder / f"time{tag}.txt") as tmp:
        tmp.write_text(f"{result.seconds:.3f}\n")


def _saved_scene_result(folder: Path, tag: str, scene: StereoScene, scoring: Scoring):
    """A scene's result read back from ``folder`` (metrics recomputed) and a note for the user.

    Returns ``(None, None)`` when the files are absent and ``(None, reason)`` when they cannot
    be used (the scene is then recomputed).
    """
    pfm, time_file = folder / f"disp0{tag}.pfm", folder / f"time{tag}.txt"
    if not (pfm.is_file() and time_file.is_file()):
        return None, None
    try:
        disparity = read_pfm(pfm)
        seconds = float(time_file.read_text(encoding="ascii").strip())
    except (InputError, OSError, UnicodeDecodeError, ValueError) as error:
        return None, f"saved result unusable ({first_line(error)}), recomputing"
    expected = scene.left.shape[:2]
    if disparity.shape != expected:
        return None, (f"saved disparity has shape {disparity.shape}, the scene {expected}, "
                      "recomputing")
    if not (np.isfinite(seconds) and seconds >= 0):
        return None, f"saved time {seconds} in {time_file.name} is not valid, recomputing"
    result = evaluate_scene(lambda left, right, ndisp: disparity, scene, scoring=scoring)
    return result._replace(seconds=seconds), None


def _earlier_outputs(folder: Path | None, *, resume: bool, overwrite: bool) -> list[Path]:
    """The files of an earlier run in ``folder`` that this run removes before it starts (with
    ``--overwrite``; none otherwise).

    Raises ``ValueError`` (one line) for a folder that is not empty without ``--resume`` or
    ``--overwrite``, and with ``--overwrite`` for one without the record of an evaluate run.
    """
    if folder is None or resume or not folder.exists():
        return []
    if not folder.is_dir():
        raise ValueError(f"output {folder} is a file: -o names a folder")
    if next(folder.iterdir(), None) is None:
        return []
    if not overwrite:
        raise ValueError(f"{folder} is not empty: add --resume to continue its run or "
                         "--overwrite to replace what an earlier run wrote there")
    try:
        stored = json.loads((folder / RECORD_NAME).read_text(encoding="utf-8"))
        command = stored["settings"]["command"]
        finished = list(stored["maps"] if "maps" in stored else stored["finished"])  # names
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError):
        command, finished = None, []
    if command != "evaluate":
        raise ValueError(f"{folder} holds no record of an earlier sswjax evaluate run "
                         f"({RECORD_NAME}): --overwrite replaces only what such a run wrote; "
                         "empty the folder or choose another")
    paths = [folder / name for name in SUMMARIES]
    for entry in finished:  # "method/scene", as run_evaluate records them
        parts = entry.split("/") if isinstance(entry, str) else []
        if len(parts) != 2 or any(part in ("", ".", "..") or os.sep in part for part in parts):
            continue
        method, scene = parts
        tag = submission_name(method)
        paths += [folder / method / scene / f"disp0{tag}.pfm",
                  folder / method / scene / f"time{tag}.txt"]
    return paths + [folder / RECORD_NAME]


def _remove(folder: Path, paths: list[Path]) -> None:
    """Remove the files ``paths`` under ``folder``, then their folders below it left empty."""
    for path in paths:
        if path.is_file() or path.is_symlink():
            path.unlink()
    for path in paths:
        for parent in (path.parent, path.parent.parent):
            if parent != folder and folder in parent.parents and parent.is_dir() \
                    and next(parent.iterdir(), None) is None:
                parent.rmdir()


def _report(results: dict, scenes: list[StereoScene], layout, scoring: Scoring, *,
            root: Path, problems: Problems, ndisp: int | None) -> str:
    """The markdown of the run: the summary, the skipped scenes, then one table per method."""
    scored = f"{len(scenes)} scored scene{'s' * (len(scenes) > 1)}, {len(problems)} skipped"
    if layout.scoring == "middeval3":
        weights = f"MiddEval3 weights renormalised over the {scored}" if problems else \
            "MiddEval3 weights"
        table1 = f" (averages over the {scored}, weights renormalised)" if problems else ""
        heads = [f"## Weighted averages ({weights}, bad-pixel % at Q resolution)",
                 summary_markdown(results),
                 f"## Table 1 layout, bad 2.0 (ours) beside the paper's figures{table1}",
                 table1_markdown(results)]
    else:
        skipped = f", {len(problems)} skipped" if problems else ""
        heads = [f"## Means over {len(scenes)} {layout.name} scenes (no weights{skipped}; "
                 f"bad-pixel %{', KITTI D1 %' if scoring.d1 else ''})",
                 summary_markdown(results, scoring=scoring)]
    heads.insert(2, ndisp_line(layout, ndisp))
    if problems:
        heads.insert(3, skipped_markdown(problems, root))
    return "\n\n".join(heads + [f"## {name}\n\n{markdown_table(rows, scoring=scoring)}"
                                for name, rows in results.items()])


def run_evaluate(args: argparse.Namespace) -> int:
    """``sswjax evaluate``; returns the exit status (0)."""
    if args.resume and args.output is None:
        raise ValueError("--resume needs -o/--output: the folder of the run to continue")
    if args.overwrite and args.output is None:
        raise ValueError("--overwrite needs -o/--output: the folder of the run to replace")
    if args.resume and args.overwrite:
        raise ValueError(f"--resume continues the run in {args.output} and --overwrite "
                         "replaces it: give one")
    if args.figure and args.output is None:
        raise ValueError("--figure writes comparison.png into the -o folder: give -o DIR")
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    if not methods:
        raise ValueError(f"no method given in --methods {args.methods!r}")
    if args.figure:
        check_matplotlib(what="--figure")
    check_dependencies(methods)
    earlier = _earlier_outputs(args.output, resume=args.resume, overwrite=args.overwrite)
    params = params_from_args(args)
    root = find_data_root(data=args.data)
    layout = detect_layout(root, split=args.split)
    searched = args.ndisp if args.ndisp is not None else \
        "auto" if layout.estimates_range else "layout"
    estimated = searched == "auto"
    if estimated and args.bucket:
        raise ValueError(
            "--ndisp auto gives each pair its own range, which --bucket cannot batch: drop one "
            "of them" if args.ndisp else
            f"{layout.name} pairs search a range estimated from each pair by default, which "
            "--bucket cannot batch: give --ndisp layout (the layout's range) or --ndisp N")
    buckets = ShapeBuckets() if args.bucket else None
    runners = {name: make_method(name, params=params, buckets=buckets, estimate_range=estimated)
               for name in methods}
    scoring = SCORINGS[layout.scoring]
    scene_args = argparse.Namespace(
        **{**vars(args), "ndisp": searched if isinstance(searched, int) else None})
    scenes, problems = checked_scenes(root, layout, scene_args)
    record = None
    if args.output is not None:
        settings = {"command": "evaluate", "version": __version__, "params": params.to_dict(),
                    "data": str(Path(root).resolve()), "split": args.split, "ndisp": args.ndisp,
                    "bucket": bool(args.bucket)}
        _remove(args.output, earlier)
        record = (RunRecord.resume if args.resume else RunRecord.start)(args.output, settings)
    results = {}
    saved, total = 0, len(runners) * len(scenes)
    try:
        for name, method in runners.items():
            tag = submission_name(name)
            rows = results[name] = [None] * len(scenes)
            folders = [None if args.output is None else args.output / name / scene.name
                       for scene in scenes]
            print(f"{name}:", file=sys.stderr)
            with tqdm(total=len(scenes), desc="scenes", unit="scene", file=sys.stderr) as bar:
                for i, scene in enumerate(scenes):
                    if args.resume and record.done(f"{name}/{scene.name}"):
                        rows[i], note = _saved_scene_result(folders[i], tag, scene, scoring)
                        if note:
                            bar.write(f"{name} {scene.name}: {note}", file=sys.stderr)
                resumed = sum(row is not None for row in rows)
                saved += resumed
                bar.update(resumed)
                pending = [i for i, row in enumerate(rows) if row is None]
                for j, result in iter_evaluate_scenes(method, [scenes[i] for i in pending],
                                                      scoring=scoring):
                    i = pending[j]
                    if folders[i] is not None:
                        with uninterrupted():  # files, record and count kept together
                            _write_scene_result(folders[i], tag, result)
                            record.finished(f"{name}/{scenes[i].name}")
                            saved += 1
                    rows[i] = result
                    bar.update(1)
                    raise_if_interrupted()  # a Ctrl-C that JAX's gc callback dropped
            if args.resume:
                print(f"{name}: resumed {resumed} of {len(scenes)} scenes from "
                      f"{args.output / name}", file=sys.stderr)
    except KeyboardInterrupt:
        if args.output is None:
            raise Interrupted("interrupted; nothing was saved (with -o DIR finished scenes are "
                              "kept and --resume continues)") from None
        raise Interrupted(f"interrupted; {saved} of {total} scene results are saved in "
                          f"{args.output}; continue with: "
                          f"{resume_command(command_line(args))}") from None
    text = _report(results, scenes, layout, scoring, root=root, problems=problems,
                   ndisp=searched)
    print(text)
    if args.output is not None:
        with atomic_output(args.output / "results.md") as tmp:
            tmp.write_text(text + "\n")
        write_metrics_csv(args.output / "metrics.csv", results)
        if args.figure:
            comparison_figure(args.output / "comparison.png", scenes, results)
        print(f"wrote {args.output}")
    return 0
