"""Scoring of the layouts other than MiddEval3: bad 3.0, D1, means, and ``sswjax evaluate``."""

from __future__ import annotations

import csv

import imageio.v3 as iio
import numpy as np
import pytest

import sswjax.cli.evaluate
from sswjax.cli import main
from sswjax.data.layouts import find_data_root
from sswjax.data.io import read_pfm
from sswjax.evaluation.metrics import evaluate_disparity
from sswjax.evaluation.runner import (
    MIDDEVAL3_SCORING,
    SCORINGS,
    SceneResult,
    markdown_table,
    summary,
    summary_markdown,
)

SHAPE = (12, 40)
SHARED = find_data_root().parent  # ../shared/data beside the project, as MiddEval3


def test_d1_is_kitti_outliers_and_only_on_request():
    gt = np.array([[10, 10, 100, 100, 50, np.inf]], np.float32)
    d = np.array([[13, 13.5, 104.5, 106, np.inf, 0]], np.float32)  # errors 3, 3.5, 4.5, 6, invalid
    m = evaluate_disparity(d, gt, ndisp=128, thresholds=(3.0,), d1=True)["all"]
    # D1: > 3 px and > 5 % of the truth: 3.5 (> 0.5), 6 (> 5) and the invalid pixel; not 3, not 4.5
    assert m["D1"] == pytest.approx(60.0) and m["bad3.0"] == pytest.approx(80.0)
    assert list(m)[:2] == ["bad3.0", "D1"]
    mask = np.array([[255, 255, 255, 128, 255, 0]], np.uint8)
    both = evaluate_disparity(d, gt, mask=mask, ndisp=128, thresholds=(3.0,), d1=True)
    assert both["nonocc"]["D1"] == pytest.approx(50.0)
    assert "D1" not in evaluate_disparity(d, gt, ndisp=128)["all"]


def _rows(region_values, extra=()):
    return [SceneResult(scene, np.zeros((2, 2), np.float32),
                        {"all": {"bad2.0": v, "bad1.0": v, "bad0.5": v, "bad3.0": v / 2,
                                 **dict.fromkeys(extra, v / 4)}}, 0.1)
            for scene, v in region_values]


def test_means_for_other_layouts_weights_for_middeval3():
    rows = _rows((("Teddy", 10.0), ("Vintage", 40.0)), extra=("D1",))
    assert summary(rows)["all"] == pytest.approx({"bad2.0": 20.0, "bad1.0": 20.0, "bad0.5": 20.0})
    kitti = summary(rows, scoring=SCORINGS["kitti"])["all"]
    assert kitti == pytest.approx({"bad2.0": 25.0, "bad1.0": 25.0, "bad0.5": 25.0, "bad3.0": 12.5,
                                   "D1": 6.25})
    table = markdown_table(rows, scoring=SCORINGS["kitti"])
    assert "| **mean** |" in table and "bad3.0 all | D1 all |" in table and "**6.25**" in table
    assert "| **weighted average** |" in markdown_table(rows, scoring=MIDDEVAL3_SCORING)
    middlebury = summary_markdown({"sgbm": rows}, scoring=SCORINGS["mean"])
    assert "D1" not in middlebury and "bad3.0 all" in middlebury and "nonocc" not in middlebury


def _pair(seed, shift, *, colour):
    shape = SHAPE + ((3,) if colour else ())
    right = (np.random.default_rng(seed).random(shape) * 255).astype(np.uint8)
    return np.roll(right, shift, axis=1), right


def _gt_image(shift, scale, dtype):
    gt = np.full(SHAPE, shift * scale, dtype)
    gt[:, :shift] = 0
    return gt


