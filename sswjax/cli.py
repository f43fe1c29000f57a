"""The ``sswjax`` command line: ``match``, ``demo``, ``evaluate`` and ``download``.

Errors in the user's input (files, sizes, parameters) print one line on stderr and exit with
status 2; ``--debug`` shows the traceback instead. Every output is written to a temporary file
and renamed into place, so an existing file survives a failed run. Ctrl-C exits with status 130;
``sswjax evaluate -o DIR`` writes each scene as soon as it is done, and its ``--resume``
continues an interrupted run without recomputing the finished scenes.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, the shell's convention


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit status 2 (argparse's own convention)."""

    def error(self, message: str):  # noqa: D102
        self.exit(EXIT_USAGE, f"sswjax: error: {message}\n")


def _params(args):
    """The parameters a command asked for: ``--params FILE``, else ``--preset NAME``, else the
    default preset (``accurate``)."""
    from sswjax.params import default_params, load_params, preset

    if args.params is not None:
        return load_params(args.params)
    return default_params() if args.preset is None else preset(args.preset)


def _add_parameter_options(parser, what: str) -> None:
    """``--preset NAME`` or ``--params FILE`` (not both), help from the registry."""
    from sswjax.registry import DEFAULT_PRESET, preset_summaries

    group = parser.add_mutually_exclusive_group()
    presets = "; ".join(f"{name}: {summary}" for name, summary in preset_summaries().items())
    group.add_argument("--preset", choices=list(preset_summaries()),
                       help=f"{what} parameters by name (default: {DEFAULT_PRESET}). {presets}")
    group.add_argument("--params", type=Path, help=f"{what} parameters from a JSON file")


def _write_outputs(disparity: np.ndarray, pfm: Path | None, png: Path | None, ndisp: int, *,
                   min_disp: int = 0) -> None:
    from sswjax.data.io import write_disparity_png, write_pfm

    if pfm is not None:
        write_pfm(pfm, disparity)
    if png is not None:
        write_disparity_png(png, disparity, vmin=min_disp, vmax=min_disp + ndisp - 1)


def _check_output_dir(*paths: Path | None) -> None:
    """Fail before any work if an output file cannot be created where the user asked."""
    for path in paths:
        if path is None:
            continue
        if path.is_dir():
            raise ValueError(f"output {path} is a folder, expected a file name")
        if not path.parent.is_dir():
            raise ValueError(f"output folder does not exist: {path.parent}")


def _add_geometry_options(parser) -> None:
    """``match``'s disparity range and the outputs beyond the map: depth, point cloud, KITTI."""
    parser.add_argument("--min-disp", type=int, default=0, metavar="M",
                        help="first disparity searched, may be negative: M..M+N-1 (default 0)")
    parser.add_argument("--kitti-png", type=Path, metavar="OUT.png",
                        help="also write KITTI's 16-bit PNG (disparity x 256, 0 = invalid)")
    parser.add_argument("--depth", type=Path, metavar="DEPTH.pfm",
                        help="also write the depth baseline * f / (d + doffs) as PFM (inf where "
                             "d + doffs <= 0); needs --calib or --focal and --baseline")
    parser.add_argument("--ply", type=Path, metavar="CLOUD.ply",
                        help="also write the pixels of finite positive depth as a binary PLY "
                             "point cloud with the left image's colours")
    rig = parser.add_mutually_exclusive_group()
    rig.add_argument("--calib", type=Path, metavar="calib.txt",
                     help="Middlebury calibration: cam0 (focal length, principal point), "
                          "baseline, doffs")
    rig.add_argument("--focal", type=float, metavar="F", help="focal length in pixels")
    parser.add_argument("--baseline", type=float, metavar="B",
                        help="with --focal: camera distance (depth comes out in its unit)")
    parser.add_argument("--doffs", type=float, metavar="D",
                        help="with --focal: x-difference of the principal points (default 0)")
    parser.add_argument("--principal", type=float, nargs=2, metavar=("CX", "CY"),
                        help="with --focal: principal point (default: the image centre)")


