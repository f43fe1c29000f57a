"""Regenerate the README's accuracy section: the paper's Table 1 with our methods, and a figure.

Runs ``sswjax evaluate`` over MiddEval3 trainingQ with SSW, the paper's comparison aggregators
(BF, GF, iGF, MF), a plain box, OpenCV SGBM and the SSW ablations, then draws a README-sized
figure (a few scenes, the main methods) from the disparities it wrote.

    python benchmarks/table1.py [--data DIR] [--params P.json] [-o benchmarks/results/table1]

Needs the ``[bench]`` extra (OpenCV, matplotlib). About 20 minutes on a 2-core machine.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sswjax.cli import main as sswjax_main
from sswjax.data.io import read_pfm
from sswjax.data.layouts import find_data_root, load_scenes
from sswjax.evaluation.methods import submission_name
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.evaluation.runner import THRESHOLDS, SceneResult
from sswjax.config import kinds
from sswjax.evaluation.methods import VARIANTS

METHODS = (*kinds("aggregation"), "sgbm", *VARIANTS)  # every aggregator and ablation
FIGURE_METHODS = ("ssw", "gf", "mf", "sgbm")
FIGURE_SCENES = ("Teddy", "ArtL", "Playtable", "Vintage")


def figure_from_outputs(out: Path, data: Path | None) -> Path:
    """Draw the README figure from the PFMs that ``sswjax evaluate`` wrote into ``out``."""
    from sswjax.evaluation.figures import comparison_figure

    scenes = load_scenes(find_data_root(data=data), scenes=list(FIGURE_SCENES))
    results = {}
    for method in FIGURE_METHODS:
        rows = []
        for scene in scenes:
            disparity = read_pfm(out / method / scene.name / f"disp0{submission_name(method)}.pfm")
            metrics = evaluate_disparity(disparity, scene.ground_truth, mask=scene.mask,
                                         ndisp=scene.ndisp, thresholds=THRESHOLDS)
            rows.append(SceneResult(scene.name, disparity, metrics, 0.0))
        results[method] = rows
    path = out / "comparison_readme.png"
    comparison_figure(path, scenes, results, thumb_inches=1.5)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path)
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results/table1"))
    parser.add_argument("--params", type=Path, help="base parameters of the SSW variants")
    parser.add_argument("--skip-evaluate", action="store_true",
                        help="only redraw the figure from an earlier run's outputs")
    args = parser.parse_args()
    if not args.skip_evaluate:
        argv = ["evaluate", "--methods", ",".join(METHODS), "-o", str(args.output)]
        if args.data is not None:
            argv += ["--data", str(args.data)]
        # The paper's Table 1 compares aggregators within the paper's method: its parameters,
        # not the library's default preset, unless a file is given.
        argv += ["--params", str(args.params)] if args.params is not None else ["--preset", "paper"]
        code = sswjax_main(argv)
        if code != 0:
            raise SystemExit(code)
    print(f"wrote {figure_from_outputs(args.output, args.data)}")


if __name__ == "__main__":
    main()