@pytest.fixture()
def kitti(tmp_path):
    """KITTI 2012 layout, frames 000000 and 000001 with disparities 3 and 5."""
    base = tmp_path / "KITTI2012" / "training"
    for i, shift in enumerate((3, 5)):
        left, right = _pair(i, shift, colour=False)
        for folder, image in (("image_0", left), ("image_1", right),
                              ("disp_noc", _gt_image(shift, 256, np.uint16))):
            (base / folder).mkdir(parents=True, exist_ok=True)
            iio.imwrite(base / folder / f"{i:06d}_10.png", image)
    return tmp_path / "KITTI2012"


@pytest.fixture()
def middlebury2001(tmp_path):
    """Middlebury 2001 layout, scenes sawtooth and venus with disparities 3 and 5."""
    for i, (scene, shift) in enumerate((("sawtooth", 3), ("venus", 5))):
        folder = tmp_path / "Middlebury2001" / scene
        folder.mkdir(parents=True)
        left, right = _pair(i, shift, colour=True)
        iio.imwrite(folder / "im2.ppm", left, extension=".ppm")
        iio.imwrite(folder / "im6.ppm", right, extension=".ppm")
        iio.imwrite(folder / "disp2.pgm", _gt_image(shift, 8, np.uint8), extension=".pgm")
    return tmp_path / "Middlebury2001"


@pytest.fixture()
def oracle(monkeypatch):
    """Replace every method by one that returns the true shift of our fixtures (off by 0.6
    px, so bad 0.5 is 100 %) and records the ndisp it is called with."""
    calls = []

    def make_method(name, params=None, *, buckets=None, devices=None, estimate_range=False):
        def run(left, right, ndisp):
            calls.append((name, ndisp))
            a, b = np.asarray(left, np.int16), np.asarray(right, np.int16)
            shift = min(range(1, 8), key=lambda s: np.abs(a[:, 8:] - np.roll(b, s, axis=1)[:, 8:]).sum())
            return np.full(left.shape[:2], shift + 0.6, np.float32)

        return run

    monkeypatch.setattr(sswjax.cli.evaluate, "make_method", make_method)  # where evaluate calls it
    return calls


def _csv(path):
    with open(path) as handle:
        return list(csv.DictReader(handle))


def test_evaluate_kitti_folder_end_to_end_with_resume(kitti, tmp_path, oracle, capsys):
    out = tmp_path / "out"
    argv = ["evaluate", "--data", str(kitti), "--methods", "ssw,sgbm", "-o", str(out)]
    assert main(argv) == 0
    assert oracle == [("ssw", 8), ("ssw", 8), ("sgbm", 8), ("sgbm", 8)]  # 5 + 2 -> 8
    text = capsys.readouterr().out
    assert "Means over 2 KITTI2012 scenes (no weights; bad-pixel %, KITTI D1 %)" in text
    assert "Table 1" not in text and "| **mean** |" in text and "weighted" not in text
    assert "| method | bad2.0 nonocc | bad2.0 all |" in text and "D1 all | median s |" in text
    rows = _csv(out / "metrics.csv")
    assert len(rows) == 2 * 2 * 2 and {r["region"] for r in rows} == {"nonocc", "all"}
    assert all(float(r["bad0.5"]) == 100 and float(r["bad1.0"]) == 0 and float(r["D1"]) == 0
               for r in rows)
    assert read_pfm(out / "sgbm" / "000001" / "disp0SGBM.pfm")[0, 0] == pytest.approx(5.6)
    (out / "ssw" / "000001" / "timeSSW.txt").unlink()
    oracle.clear()
    assert main(argv + ["--resume"]) == 0
    assert oracle == [("ssw", 8)]  # only the scene without a saved result ran again
    assert "D1 all" in (out / "results.md").read_text()  # resumed scenes are scored as KITTI
    assert all(float(r["D1"]) == 0 for r in _csv(out / "metrics.csv"))
    # the run's record refuses a resume with other settings, naming them
    capsys.readouterr()
    assert main(argv + ["--resume", "--ndisp", "16"]) == 2
    assert "with other settings than it was made with: ndisp 16 (was null)" in \
        capsys.readouterr().err