def _calibration(args):
    """The rig of ``--calib`` or ``--focal/--baseline/...`` (None when neither is given)."""
    from sswjax.geometry import Calibration, check_calibration, read_calibration

    by_hand = [f"--{name}" for name in ("baseline", "doffs", "principal")
               if getattr(args, name) is not None]
    options, one = ", ".join(by_hand), len(by_hand) == 1
    if args.calib is not None:
        if by_hand:
            raise ValueError(f"{options} {'goes' if one else 'go'} with --focal, not --calib "
                             "(the file gives it)")
        return read_calibration(args.calib)
    if args.focal is None:
        if by_hand:
            raise ValueError(f"{options} {'needs' if one else 'need'} --focal")
        if args.depth is not None or args.ply is not None:
            raise ValueError("--depth and --ply need --calib FILE or --focal F --baseline B")
        return None
    if args.baseline is None:
        raise ValueError("--focal needs --baseline")
    principal = None if args.principal is None else tuple(args.principal)
    return check_calibration(Calibration(args.focal, args.baseline, args.doffs or 0.0,
                                         principal))


def _write_geometry_outputs(args, disparity: np.ndarray, left: np.ndarray, calib) -> None:
    """``--kitti-png``, ``--depth`` and ``--ply`` of ``match``."""
    from sswjax.data.io import write_pfm
    from sswjax.data.layouts import write_scaled_disparity
    from sswjax.geometry import depth_from_disparity, point_cloud, write_ply

    if args.kitti_png is not None:
        write_scaled_disparity(args.kitti_png, disparity, scale=256)
    if args.depth is not None:
        write_pfm(args.depth, depth_from_disparity(disparity, focal=calib.focal,
                                                   baseline=calib.baseline, doffs=calib.doffs))
    if args.ply is not None:
        write_ply(args.ply, *point_cloud(disparity, left, calib))


def cmd_match(args) -> int:
    """``sswjax match LEFT RIGHT --ndisp N -o OUT.pfm`` (folders: :mod:`sswjax.folders`)."""
    import sswjax
    from sswjax.data.io import read_image
    from sswjax.cli_confidence import invalid_as_inf, wants_confidence, write_confidence_outputs
    from sswjax.folders import guard_pair, match_folders

    if os.path.isdir(args.left) or os.path.isdir(args.right):  # never raises
        if wants_confidence(args):
            raise ValueError("--confidence, --validity and --invalid-as-inf take one pair, "
                             "not folders")
        return match_folders(args)
    _check_output_dir(args.output, args.png, args.kitti_png, args.depth, args.ply,
                      args.confidence, args.validity)
    calib = _calibration(args)
    params = _params(args)
    params = guard_pair(args, params)
    left, right = read_image(args.left), read_image(args.right)
    start = time.perf_counter()
    if wants_confidence(args):
        matched = sswjax.match_with_confidence(left, right, args.ndisp, min_disp=args.min_disp,
                                               params=params, low_confidence=args.low_confidence,
                                               check_memory=False)  # guard_pair checked it
        disparity = matched.disparity
        if args.invalid_as_inf:
            disparity = invalid_as_inf(disparity, matched.validity)
        write_confidence_outputs(matched, confidence=args.confidence, validity=args.validity)
    else:
        disparity = sswjax.match(left, right, args.ndisp, min_disp=args.min_disp, params=params,
                                 check_memory=False)  # guard_pair checked it
    seconds = time.perf_counter() - start
    _write_outputs(disparity, args.output, args.png, args.ndisp, min_disp=args.min_disp)
    _write_geometry_outputs(args, disparity, left, calib)
    print(f"wrote {args.output} ({disparity.shape[1]}x{disparity.shape[0]}, {seconds:.2f} s)")
    return 0


DEMO_NDISP = 70  # Middlebury Motorcycle at this resolution (MiddEval3 trainingQ calib.txt)


