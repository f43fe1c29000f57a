"""Evaluation over MiddEval3-style folders: methods, tables, CSV, submission layout."""

from __future__ import annotations

import csv

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.api.batch import iter_match_scenes
from sswjax.cli import main
from sswjax.evaluation.runner import PAPER_TABLE1, SceneResult, summary, table1_markdown
from sswjax.data.io import read_pfm, write_pfm
from sswjax.evaluation.methods import make_method, submission_name
from sswjax.evaluation.methods import method_names
from sswjax.evaluation.metrics import weighted_average


def test_paper_table1_averages_match_the_paper():
    for method, (all_, nonocc) in {"ssw": (21.8, 13.3), "mf": (25.9, 16.2), "bf": (33.5, 25.5)}.items():
        rows = PAPER_TABLE1[method]
        assert weighted_average({s: v["all"] for s, v in rows.items()}) == pytest.approx(all_, abs=0.05)
        assert weighted_average({s: v["nonocc"] for s, v in rows.items()}) == pytest.approx(nonocc, abs=0.05)


def test_make_method_rejects_unknown_names():
    with pytest.raises(ValueError, match="unknown method 'nope'"):
        make_method("nope")
    assert {"ssw", "bf", "gf", "igf", "mf", "sgbm"} <= set(method_names())
    assert submission_name("ssw-noseg") == "SSWNOSEG"


def _result(scene, all_, nonocc):
    metrics = {region: {"bad2.0": v, "bad1.0": v + 1, "bad0.5": v + 2} for region, v in
               (("all", all_), ("nonocc", nonocc))}
    return SceneResult(scene, np.zeros((2, 2), np.float32), metrics, 0.5)


def test_table1_and_summary_use_the_official_weights():
    results = {"ssw": [_result("Teddy", 10.0, 4.0), _result("Vintage", 40.0, 10.0)]}
    assert summary(results["ssw"])["all"]["bad2.0"] == pytest.approx(20.0)  # weights 0.08 / 0.04
    table = table1_markdown(results)
    assert "| Teddy | 10.00 | 4.00 | 14.6 | 5.95 |" in table
    assert "**20.00** | **6.00**" in table


@pytest.fixture()
def tiny_middeval3(tmp_path):
    """Two 30x48 scenes with constant disparities 3 and 5, ground truth and masks."""
    rng = np.random.default_rng(0)
    for name, shift in (("Teddy", 3), ("Vintage", 5)):
        folder = tmp_path / "trainingQ" / name
        folder.mkdir(parents=True)
        right = (rng.random((30, 48, 3)) * 255).astype(np.uint8)
        iio.imwrite(folder / "im0.png", np.roll(right, shift, axis=1))
        iio.imwrite(folder / "im1.png", right)
        (folder / "calib.txt").write_text("cam0=[1 0 0; 0 1 0; 0 0 1]\nndisp=10\nvmin=0\nvmax=9\n")
        gt = np.full((30, 48), shift, np.float32)
        gt[:, :shift] = np.inf
        write_pfm(folder / "disp0GT.pfm", gt)
        mask = np.full((30, 48), 255, np.uint8)
        mask[:, :shift] = 0
        iio.imwrite(folder / "mask0nocc.png", mask)
    return tmp_path


