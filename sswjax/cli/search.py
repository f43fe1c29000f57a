"""``sswjax search``: tune the continuous parameters to the user's own data with ground truth.

Every ``--data`` folder is read as ``sswjax evaluate`` reads it (its layout told by its files;
a user's own folder is best laid out as MiddEval3's: one sub-folder per pair holding
``im0.png``, ``im1.png``, ``disp0GT.pfm`` and a ``calib.txt`` with ``ndisp=N``). Each folder is
one data set. The run: a held-out report (``--held-out``: leave one data set out, or one scene
out), then a search on everything, whose parameters are written to ``-o`` (with the report as
provenance) and load with ``--params``. The search's state lives in a run folder
(``--run-dir``, default ``<output>.search``): each start's checkpoints, each fold's scores;
``--resume`` continues it and never recomputes a finished part.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
from pathlib import Path

import numpy as np

from sswjax._files import InputError, same_file, write_json
from sswjax.cli.common import (Interrupted, check_output_files, command_line, interrupt_flag,
                               resume_command)
from sswjax.cli.options import add_parameter_options, params_from_args
from sswjax.cli.scenes import checked_scenes
from sswjax.config import save_params
from sswjax.data.layouts import detect_layout
from sswjax.search import all_raw_keys, valid_mask
from sswjax.search.held_out import FOLD_MODES, report_markdown, search_with_report
from sswjax.search.settings import SearchSettings
from sswjax.search.surrogates import SURROGATES

__all__ = ["MIN_KNOWN_PIXELS", "add_search_command", "run_search_command"]

MIN_KNOWN_PIXELS = 20_000
"""Ground-truth pixels (known, in range, non-occluded where masked) a search needs at least:
about two crops' worth at the default size. Below it the crops repeat the same few pixels and
the held-out report says nothing."""
_SETTINGS = {  # option -> (SearchSettings field, type, help)
    "--steps": ("steps", int, "Adam steps per start at most (%(default)s)"),
    "--batch": ("batch", int, "crops per step (%(default)s)"),
    "--crop-height": ("crop_height", int, "crop rows (%(default)s)"),
    "--crop-context": ("crop_context", int, "crop columns beyond the disparity range "
                       "(%(default)s)"),
    "--lr": ("lr", float, "Adam's learning rate (%(default)s)"),
    "--surrogate": ("surrogate", str, "the loss (%(default)s; docs/parameter-search.md "
                    "compares them)"),
    "--val-every": ("val_every", int, "steps between validations on whole images "
                    "(%(default)s)"),
    "--val-images": ("val_images", int, "whole training images validated on (%(default)s)"),
    "--patience": ("patience", int, "validations without improvement before a start stops "
                   "(%(default)s)"),
    "--restarts": ("restarts", int, "starts: the preset, then random points around it "
                   "(%(default)s)"),
    "--min-valid": ("min_valid", float, "share of a crop's pixels with ground truth "
                    "(%(default)s)"),
    "--seed": ("seed", int, "random seed (%(default)s)"),
}


def add_search_command(commands) -> None:
    """Add the ``search`` sub-command to ``commands`` (argparse's sub-parsers)."""
    parser = commands.add_parser("search", help="tune the parameters to data with ground truth")
    parser.add_argument("--data", type=Path, action="append", required=True, metavar="DIR",
                        help="a data folder with ground truth, any layout evaluate reads "
                             "(repeatable: each folder is one data set)")
    parser.add_argument("--split", default="trainingQ", help="MiddEval3 sub-folder (trainingQ)")
    parser.add_argument("-o", "--output", type=Path, required=True, metavar="FILE",
                        help="the searched parameters (JSON, for --params)")
    parser.add_argument("--run-dir", type=Path, metavar="DIR",
                        help="the run's checkpoints and scores (default: OUTPUT.search)")
    parser.add_argument("--resume", action="store_true", help="continue the run in --run-dir")
    parser.add_argument("--held-out", choices=("auto",) + FOLD_MODES, default="auto",
                        help="the report's folds: datasets (leave one --data out), scenes "
                             "(leave one scene out), none; auto: datasets with two --data or "
                             "more, else scenes")
    parser.add_argument("--freeze", nargs="*", default=list(SearchSettings().frozen),
                        choices=all_raw_keys(), metavar="KEY",
                        help="search variables held at their start (%(default)s; an empty "
                             "--freeze moves all), of %(choices)s")
    parser.add_argument("--no-grid", action="store_true", help="skip the grid over the options "
                        "without a gradient (occlusion gaps, tolerances, the smoothing's gate) "
                        "after the continuous search")
    defaults = SearchSettings()
    for flag, (field, kind, text) in _SETTINGS.items():
        parser.add_argument(flag, type=kind, default=getattr(defaults, field), help=text,
                            **({"choices": list(SURROGATES)} if field == "surrogate" else {}))
    add_parameter_options(parser, "the starting")
    parser.set_defaults(run=run_search_command, scenes=None, ndisp=None, skip_bad=False)


def _data_sets(args) -> dict:
    """``{name: (scenes, scoring)}`` of the ``--data`` folders, refusing too little truth."""
    sets = {}
    for root in args.data:
        if not root.is_dir():
            raise InputError(f"--data {root}: no such folder")
        layout = detect_layout(root, split=args.split)
        scenes, _ = checked_scenes(root, layout, args)
        name = root.name if root.name not in sets else str(root)
        sets[name] = (scenes, layout.scoring)
    known = sum(int(valid_mask(s.ground_truth, s.mask, ndisp=s.ndisp).sum())
                for scenes, _ in sets.values() for s in scenes)
    count = sum(len(scenes) for scenes, _ in sets.values())
    if known < MIN_KNOWN_PIXELS:
        raise InputError(f"too little ground truth to search: {count} scene(s) with {known:,} "
                         f"known pixels in range, at least {MIN_KNOWN_PIXELS:,} needed")
    return sets


def _settings(args) -> SearchSettings:
    values = {field: getattr(args, flag[2:].replace("-", "_")) for flag, (field, _, _)
              in _SETTINGS.items()}
    return SearchSettings(**values, frozen=tuple(args.freeze), grid=not args.no_grid)


def _check_run_dir(run_dir: Path, resume: bool, recorded: dict) -> None:
    """Refuse a run folder that holds another run, or a resume without one."""
    path = run_dir / "run.json"
    if not resume:
        if path.exists():
            raise InputError(f"{run_dir} holds a search run: pass --resume to continue it, or "
                             "name another --run-dir")
        return
    if not path.exists():
        raise InputError(f"--resume: {run_dir} holds no search run")
    stored = json.loads(path.read_text())
    changed = sorted(k for k in recorded if stored.get(k) != recorded[k])
    if changed:
        raise InputError(f"--resume: {run_dir} was run with other {', '.join(changed)}; name "
                         "another --run-dir to search with these")


def run_search_command(args: argparse.Namespace) -> int:
    """Run ``sswjax search``; return the exit status."""
    base = params_from_args(args)
    if base.coarse is not None:
        raise ValueError("the search runs the full-resolution volume; a preset with a coarse "
                         "pass (coarse is set) cannot be searched: start from accurate, paper "
                         "or finest")
    if base.band is not None:
        raise ValueError("the search runs the full-range volume; a configuration with a band "
                         "(band is set) cannot be searched: start from accurate, paper or finest")
    settings = _settings(args)
    output = args.output
    check_output_files(output)
    if args.params is not None and same_file(output, args.params):
        raise InputError(f"-o {output} is the --params file: it would be overwritten")
    sets = _data_sets(args)
    mode = args.held_out
    if mode == "auto":
        mode = "datasets" if len(sets) > 1 else "scenes"
    run_dir = args.run_dir or output.with_name(output.name + ".search")
    recorded = {"data": [str(p.resolve()) for p in args.data], "split": args.split,
                "held_out": mode, "settings": settings.to_dict(), "start": base.to_dict()}
    _check_run_dir(run_dir, args.resume, recorded)
    run_dir.mkdir(parents=True, exist_ok=True)
    write_json(run_dir / "run.json", recorded)
    count = sum(len(s) for s, _ in sets.values())
    print(f"searching on {count} scenes of {len(sets)} data set(s); held out: {mode}; run "
          f"folder {run_dir}", file=sys.stderr, flush=True)
    try:
        with interrupt_flag() as interrupted:
            final, report = search_with_report(sets, base, settings, folder=run_dir, mode=mode,
                                               interrupted=interrupted)
    except KeyboardInterrupt:
        raise Interrupted(f"interrupted; the finished steps are kept in {run_dir}: "
                          f"{resume_command(command_line(args))} continues") from None
    if report["folds"]:
        print(report_markdown(report))
    provenance = {
        "how": "sswjax search: Adam on random crops through the search volume, surrogate "
               f"{settings.surrogate}, best validated point of {settings.restarts} start(s)",
        "data": recorded["data"], "command": " ".join(["sswjax", *command_line(args)]),
        "date": datetime.date.today().isoformat(), "settings": settings.to_dict(),
        "validation_bad2": {"start": final.start_validation, "searched": final.validation},
        "held_out": report["folds"] and [
            {k: fold[k] for k in ("held_out", "base", "searched")} for fold in report["folds"]],
    }
    save_params(output, final.params, provenance=json.loads(json.dumps(provenance,
                                                                       default=_plain)))
    print(f"wrote {output} (validation bad 2.0 {final.start_validation:.2f} -> "
          f"{final.validation:.2f} %)", file=sys.stderr)
    return 0


def _plain(value):
    """JSON for NumPy scalars in the provenance."""
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON: {type(value).__name__}")