def cmd_demo(args) -> int:
    """``sswjax demo``: the Motorcycle pair that scikit-image ships, scored against its GT."""
    import skimage.data

    import sswjax
    from sswjax.evaluation.metrics import evaluate_disparity

    out = args.output
    out.mkdir(parents=True, exist_ok=True)
    left, right, ground_truth = skimage.data.stereo_motorcycle()
    params = _params(args)
    start = time.perf_counter()
    disparity = sswjax.match(left, right, DEMO_NDISP, params=params)
    seconds = time.perf_counter() - start
    _write_outputs(disparity, out / "disp0SSW.pfm", out / "disp0SSW.png", DEMO_NDISP)
    ground_truth = np.where(np.isfinite(ground_truth), ground_truth, np.inf).astype(np.float32)
    metrics = evaluate_disparity(disparity, ground_truth, ndisp=DEMO_NDISP)["all"]
    print(f"Motorcycle (scikit-image), {left.shape[1]}x{left.shape[0]}, ndisp {DEMO_NDISP}: "
          f"{seconds:.2f} s including compilation")
    print("bad-pixel error over pixels with known ground truth:")
    for threshold in ("2.0", "1.0", "0.5"):
        print(f"  bad {threshold}: {metrics['bad' + threshold]:6.2f} %")
    print(f"  avgerr  : {metrics['avgerr']:6.3f} px")
    print(f"wrote {out / 'disp0SSW.pfm'} and {out / 'disp0SSW.png'}")
    return 0


class Interrupted(KeyboardInterrupt):
    """Ctrl-C, carrying the one-line message shown to the user (what was kept, how to resume)."""


def _resume_command(argv: list[str]) -> str:
    """The user's command line with ``--resume`` added (once)."""
    return shlex.join(["sswjax", *argv] + ([] if "--resume" in argv else ["--resume"]))


def _write_scene_result(folder: Path, tag: str, result) -> None:
    """Atomically write one scene's ``disp0<TAG>.pfm`` and ``time<TAG>.txt``.

    The disparity goes first: ``--resume`` needs both files, so an interruption between the two
    writes costs a recomputation but never pairs a new time with an old disparity map.
    """
    from sswjax.data.io import atomic_output, write_pfm

    folder.mkdir(parents=True, exist_ok=True)
    write_pfm(folder / f"disp0{tag}.pfm", result.disparity)
    with atomic_output(folder / f"time{tag}.txt") as tmp:
        tmp.write_text(f"{result.seconds:.3f}\n")


def _saved_scene_result(folder: Path, tag: str, scene):
    """A scene's result read back from ``folder`` (metrics recomputed) and a note for the user.

    Returns ``(None, None)`` when the files are absent and ``(None, reason)`` when they cannot
    be used (the scene is then recomputed).
    """
    from sswjax.evaluation.runner import evaluate_scene
    from sswjax.data.io import InputError, first_line, read_pfm

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
    result = evaluate_scene(lambda left, right, ndisp: disparity, scene)
    return result._replace(seconds=seconds), None


