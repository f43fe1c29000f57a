"""Error maps of the presets and the peers on chosen scenes of the three data sets: one figure.

Per scene (``--scenes SET:NAME``, SET one of trainingQ, KITTI2012, Middlebury2001), the left
image, the ground truth and, for each method (presets of :data:`sswjax.PRESETS` through
``sswjax.match`` at the pair's exact shape, peers of :data:`sswjax.evaluation.methods.PEERS` that are
installed), its disparity map above its bad 2.0 error map (red = wrong, grey = right, black =
no ground truth; KITTI's sparse ground truth drawn grown by ``--dilate`` pixels so the dots stay
visible), each titled with the scene's bad 2.0 over all pixels with ground truth. Writes the
PNG (``-o``) and beside it a Markdown table of the same figures (``.md``, bad 2.0 all and,
where the scene has occluded pixels, nonocc), and of bad 2.0 by region (:func:`regions`):
near depth edges, in the left band, and elsewhere in the lower third and the upper two thirds
of the image (the floor or road, and the rest).

``--candidates`` scores every scene of the named sets (or of all three) instead and prints a
table sorted by how much ``paper`` loses to the best peer, with the left image's mean and
standard deviation of intensity (dark, low-contrast scenes): how the default scenes were chosen.

    python benchmarks/error_maps.py [--data DIR] [--scenes trainingQ:Vintage KITTI2012:000104 ...]
        [--methods paper fast accurate sgbm pandora] [-o benchmarks/results/error_maps.png]
    python benchmarks/error_maps.py --candidates --scenes trainingQ: KITTI2012:
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.ndimage import binary_dilation

import sswjax
from sswjax._files import atomic_output
from sswjax.data.io import InputError
from sswjax.data.layouts import load_scenes
from sswjax.evaluation.figures import comparison_figure
from sswjax.evaluation.runner import SCORINGS, evaluate_scene
from sswjax.evaluation.methods import PEERS
from sswjax.stages.color import rgb_to_gray

from _report import SETS  # benchmarks/, on the path when run as a script: set -> folder, scoring
from front import _method_runners  # presets and installed peers as (left, right, ndisp) callables

# Chosen with --candidates: the trainingQ scenes where paper loses most to the best peer (Playtable,
# weak texture; PianoL, dark with the lighting changed between the views) and the lowest-contrast
# one it loses (Shelves); the KITTI pair it loses most; Middlebury 2001's slanted sawtooth.
DEFAULT_SCENES = ("trainingQ:Playtable", "trainingQ:PianoL", "trainingQ:Shelves",
                  "KITTI2012:000123", "Middlebury2001:sawtooth")
DEFAULT_METHODS = ("paper", "fast", "accurate", "sgbm", "pandora")
THRESHOLD = 2.0
KEY = f"bad{THRESHOLD}"


def parse_scenes(specs, parser) -> dict[str, list[str]]:
    """``["SET:NAME", "SET:"]`` -> {set: [names]} in order (an empty name: every scene)."""
    chosen: dict[str, list[str]] = {}
    for spec in specs:
        set_name, colon, name = spec.partition(":")
        if not colon or set_name not in SETS:
            parser.error(f"--scenes takes SET:NAME with SET one of {', '.join(SETS)}, got {spec!r}")
        chosen.setdefault(set_name, [])
        if name:
            chosen[set_name].append(name)
    return chosen


def load(data: Path, chosen: dict[str, list[str]], parser):
    """[(set name, scene)] in the order of ``chosen``; a missing folder or scene is a usage error."""
    out = []
    for set_name, names in chosen.items():
        try:
            scenes = load_scenes(data / SETS[set_name][0], scenes=names or None)
        except InputError as error:
            parser.error(str(error))
        out += [(set_name, s) for s in scenes]
    return out


def run(runners: dict, set_name: str, scene):
    """Each method's :class:`~sswjax.evaluation.SceneResult` on one scene, scored as its set."""
    scoring = SCORINGS[SETS[set_name][1]]
    results = {}
    for name, run_kind in runners.items():
        results[name] = evaluate_scene(run_kind["exact"], scene, scoring=scoring)
        print(f"  {set_name}/{scene.name} {name}: bad 2.0 {results[name].metrics['all'][KEY]:.2f}",
              file=sys.stderr, flush=True)
    return results


def candidates(runners: dict, loaded) -> str:
    """Markdown table of every loaded scene: each method's bad 2.0 (all), the left image's mean and
    standard deviation of intensity, sorted by ``paper`` minus the best peer (largest first)."""
    rows = []
    for set_name, scene in loaded:
        results = run(runners, set_name, scene)
        bad = {name: r.metrics["all"][KEY] for name, r in results.items()}
        peers = [bad[n] for n in bad if n in PEERS]
        gap = bad["paper"] - min(peers) if "paper" in bad and peers else float("nan")
        gray = np.asarray(rgb_to_gray(scene.left.astype(np.float32))) if scene.left.ndim == 3 \
            else scene.left.astype(np.float32)
        rows.append((gap, set_name, scene.name, float(gray.mean()), float(gray.std()), bad))
    rows.sort(key=lambda row: -row[0] if np.isfinite(row[0]) else np.inf)
    names = list(runners)
    lines = ["| set | scene | left mean | left std | " + " | ".join(names) + " | paper - best peer |",
             "|---" * (len(names) + 5) + "|"]
    for gap, set_name, scene, mean, std, bad in rows:
        lines.append(f"| {set_name} | {scene} | {mean:.0f} | {std:.0f} | "
                     + " | ".join(f"{bad[n]:.2f}" for n in names) + f" | {gap:+.2f} |")
    return "\n".join(lines)


EDGE_RADIUS = 3  # pixels within this distance of a ground-truth depth jump are "edges"