def test_evaluate_middlebury2001_scenes_and_ndisp(middlebury2001, tmp_path, oracle, capsys):
    argv = ["evaluate", "--data", str(middlebury2001), "--methods", "sgbm", "--scenes", "venus",
            "--ndisp", "32", "-o", str(tmp_path / "out")]
    assert main(argv) == 0
    assert oracle == [("sgbm", 32)]
    text = capsys.readouterr().out
    assert "Means over 1 Middlebury2001 scenes (no weights; bad-pixel %)" in text
    assert "nonocc" not in text and "D1" not in text and "bad3.0 all" in text
    rows = _csv(tmp_path / "out" / "metrics.csv")
    assert [(r["scene"], r["region"]) for r in rows] == [("venus", "all")]
    assert "D1" not in rows[0] and float(rows[0]["bad3.0"]) == 0


def test_evaluate_unknown_layout_and_missing_scene(tmp_path, kitti, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["evaluate", "--data", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no known stereo data layout" in err and "KITTI2015" in err
    assert main(["evaluate", "--data", str(kitti), "--scenes", "000009"]) == 2
    assert "unknown scene(s) 000009" in capsys.readouterr().err


def test_evaluate_real_shared_data_with_sgbm(tmp_path, capsys):
    pytest.importorskip("cv2")
    if not (SHARED / "Middlebury2001").is_dir() or not (SHARED / "KITTI2012").is_dir():
        pytest.skip(f"KITTI2012 / Middlebury2001 not found in {SHARED}")
    assert main(["evaluate", "--data", str(SHARED / "Middlebury2001"), "--methods", "sgbm",
                 "--scenes", "sawtooth", "-o", str(tmp_path / "m")]) == 0
    (row,) = _csv(tmp_path / "m" / "metrics.csv")
    assert row["region"] == "all" and float(row["bad2.0"]) < 10  # measured 3.27
    assert main(["evaluate", "--data", str(SHARED / "KITTI2012"), "--methods", "sgbm",
                 "--scenes", "000100", "-o", str(tmp_path / "k")]) == 0
    rows = {r["region"]: r for r in _csv(tmp_path / "k" / "metrics.csv")}
    assert rows["nonocc"]["D1"] == rows["all"]["D1"]  # disp_noc: every known pixel is nonocc
    assert float(rows["all"]["D1"]) < 8 and float(rows["all"]["bad3.0"]) < 8  # measured 2.45, 2.46
    assert "Means over 1 KITTI2012 scenes" in capsys.readouterr().out


def test_evaluate_eth3d_folder(tmp_path, oracle, capsys, write_eth3d):
    root = write_eth3d(tmp_path, shifts=(3, 5), ndisps=(24, None))
    out = tmp_path / "out"
    assert main(["evaluate", "--data", str(root), "--methods", "ssw", "-o", str(out),
                 "--ndisp", "layout"]) == 0
    assert oracle == [("ssw", 24), ("ssw", 8)]  # calib.txt's ndisp, else the rule
    assert "Means over 2 ETH3D scenes (no weights; bad-pixel %)" in capsys.readouterr().out
    rows = _csv(out / "metrics.csv")
    assert {r["region"] for r in rows} == {"nonocc", "all"} and "D1" not in rows[0]
    assert all(float(r["bad1.0"]) == 0 and float(r["bad0.5"]) == 100 for r in rows)
    (root / "two_view_training_gt" / "electro_1l" / "mask0nocc.png").unlink()
    assert main(["evaluate", "--data", str(root)]) == 2
    err = capsys.readouterr().err
    truth = root / "two_view_training_gt" / "electro_1l"
    assert f"1 of 2 scenes cannot be scored: scene electro_1l: missing mask0nocc.png in {truth}" in err
    assert err.count("\n") == 1 and "--skip-bad scores the other 1" in err