def cmd_evaluate(args) -> int:
    """``sswjax evaluate``: methods over a data folder; tables, CSV, figure, disparities.

    The folder's layout (:func:`sswjax.data.layouts.detect_layout`: MiddEval3, KITTI, older
    Middlebury) sets the metrics and their summary: MiddEval3's weighted averages and Table 1,
    elsewhere means over scenes with bad 3.0 (and D1 for KITTI). ``--ndisp`` replaces every
    scene's disparity count.

    With ``-o``, each scene's disparity and time are written as soon as the scene is done, so
    Ctrl-C keeps the finished scenes and ``--resume`` continues without recomputing them (their
    disparities are read back and their metrics recomputed). With ``--bucket`` the SSW methods
    are :class:`~sswjax.evaluation.methods.BucketedSSW`: their scenes run grouped by bucket, one pair per
    JAX device per call, and a scene's time is its call's time divided by the pairs in it.
    """
    from tqdm import tqdm

    from sswjax.data.datasets import find_data_root
    from sswjax.data.layouts import detect_layout, load_scenes
    from sswjax.evaluation.runner import (
        SCORINGS,
        iter_evaluate_scenes,
        markdown_table,
        rescore,
        summary_markdown,
        table1_markdown,
        write_metrics_csv,
    )
    from sswjax.data.io import atomic_output
    from sswjax.api import ShapeBuckets
    from sswjax.evaluation.methods import make_method, submission_name

    if args.resume and args.output is None:
        raise ValueError("--resume needs -o/--output: the folder of the run to continue")
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    if not methods:
        raise ValueError(f"no method given in --methods {args.methods!r}")
    buckets = ShapeBuckets() if args.bucket else None
    runners = {name: make_method(name, params=_params(args), buckets=buckets) for name in methods}
    root = find_data_root(data=args.data)
    layout = detect_layout(root, split=args.split)
    scoring = SCORINGS[layout.scoring]
    scenes = load_scenes(root, layout=layout, split=args.split, scenes=args.scenes, ndisp=args.ndisp)
    required = [("ground_truth", layout.ground_truth or "disp0GT.pfm")]
    required += [("mask", "mask0nocc.png")] if layout.kind in ("middeval3", "eth3d") else []
    for attribute, file in required:
        lacking = [scene.name for scene in scenes if getattr(scene, attribute) is None]
        if lacking:
            raise ValueError(f"cannot score scene(s) without {file}: {', '.join(lacking)} "
                             f"in {scenes[0].path.parent}")
    if args.output is not None:
        args.output.mkdir(parents=True, exist_ok=True)
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
                    if args.resume:
                        rows[i], note = _saved_scene_result(folders[i], tag, scene)
                        if rows[i] is not None and layout.kind != "middeval3":
                            rows[i] = rescore(rows[i], scene, scoring=scoring)
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
                        _write_scene_result(folders[i], tag, result)
                        saved += 1
                    rows[i] = result
                    bar.update(1)
            if args.resume:
                print(f"{name}: resumed {resumed} of {len(scenes)} scenes from {args.output / name}",
                      file=sys.stderr)
    except KeyboardInterrupt:
        if args.output is None:
            raise Interrupted("interrupted; nothing was saved (with -o DIR finished scenes are kept "
                              "and --resume continues)") from None
        raise Interrupted(f"interrupted; {saved} of {total} scene results are saved in {args.output}; "
                          f"continue with: {_resume_command(getattr(args, 'argv', sys.argv[1:]))}") from None
    if layout.kind == "middeval3":
        heads = ["## Weighted averages (MiddEval3 weights, bad-pixel % at Q resolution)",
                 summary_markdown(results),
                 "## Table 1 layout, bad 2.0 (ours) beside the paper's figures", table1_markdown(results)]
    else:
        heads = [f"## Means over {len(scenes)} {layout.name} scenes (no weights; bad-pixel %"
                 f"{', KITTI D1 %' if scoring.d1 else ''})", summary_markdown(results, scoring=scoring)]
    text = "\n\n".join(
        heads + [f"## {name}\n\n{markdown_table(rows, scoring=scoring)}" for name, rows in results.items()]
    )
    print(text)
    if args.output is not None:
        with atomic_output(args.output / "results.md") as tmp:
            tmp.write_text(text + "\n")
        write_metrics_csv(args.output / "metrics.csv", results)
        if args.figure:
            from sswjax.evaluation.figures import comparison_figure

            comparison_figure(args.output / "comparison.png", scenes, results)
        print(f"wrote {args.output}")
    return 0


def cmd_download(args) -> int:
    """``sswjax download middlebury|eth3d|kitti``: fetch and unpack a data set's archives
    (KITTI: a one-line message on how to get it, exit 2)."""
    from sswjax.data import download

    if args.dataset == "kitti":
        raise ValueError(download.KITTI_HOWTO.replace("DIR", str(args.dest)))
    if args.dataset == "eth3d":
        root = download.download_eth3d(args.dest, keep_archives=args.keep_archives)
        print(f"ETH3D two-view ready in {root}; evaluate with: sswjax evaluate --data {root}")
        return 0
    download_middeval3 = download.download_middeval3
    root = download_middeval3(args.dest, resolution=args.resolution, keep_archives=args.keep_archives)
    print(f"MiddEval3 {args.resolution} ready in {root}; evaluate with: sswjax evaluate --data {root}")
    return 0


def _methods_help() -> str:
    """``--methods`` help from the registry: every method name with its one-line summary."""
    from sswjax.registry import method_summaries

    listed = "; ".join(f"{name}: {summary}" for name, summary in method_summaries().items())
    return f"comma-separated method names (default ssw). {listed}"