def regions(scene) -> dict[str, np.ndarray]:
    """Boolean (H, W) masks splitting the pixels with ground truth: within :data:`EDGE_RADIUS` of a
    jump of more than 1 px between neighbours in the ground truth ("edges"), else the first
    ``ndisp`` columns ("left band"), else the lower third and the upper two thirds ("lower",
    "upper": on the indoor and street scenes, the floor or road and the rest)."""
    known = np.isfinite(scene.ground_truth)
    gt = np.where(known, scene.ground_truth, np.nan)  # no jump to or from an unknown pixel
    jump = np.zeros_like(known)
    with np.errstate(invalid="ignore"):
        jump[:, 1:] |= np.abs(np.diff(gt, axis=1)) > 1
        jump[1:, :] |= np.abs(np.diff(gt, axis=0)) > 1
    size = 2 * EDGE_RADIUS + 1
    edges = binary_dilation(jump, structure=np.ones((size, size), bool)) & known
    band = np.zeros_like(known)
    band[:, :scene.ndisp] = True
    band &= known & ~edges
    lower = np.zeros_like(known)
    lower[2 * gt.shape[0] // 3:] = True
    rest = known & ~edges & ~band
    return {"edges": edges, "left band": band, "lower": rest & lower, "upper": rest & ~lower}


def region_table(loaded, results) -> str:
    """Markdown: per scene and method, bad 2.0 (%) in each of :func:`regions`, with their shares."""
    methods = list(results[0])
    lines = []
    for (set_name, scene), per_method in zip(loaded, results):
        masks = regions(scene)
        known = np.isfinite(scene.ground_truth)
        if not lines:
            lines = ["| scene | method | " + " | ".join(masks) + " |", "|---" * (len(masks) + 2) + "|"]
        shares = [f"{100 * m.sum() / known.sum():.1f} % of pixels" for m in masks.values()]
        lines.append(f"| {set_name}/{scene.name} | (share) | " + " | ".join(shares) + " |")
        for name in methods:
            error = np.abs(per_method[name].disparity - np.where(known, scene.ground_truth, 0))
            bad = known & ~(error <= THRESHOLD)
            cells = [f"{100 * (bad & m).sum() / max(m.sum(), 1):.1f}" for m in masks.values()]
            lines.append(f"| | {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def markdown(loaded, results, command: str) -> str:
    """Per scene and method, bad 2.0 over all pixels with ground truth (and nonocc where known)."""
    methods = list(results[0])
    lines = ["Bad 2.0 (%) of the panels of the error-map figure: all pixels with ground truth "
             "(nonocc in brackets where the scene has occluded pixels).", "",
             "| scene | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]
    for (set_name, scene), per_method in zip(loaded, results):
        cells = []
        for name in methods:
            metrics = per_method[name].metrics
            occluded = scene.mask is not None and bool((scene.mask == 128).any())
            nonocc = f" ({metrics['nonocc'][KEY]:.2f})" if occluded else ""
            cells.append(f"{metrics['all'][KEY]:.2f}{nonocc}")
        lines.append(f"| {set_name}/{scene.name} | " + " | ".join(cells) + " |")
    lines += ["", f"Bad 2.0 (%) by region: within {EDGE_RADIUS} px of a ground-truth depth jump "
              "(> 1 px), else the left band (x < ndisp), else the lower third and the upper two "
              "thirds of the image.", "", region_table(loaded, results)]
    return "\n".join(lines + ["", f"`{command}`"])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data", help="folder holding the three data sets")
    parser.add_argument("--scenes", nargs="+", default=list(DEFAULT_SCENES),
                        help="SET:NAME, one figure row each (SET: alone = every scene of SET)")
    parser.add_argument("--methods", nargs="+", default=list(DEFAULT_METHODS),
                        choices=[*sswjax.PRESETS, *PEERS])
    parser.add_argument("--dilate", type=int, default=2,
                        help="pixels by which sparse ground truth (KITTI) is grown in the maps")
    parser.add_argument("--thumb-inches", type=float, default=2.2, help="width of one panel")
    parser.add_argument("--candidates", action="store_true",
                        help="only score every scene of the sets and print the ranking")
    parser.add_argument("-o", "--output", type=Path,
                        default=Path("benchmarks/results/error_maps.png"))
    args = parser.parse_args(argv)
    if args.dilate < 0:
        parser.error(f"--dilate must be >= 0, got {args.dilate}")
    if not args.candidates and not args.output.parent.is_dir():
        parser.error(f"output folder {args.output.parent} does not exist")
    chosen = parse_scenes(args.scenes, parser)
    if not args.candidates and any(not names for names in chosen.values()):
        parser.error("the figure takes named scenes (SET:NAME); SET: alone is for --candidates")
    loaded = load(args.data, chosen, parser)
    runners = _method_runners(args.methods, 64)
    if args.candidates:
        print(candidates(runners, loaded))
        return 0
    results = [run(runners, set_name, scene) for set_name, scene in loaded]
    by_method = {name: [r[name] for r in results] for name in runners}
    comparison_figure(args.output, [s for _, s in loaded], by_method, threshold=THRESHOLD,
                      stacked=True, sparse_dilate=args.dilate, thumb_inches=args.thumb_inches,
                      labels=[f"{set_name} {s.name}" for set_name, s in loaded], dpi=90,
                      colors=256)
    command = "python benchmarks/error_maps.py " + " ".join(argv if argv is not None else sys.argv[1:])
    table = markdown(loaded, results, command.strip())
    print(table)
    with atomic_output(args.output.with_suffix(".md")) as tmp:
        tmp.write_text(table + "\n")
    print(f"wrote {args.output} and {args.output.with_suffix('.md')}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
