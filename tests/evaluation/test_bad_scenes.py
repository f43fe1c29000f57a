"""``sswjax evaluate`` on real benchmark files: ETH3D as it unpacks, and folders with bad scenes.

Every scene is checked before any is matched: one bad scene refuses the run with one line
naming every bad scene and why, ``--skip-bad`` scores the others and reports the skipped, and
no average ever takes a ``nan``.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

import sswjax.cli.evaluate
from sswjax.cli import main as cli_main
from sswjax.data.io import write_pfm
from sswjax.data.layouts import load_scenes, load_scenes_checked
from sswjax.evaluation.metrics import scene_mean, weighted_average
from sswjax.evaluation.runner import SCORINGS, SceneResult, evaluate_scene, summary

HEIGHT = 16

#: (scene, width, disparity): names of ETH3D training scenes, small sizes; the last one in RGB.
ETH3D_SCENES = (("delivery_area_1l", 40, 3), ("electro_1l", 48, 5), ("playground_1s", 56, 13))


def write_eth3d_archives(root: Path, scenes=ETH3D_SCENES, *, rgb=("playground_1s",)) -> Path:
    """``root/ETH3D`` as ETH3D's ``two_view_training.7z`` and ``two_view_training_gt.7z`` unpack.

    ``two_view_training/<scene>/`` holds ``im0.png``, ``im1.png`` (8-bit PNG, gray as ETH3D's
    rig cameras are, RGB for the scenes in ``rgb``), ``calib.txt`` in Middlebury's format with
    ETH3D's convention ``ndisp`` = the image width, and COLMAP's ``cameras.txt`` and
    ``images.txt``; ``two_view_training_gt/<scene>/`` holds ``disp0GT.pfm`` (float PFM, ``inf``
    = unknown: a sparse laser-scan ground truth, unknown left of the disparity) and
    ``mask0nocc.png`` (255 = non-occluded, 0 elsewhere).
    """
    base = root / "ETH3D"
    for seed, (name, width, shift) in enumerate(scenes):
        images, truth = base / "two_view_training" / name, base / "two_view_training_gt" / name
        images.mkdir(parents=True)
        truth.mkdir(parents=True)
        rng = np.random.default_rng(seed)
        right = (rng.random((HEIGHT, width)) * 255).astype(np.uint8)
        if name in rgb:
            right = np.repeat(right[:, :, None], 3, axis=2)
        iio.imwrite(images / "im0.png", np.roll(right, shift, axis=1))
        iio.imwrite(images / "im1.png", right)
        gt = np.full((HEIGHT, width), float(shift), np.float32)
        gt[rng.random((HEIGHT, width)) < 0.3] = np.inf  # sparse, as a laser scan
        gt[:, :shift] = np.inf
        write_pfm(truth / "disp0GT.pfm", gt)
        iio.imwrite(truth / "mask0nocc.png", np.where(np.isfinite(gt), 255, 0).astype(np.uint8))
        focal, cx, cy, baseline = 541.764 * width / 942, width / 2 - 0.5, HEIGHT / 2 - 0.5, 59.8839
        camera = f"[{focal:.3f} 0 {cx}; 0 {focal:.3f} {cy}; 0 0 1]"
        known = gt[np.isfinite(gt)]
        (images / "calib.txt").write_text(
            f"cam0={camera}\ncam1={camera}\ndoffs=0\nbaseline={baseline}\nwidth={width}\n"
            f"height={HEIGHT}\nndisp={width}\nisint=0\nvmin={known.min():g}\n"
            f"vmax={known.max():g}\ndyavg=0\ndymax=0\n")
        (images / "cameras.txt").write_text(
            "# Camera list with one line of data per camera:\n"
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: 1\n"
            f"0 PINHOLE {width} {HEIGHT} {focal:.3f} {focal:.3f} {cx} {cy}\n")
        (images / "images.txt").write_text(
            "# Image list with two lines of data per image:\n"
            "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
            "#   POINTS2D[] as (X, Y, POINT3D_ID)\n# Number of images: 2\n"
            "0 1 0 0 0 0 0 0 0 im0.png\n\n"
            f"1 1 0 0 0 {-baseline / 1000} 0 0 0 im1.png\n\n")
    return base


@pytest.fixture()
def oracle(monkeypatch):
    """Every method replaced by one returning the true shift + 0.6 (bad 0.5 is 100 %, bad 1.0
    0 %); records ``(method, scene width, ndisp)`` of each call."""
    calls = []

    def make_method(name, params=None, *, buckets=None, devices=None, estimate_range=False):
        def run(left, right, ndisp):
            calls.append((name, left.shape[1], ndisp))
            a, b = np.asarray(left, np.int16), np.asarray(right, np.int16)
            shift = min(range(1, 16), key=lambda s: np.abs(a[:, 16:] - np.roll(b, s, axis=1)[:, 16:]).sum())
            return np.full(left.shape[:2], shift + 0.6, np.float32)

        return run

    monkeypatch.setattr(sswjax.cli.evaluate, "make_method", make_method)
    return calls


def main(argv) -> int:
    """The command line in process, its arguments as strings."""
    return cli_main([str(a) for a in argv])


def _csv(path):
    with open(path) as handle:
        return list(csv.DictReader(handle))


# ----------------------------------------------------------------------------- ETH3D


def test_eth3d_as_it_unpacks_ndisp_is_the_width_and_every_scene_is_scored(tmp_path, capsys,
                                                                           tiny):
    root = write_eth3d_archives(tmp_path)
    scenes = load_scenes(root)
    assert [s.ndisp for s in scenes] == [8, 8, 16]  # the GT rule: 3, 5, 13 + 2 -> 8, 8, 16
    assert [s.left.ndim for s in scenes] == [2, 2, 3]
    out = tmp_path / "out"
    assert main(["evaluate", "--data", root, "--methods", "box", "-o", out, "--ndisp",
                 "layout", *tiny.args]) == 0  # a real match (conftest's tiny as the base)
    text = capsys.readouterr().out
    assert "Means over 3 ETH3D scenes (no weights; bad-pixel %)" in text
    assert "Disparity range searched (ETH3D): calib.txt's ndisp when below the image width" in text
    for name, _, _ in ETH3D_SCENES:
        assert f"| {name} |" in text
    rows = _csv(out / "metrics.csv")
    assert {(r["scene"], r["region"]) for r in rows} == {
        (name, region) for name, _, _ in ETH3D_SCENES for region in ("nonocc", "all")}
    assert all(math.isfinite(float(r[key])) for r in rows for key in ("bad2.0", "bad1.0", "bad3.0"))
    assert "nan" not in (out / "results.md").read_text()


def test_eth3d_ndisp_rule_with_the_oracle_and_an_explicit_ndisp(tmp_path, oracle, capsys):
    root = write_eth3d_archives(tmp_path)
    assert main(["evaluate", "--data", root, "--methods", "ssw", "--ndisp", "layout"]) == 0
    assert oracle == [("ssw", 40, 8), ("ssw", 48, 8), ("ssw", 56, 16)]
    mean = [line for line in capsys.readouterr().out.splitlines() if "**mean**" in line][0]
    assert "| **0.00** | **0.00** | **100.00** | **100.00** |" in mean  # bad 1.0 then bad 0.5
    oracle.clear()
    assert main(["evaluate", "--data", root, "--methods", "ssw", "--ndisp", "24"]) == 0
    assert [ndisp for _, _, ndisp in oracle] == [24, 24, 24]
    assert "Disparity range searched: 0..23 in every scene (--ndisp 24)." in capsys.readouterr().out
    oracle.clear()
    assert main(["evaluate", "--data", root, "--methods", "ssw", "--ndisp", "48"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and oracle == []
    assert ("2 of 3 scenes cannot be scored: scene delivery_area_1l: ndisp 48 is not below the "
            "image width 40; scene electro_1l: ndisp 48 is not below the image width 48 (in ") in err
    assert "--skip-bad scores the other 1)" in err


def test_eth3d_searches_the_estimate_by_default(tmp_path, monkeypatch, capsys):
    """ETH3D's files carry no range: without --ndisp the SSW methods are made to search the
    range estimated from each pair; --ndisp layout searches the ground-truth rule, N searches N."""
    root = write_eth3d_archives(tmp_path)
    made = []

    def make_method(name, params=None, *, buckets=None, devices=None, estimate_range=False):
        made.append(estimate_range)
        return lambda left, right, ndisp: np.full(left.shape[:2], 4.0, np.float32)

    monkeypatch.setattr(sswjax.cli.evaluate, "make_method", make_method)
    default = ("estimated from each pair (--ndisp auto, the default for ETH3D, whose files carry "
               "no search range; --ndisp layout searches the layout's); scored, and searched by "
               "the peers, over ETH3D's: calib.txt's ndisp when below the image width")
    for argv, estimated, line in (
            ([], True, default), (["--ndisp", "auto"], True, default),
            (["--ndisp", "layout"], False, "Disparity range searched (ETH3D): calib.txt's ndisp"),
            (["--ndisp", "24"], False, "Disparity range searched: 0..23 in every scene")):
        made.clear()
        assert main(["evaluate", "--data", root, *argv]) == 0
        assert made == [estimated] and line in capsys.readouterr().out
    assert main(["evaluate", "--data", root, "--bucket"]) == 2
    assert capsys.readouterr().err == (
        "sswjax: error: ETH3D pairs search a range estimated from each pair by default, which "
        "--bucket cannot batch: give --ndisp layout (the layout's range) or --ndisp N\n")
    assert main(["evaluate", "--data", root, "--ndisp", "layout", "--bucket"]) == 0
    assert made[-1] is False


def test_eth3d_scene_without_ground_truth_or_nonoccluded_pixel(tmp_path, oracle, capsys):
    root = write_eth3d_archives(tmp_path)
    (root / "two_view_training_gt" / "electro_1l" / "disp0GT.pfm").unlink()
    iio.imwrite(root / "two_view_training_gt" / "playground_1s" / "mask0nocc.png",
                np.zeros((HEIGHT, 56), np.uint8))
    assert main(["evaluate", "--data", root]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and oracle == []
    assert "2 of 3 scenes cannot be scored: scene electro_1l: ndisp=48 in " in err
    assert "is not below the image width 48 (no search range) and there is no ground truth" in err
    assert "; scene playground_1s: mask0nocc.png marks no pixel of known disparity non-occluded" in err


# ----------------------------------------------------------------------------- MiddEval3


def _break(root: Path) -> None:
    """Teddy's im1.png truncated; Vintage's ground truth without one known pixel."""
    image = root / "trainingQ" / "Teddy" / "im1.png"
    image.write_bytes(image.read_bytes()[:100])
    write_pfm(root / "trainingQ" / "Vintage" / "disp0GT.pfm", np.full((24, 48), np.inf, np.float32))


def test_bad_scenes_refuse_the_run_naming_every_one(tmp_path, middeval3, oracle, capsys):
    root = middeval3(tmp_path / "MiddEval3")
    _break(root)
    assert main(["evaluate", "--data", root, "-o", tmp_path / "out"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and oracle == [] and not (tmp_path / "out").exists()
    assert err == (f"sswjax: error: 2 of 3 scenes cannot be scored: scene Teddy: cannot read "
                   f"image {root}/trainingQ/Teddy/im1.png: the file is truncated; scene Vintage: "
                   f"disp0GT.pfm has no known disparity (in {root}; --skip-bad scores the other "
                   "1)\n")


def test_skip_bad_scores_the_others_and_reports_the_skipped(tmp_path, middeval3, oracle, capsys):
    root = middeval3(tmp_path / "MiddEval3")
    _break(root)
    out = tmp_path / "out"
    assert main(["evaluate", "--data", root, "--skip-bad", "-o", out]) == 0
    assert oracle == [("ssw", 40, 8)]  # Adirondack only
    captured = capsys.readouterr()
    assert (f"sswjax: skipped 2 of 3 scenes, which cannot be scored: scene Teddy: cannot read "
            f"image {root}/trainingQ/Teddy/im1.png: the file is truncated; scene Vintage: "
            f"disp0GT.pfm has no known disparity (in {root})\n") in captured.err
    text = (out / "results.md").read_text()
    assert ("## Weighted averages (MiddEval3 weights renormalised over the 1 scored scene, 2 "
            "skipped, bad-pixel % at Q resolution)") in text
    assert "## Skipped scenes (2, not in any average)" in text
    assert f"- Teddy: cannot read image {root}/trainingQ/Teddy/im1.png: the file is truncated" \
        in text
    assert "- Vintage: disp0GT.pfm has no known disparity" in text
    assert "| Adirondack |" in text and "| Teddy |" not in text and "nan" not in text
    assert "| **weighted average** | **0.00** | **0.00** |" in text  # bad 2.0: Adirondack's own
    assert {r["scene"] for r in _csv(out / "metrics.csv")} == {"Adirondack"}


def test_missing_ground_truth_and_every_scene_bad(tmp_path, middeval3, oracle, capsys):
    root = middeval3(tmp_path / "MiddEval3")
    (root / "trainingQ" / "Teddy" / "disp0GT.pfm").unlink()
    assert main(["evaluate", "--data", root]) == 2
    teddy = root / "trainingQ" / "Teddy"
    assert (f"1 of 3 scenes cannot be scored: scene Teddy: missing disp0GT.pfm in {teddy} (in "
            f"{root}; --skip-bad scores the other 2)") in capsys.readouterr().err
    assert main(["evaluate", "--data", root, "--skip-bad", "--scenes", "Teddy", "Vintage"]) == 0
    assert oracle == [("ssw", 48, 8)]
    assert (f"sswjax: skipped 1 of 2 scenes, which cannot be scored: scene Teddy: missing "
            f"disp0GT.pfm in {teddy} (in {root})\n") in capsys.readouterr().err
    assert main(["evaluate", "--data", root, "--skip-bad", "--scenes", "Teddy"]) == 2
    assert capsys.readouterr().err == (f"sswjax: error: the one scene in {root} cannot be "
                                       f"scored: scene Teddy: missing disp0GT.pfm in {teddy}\n")
    for name in ("Adirondack", "Vintage"):
        (root / "trainingQ" / name / "calib.txt").write_text("cam0=[1 0 0; 0 1 0; 0 0 1]\n")
    assert main(["evaluate", "--data", root, "--skip-bad"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("sswjax: error: none of the 3 scenes in ") and err.count("\n") == 1
    assert f"scene Adirondack: calibration file {root}/trainingQ/Adirondack/calib.txt needs " \
        "ndisp=<positive integer>, got None" in err
    assert f"; scene Teddy: missing disp0GT.pfm in {teddy}; scene Vintage: calibration file" in err


def test_load_scenes_checked_collects_and_load_scenes_still_stops_at_the_first(tmp_path,
                                                                                middeval3):
    root = middeval3(tmp_path / "MiddEval3")
    _break(root)
    scenes, problems = load_scenes_checked(root)
    assert [s.name for s in scenes] == ["Adirondack"]
    assert [name for name, _ in problems] == ["Teddy", "Vintage"]
    assert problems[0][1].startswith("cannot read image ") and problems[0][1].endswith(
        "Teddy/im1.png: the file is truncated")
    assert problems[1] == ("Vintage", "disp0GT.pfm has no known disparity")
    loaded, problems = load_scenes_checked(root, scorable=False)  # Vintage loads: ndisp in calib
    assert [s.name for s in loaded] == ["Adirondack", "Vintage"] and len(problems) == 1
    with pytest.raises(ValueError, match=r"cannot read image .*Teddy/im1.png: the file is truncated"):
        load_scenes(root)


# ----------------------------------------------------------------------------- no nan averaged


def _rows(values):
    return [SceneResult(scene, np.zeros((2, 2), np.float32),
                        {"all": {"bad2.0": v, "bad1.0": v, "bad0.5": v, "bad3.0": v}}, 0.1)
            for scene, v in values]


def test_no_average_takes_a_nan():
    with pytest.raises(ValueError, match="scene Vintage has no score to average"):
        weighted_average({"Teddy": 10.0, "Vintage": float("nan")})
    with pytest.raises(ValueError, match="scene b has no score to average"):
        scene_mean({"a": 1.0, "b": float("nan")})
    rows = _rows((("Teddy", 10.0), ("Vintage", float("nan"))))
    with pytest.raises(ValueError, match="scene Vintage"):
        summary(rows)
    with pytest.raises(ValueError, match="scene Vintage"):
        summary(rows, scoring=SCORINGS["mean"])
    # leaving a scene out renormalises the weights over the others
    assert weighted_average({"Teddy": 10.0}) == 10.0
    assert summary(rows[:1])["all"]["bad2.0"] == 10.0


def test_evaluate_scene_refuses_a_ground_truth_without_known_pixel(tmp_path, middeval3):
    root = middeval3(tmp_path / "MiddEval3")
    scene = load_scenes(root, scenes=["Teddy"])[0]
    unknown = scene._replace(ground_truth=np.full_like(scene.ground_truth, np.inf))
    with pytest.raises(ValueError, match="scene Teddy has no known ground-truth disparity"):
        evaluate_scene(lambda left, right, ndisp: np.zeros(left.shape[:2], np.float32), unknown)


def test_eth3d_with_an_estimated_range(tmp_path, capsys, tiny):
    """ETH3D's calib.txt gives no range (its ndisp is the width): by default the SSW methods
    search what the pair's coarse pass estimates (--ndisp auto), a real match (of conftest's
    ``tiny`` configuration: the estimate's coarse pass is the same for all)."""
    images = tmp_path / "ETH3D" / "two_view_training" / "terrace_1s"
    truth = tmp_path / "ETH3D" / "two_view_training_gt" / "terrace_1s"
    images.mkdir(parents=True)
    truth.mkdir(parents=True)
    rng = np.random.default_rng(3)
    right = (rng.random((96, 192)) * 255).astype(np.uint8)
    right = np.repeat(np.repeat(right[::2, ::2], 2, axis=0), 2, axis=1)  # 2-pixel texture
    iio.imwrite(images / "im0.png", np.roll(right, 21, axis=1))
    iio.imwrite(images / "im1.png", right)
    (images / "calib.txt").write_text("cam0=[500 0 96; 0 500 48; 0 0 1]\nbaseline=60\n"
                                      "width=192\nheight=96\nndisp=192\n")
    gt = np.full((96, 192), 21.0, np.float32)
    gt[:, :21] = np.inf
    write_pfm(truth / "disp0GT.pfm", gt)
    iio.imwrite(truth / "mask0nocc.png", np.where(np.isfinite(gt), 255, 0).astype(np.uint8))
    root = tmp_path / "ETH3D"
    assert main(["--no-cache", "evaluate", "--data", root, "--methods", "ssw", *tiny.args]) == 0
    out = capsys.readouterr().out
    assert "estimated from each pair (--ndisp auto, the default for ETH3D" in out
    row = [line for line in out.splitlines() if "| terrace_1s |" in line][0]
    assert float(row.split("|")[2]) < 5.0  # bad 2.0 nonocc
    assert main(["evaluate", "--data", root, "--ndisp", "auto", "--bucket"]) == 2
    assert "--ndisp auto gives each pair its own range" in capsys.readouterr().err