def build_parser() -> argparse.ArgumentParser:
    from sswjax.cli_confidence import add_confidence_options

    parser = _Parser(prog="sswjax", description="Segment-Side-Window stereo matching in JAX.")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--no-cache", action="store_true",
                        help="do not use the persistent compilation cache ($SSWJAX_CACHE_DIR, "
                             "default ~/.cache/sswjax/xla)")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    match = commands.add_parser("match", help="disparity map of a rectified pair")
    match.add_argument("left", type=Path, help="left (reference) image, or a folder of them")
    match.add_argument("right", type=Path, help="right image, or a folder (pairs: same names)")
    match.add_argument("--ndisp", type=int, required=True,
                       help="disparities searched: 0..N-1 (M..M+N-1 with --min-disp M)")
    match.add_argument("-o", "--output", type=Path, required=True,
                       help="output PFM file (folders: the folder of <name>.pfm, created)")
    match.add_argument("--max-memory", type=_gigabytes, metavar="GB",
                       help="refuse to run if the estimated peak memory exceeds GB (the memory "
                            "available is always a limit)")
    match.add_argument("--resume", action="store_true",
                       help="folders: keep the maps already in OUT_DIR, match the others")
    match.add_argument("--bucket", action="store_true",
                       help="folders: pad pairs to a few bucketed shapes (fewer compilations)")
    match.add_argument("--png", type=Path, help="also write a colour-mapped PNG")
    add_confidence_options(match)
    _add_geometry_options(match)
    _add_parameter_options(match, "the")
    match.set_defaults(run=cmd_match)

    demo = commands.add_parser("demo", help="run on scikit-image's Middlebury Motorcycle pair")
    demo.add_argument("-o", "--output", type=Path, default=Path("sswjax-demo"), help="output folder")
    _add_parameter_options(demo, "the")
    demo.set_defaults(run=cmd_demo)

    evaluate = commands.add_parser("evaluate", help="score methods on MiddEval3 scenes")
    evaluate.add_argument("--data", type=Path, help="data folder: MiddEval3, KITTI 2012/2015, "
                          "Middlebury 2001/2003/2005/2006 or ETH3D two-view, told by its files "
                          "(default: $SSWJAX_DATA, then ../shared/data/MiddEval3 beside the project)")
    evaluate.add_argument("--split", default="trainingQ", help="sub-folder of the data (trainingQ)")
    evaluate.add_argument("--ndisp", type=int,
                          help="disparities searched in every scene, 0..N-1 (default: calib.txt "
                               "for MiddEval3; elsewhere the smallest multiple of 8 >= max GT + 2)")
    evaluate.add_argument("--scenes", nargs="+", help="only these scenes")
    evaluate.add_argument("--methods", default="ssw", help=_methods_help())
    _add_parameter_options(evaluate, "the base")
    evaluate.add_argument("-o", "--output", type=Path,
                          help="folder for disparities (MiddEval3 layout), results.md, metrics.csv")
    evaluate.add_argument("--figure", action="store_true",
                          help="also write comparison.png (needs matplotlib)")
    evaluate.add_argument("--bucket", action="store_true",
                          help="pad pairs to a few bucketed shapes: fewer compilations (3 for "
                               "trainingQ), slightly different results at the bottom/right "
                               "borders; SSW methods then run one pair per JAX device per call, "
                               "over all devices (a scene's time: its call's time / its pairs)")
    evaluate.add_argument("--resume", action="store_true",
                          help="continue an interrupted run: keep the scenes already in -o "
                               "(disparity and time files) instead of recomputing them")
    evaluate.set_defaults(run=cmd_evaluate)

    download = commands.add_parser("download", help="download a stereo dataset")
    download.add_argument("dataset", choices=["middlebury", "eth3d", "kitti"],
                          help="middlebury (MiddEval3), eth3d (two-view training, needs py7zr); "
                               "kitti needs a registration: says where to get it")
    download.add_argument("--resolution", choices=["Q", "H", "F"], default="Q")
    download.add_argument("--dest", type=Path, default=Path("data"), help="folder to fill (data)")
    download.add_argument("--keep-archives", action="store_true", help="keep the archives")
    download.set_defaults(run=cmd_download)
    return parser


def _gigabytes(text: str) -> float:
    """``--max-memory`` value: a finite number of GB > 0."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"must be a number of GB > 0, got {text!r}")
    return value


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status (0, 2 for bad input, 130 on Ctrl-C)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = argv
    from sswjax.memory import MemoryEstimateError
    if not args.no_cache:
        from sswjax.compilation import enable_compilation_cache

        enable_compilation_cache()
    try:
        return args.run(args)
    except (ValueError, TypeError, OSError, MemoryEstimateError) as error:
        if args.debug:
            raise
        from sswjax.data.io import first_line

        message = first_line(error)
        print(f"sswjax: error: {message}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as interrupt:
        print(f"sswjax: {interrupt if isinstance(interrupt, Interrupted) else 'interrupted'}",
              file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