def test_evaluate_writes_submission_layout_csv_and_tables(tiny_middeval3, tmp_path, capsys, tiny):
    out = tmp_path / "out"
    code = main(["evaluate", "--data", str(tiny_middeval3), "--methods", "ssw,box", "-o", str(out),
                 *tiny.args])
    assert code == 0
    for method, tag in (("ssw", "SSW"), ("box", "BOX")):
        for scene, shift in (("Teddy", 3), ("Vintage", 5)):
            disparity = read_pfm(out / method / scene / f"disp0{tag}.pfm")
            assert np.median(disparity[:, 12:]) == pytest.approx(shift, abs=0.05)
            assert float((out / method / scene / f"time{tag}.txt").read_text()) > 0
    with open(out / "metrics.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 2 * 2 * 2  # methods x scenes x regions
    assert {r["region"] for r in rows} == {"all", "nonocc"}
    assert all(float(r["bad2.0"]) < 10 for r in rows)
    text = (out / "results.md").read_text()
    assert "Table 1 layout" in text and "| ssw |" in text and "| box |" in text
    assert "wrote" in capsys.readouterr().out


def test_evaluate_missing_data_is_a_one_line_error(tmp_path, capsys):
    assert main(["evaluate", "--data", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("sswjax: error:") and err.count("\n") == 1


def test_evaluate_unknown_method(tiny_middeval3, capsys):
    assert main(["evaluate", "--data", str(tiny_middeval3), "--methods", "ssw,zzz"]) == 2
    assert "unknown method 'zzz'" in capsys.readouterr().err


def test_sgbm_peer_is_dense_and_recovers_a_shift():
    pytest.importorskip("cv2")
    from sswjax.evaluation.peers import sgbm_disparity

    rng = np.random.default_rng(2)
    right = (rng.random((40, 80, 3)) * 255).astype(np.uint8)
    disparity = sgbm_disparity(np.roll(right, 6, axis=1), right, 16)
    assert disparity.dtype == np.float32 and np.isfinite(disparity).all()
    assert disparity.min() >= 0 and disparity.max() <= 15
    assert np.median(disparity[:, 24:]) == pytest.approx(6, abs=0.25)


def test_evaluate_figure(tiny_middeval3, tmp_path, tiny):
    pytest.importorskip("matplotlib")
    out = tmp_path / "out"
    assert main(["evaluate", "--data", str(tiny_middeval3), "--methods", "box", "-o", str(out),
                 "--figure", *tiny.args]) == 0
    image = iio.imread(out / "comparison.png")
    assert image.ndim == 3 and image.shape[0] > 50


def test_tables_without_masks_show_all_only():
    from sswjax.evaluation.runner import markdown_table, summary_markdown

    rows = [SceneResult(s, np.zeros((2, 2), np.float32),
                        {"all": {"bad2.0": v, "bad1.0": v, "bad0.5": v}}, 0.1)
            for s, v in (("Teddy", 10.0), ("Vintage", 40.0))]
    table = markdown_table(rows)
    assert "nonocc" not in table and "**20.00**" in table
    assert "nonocc" not in summary_markdown({"ssw": rows})


def test_evaluate_bucket_runs_ssw_scenes_through_the_sharded_grouped_path(tiny_middeval3, tmp_path,
                                                                          monkeypatch, tiny):
    import sswjax
    import sswjax.evaluation.methods

    sswjax.save_params(tmp_path / "tiny.json", tiny.params)
    batches = []

    def spy(pairs, ndisps, *args, **kwargs):
        batches.append(list(ndisps))
        return iter_match_scenes(pairs, ndisps, *args, **kwargs)

    monkeypatch.setattr(sswjax.evaluation.methods, "iter_match_scenes", spy)
    out = tmp_path / "out"
    argv = ["evaluate", "--data", str(tiny_middeval3), "--methods", "ssw", "--params",
            str(tmp_path / "tiny.json"), "--bucket", "-o", str(out)]
    assert main(argv) == 0
    assert batches == [[10, 10]]  # both scenes in one run of the grouped path (maps equal to
    for scene, shift in (("Teddy", 3), ("Vintage", 5)):  # match's: tests/test_batching.py)
        disparity = read_pfm(out / "ssw" / scene / "disp0SSW.pfm")
        assert disparity.shape == (30, 48)
        assert np.median(disparity[:, 12:]) == pytest.approx(shift, abs=0.05)
        assert float((out / "ssw" / scene / "timeSSW.txt").read_text()) > 0
    (out / "ssw" / "Vintage" / "timeSSW.txt").unlink()
    assert main(argv + ["--resume"]) == 0
    assert batches == [[10, 10], [10]]  # only the scene without a saved result ran again


def test_summary_of_scenes_without_official_weights_is_the_plain_mean():
    """A user's own folder in MiddEval3's layout: its pair names have no benchmark weight."""
    rows = [SceneResult(name, np.zeros((2, 2), np.float32),
                        {"nonocc": {"bad2.0": value, "bad1.0": value, "bad0.5": value}}, 0.1)
            for name, value in (("kitchen", 10.0), ("garden", 20.0))]
    assert summary(rows)["nonocc"]["bad2.0"] == pytest.approx(15.0)
    official = [row._replace(scene=name) for row, name in zip(rows, ("Teddy", "Playroom"))]
    assert summary(official)["nonocc"]["bad2.0"] == pytest.approx(40 / 3)  # weights 0.08, 0.04
