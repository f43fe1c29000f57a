"""``sswjax search`` end to end on a small user folder: the held-out report, the written
parameters (loadable by ``--params``), ``--resume`` after Ctrl-C, and the refusals."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
import skimage.data

import sswjax
from sswjax.data.io import write_pfm

# The vertical alignment is off: the search treats it as any other stage, and on these windows
# its first pass would only add compiling (tests/test_alignment.py tests it).
QUICK = ["--set", "alignment=none", "--steps", "2", "--batch", "2", "--crop-height", "48",
         "--crop-context", "64", "--val-every", "1", "--val-images", "1", "--restarts", "1",
         "--patience", "5", "--no-grid"]
WINDOWS = {"top": np.s_[20:120, 60:260], "bottom": np.s_[140:240, 40:240]}  # 100 x 200 windows
# of the half-size Motorcycle


@pytest.fixture(scope="module")
def user_folder(tmp_path_factory):
    """A user's folder in MiddEval3's layout: two pairs cut from skimage's Motorcycle at half
    size, with their ground truth (``inf`` = unknown), a mask of every pixel and ``calib.txt``."""
    left, right, disparity = skimage.data.stereo_motorcycle()
    left, right = left[::2, ::2], right[::2, ::2]
    truth = np.where(np.isfinite(disparity), disparity / 2, np.inf)[::2, ::2].astype(np.float32)
    root = tmp_path_factory.mktemp("user-data")
    for name, window in WINDOWS.items():
        folder = root / name
        folder.mkdir()
        iio.imwrite(folder / "im0.png", left[window])
        iio.imwrite(folder / "im1.png", right[window])
        write_pfm(folder / "disp0GT.pfm", truth[window])
        iio.imwrite(folder / "mask0nocc.png", np.full(truth[window].shape, 255, np.uint8))
        (folder / "calib.txt").write_text("ndisp=32\n")
    return root


@pytest.fixture(scope="module")
def searched(user_folder, tmp_path_factory):
    """One finished run: ``(exit code, output path)``. Its graphs go to this process's
    compilation cache (conftest's folder of this test process), which the interrupted run of
    :func:`test_interrupted_search_resumes_to_the_same_parameters` reads."""
    from sswjax.cli import main

    out = tmp_path_factory.mktemp("search") / "params.json"
    code = main(["search", "--data", str(user_folder), "-o", str(out), *QUICK])
    return code, out


def test_search_writes_parameters_with_a_held_out_report(searched, user_folder):
    code, out = searched
    assert code == 0
    data = json.loads(out.read_text())
    folds = data["provenance"]["held_out"]
    assert [f["held_out"] for f in folds] == sorted(WINDOWS)  # leave one scene out
    for fold in folds:
        for scores in (fold["base"], fold["searched"]):
            assert 0 <= scores[user_folder.name]["nonocc"]["bad2.0"] <= 100
    report = json.loads((out.parent / "params.json.search" / "report.json").read_text())
    assert report["searched"] == ["cost.tad_truncation", "cost.gradient_truncation",
                                  "optimizer.p1", "optimizer.p2", "optimizer.sigma"]
    validation = data["provenance"]["validation_bad2"]
    assert validation["searched"] <= validation["start"]  # the best validated point is kept


def test_searched_parameters_run_with_params(searched, user_folder, tmp_path, run_cli):
    _, out = searched
    params = sswjax.load_params(out)
    assert params.optimizer is not None
    disparity = tmp_path / "d.pfm"
    code, _, err = run_cli(["match", user_folder / "top" / "im0.png",
                            user_folder / "top" / "im1.png", "--ndisp", "32", "--params", out,
                            "-o", disparity])
    assert code == 0, err
    assert disparity.exists()


def test_a_second_run_refuses_the_run_folder_and_resume_reuses_it(searched, user_folder,
                                                                 run_cli):
    _, out = searched
    before = out.read_bytes()
    code, _, err = run_cli(["--no-cache", "search", "--data", user_folder, "-o", out, *QUICK])
    assert code == 2 and "holds a search run: pass --resume" in err
    stamps = {p: p.stat().st_mtime_ns for p in out.with_name("params.json.search").rglob("*.pkl")}
    code, _, err = run_cli(["--no-cache", "search", "--data", user_folder, "-o", out, *QUICK,
                            "--resume"])
    assert code == 0, err
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps  # no start was run again
    after = {k: v for k, v in json.loads(out.read_bytes()).items() if k != "provenance"}
    assert after == {k: v for k, v in json.loads(before).items() if k != "provenance"}
    code, _, err = run_cli(["--no-cache", "search", "--data", user_folder, "-o", out,
                            *QUICK[:-3], "--patience", "4", "--no-grid", "--resume"])
    assert code == 2 and "was run with other settings" in err


@pytest.mark.slow  # two fresh processes, one stopped by a real signal
def test_interrupted_search_resumes_to_the_same_parameters(searched, user_folder, tmp_path):
    _, reference = searched
    out = tmp_path / "params.json"
    command = [sys.executable, "-m", "sswjax.cli", "search", "--data", str(user_folder), "-o",
               str(out), *QUICK]
    # Both runs load the graphs that ``searched`` compiled into this process's cache
    # (SSWJAX_CACHE_DIR, inherited): what they test is the stop and the resume, not compiling.
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first = out.with_name("params.json.search") / "fold-bottom" / "start-0" / "log.json"  # done
    deadline = time.monotonic() + 300
    while not first.exists() and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130, err.decode()
    assert "--resume" in err.decode().splitlines()[-1]
    assert not out.exists()
    done = subprocess.run(command + ["--resume"], env=env, capture_output=True, timeout=600)
    assert done.returncode == 0, done.stderr.decode()
    searched_values = {k: v for k, v in json.loads(out.read_text()).items() if k != "provenance"}
    expected = {k: v for k, v in json.loads(reference.read_text()).items() if k != "provenance"}
    assert searched_values == expected


def test_too_little_ground_truth_is_refused(tmp_path, run_cli):
    folder = tmp_path / "tiny" / "pair"
    folder.mkdir(parents=True)
    image = (np.random.default_rng(0).random((40, 60, 3)) * 255).astype(np.uint8)
    iio.imwrite(folder / "im0.png", image)
    iio.imwrite(folder / "im1.png", image)
    write_pfm(folder / "disp0GT.pfm", np.zeros((40, 60), np.float32))
    iio.imwrite(folder / "mask0nocc.png", np.full((40, 60), 255, np.uint8))
    (folder / "calib.txt").write_text("ndisp=16\n")
    out = tmp_path / "p.json"
    code, _, err = run_cli(["search", "--data", tmp_path / "tiny", "-o", out])
    assert code == 2
    assert err.startswith("sswjax: error: too little ground truth to search: 1 scene(s) with "
                          "2,400 known pixels") and len(err.strip().splitlines()) == 1
    assert not out.exists() and not out.with_name("p.json.search").exists()


def test_a_preset_with_a_coarse_pass_is_refused(user_folder, tmp_path, run_cli):
    code, _, err = run_cli(["search", "--data", user_folder, "-o", tmp_path / "p.json",
                            "--preset", "fast"])
    assert code == 2 and "coarse pass" in err


def test_a_band_is_refused(user_folder, tmp_path, run_cli):
    code, _, err = run_cli(["search", "--data", user_folder, "-o", tmp_path / "p.json",
                            "--preset", "accurate", "--set", "band=around-map"])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "(band is set)" in err
    assert not (tmp_path / "p.json").exists()


def test_the_grid_runs_after_the_continuous_search_and_is_kept(user_folder, tmp_path, run_cli):
    out = tmp_path / "paper.json"
    # without superpixels (their options have no grid step: the same grid, cheaper trials)
    args = ["--no-cache", "search", "--data", user_folder, "-o", out, "--preset", "paper",
            "--set", "segments=none", "--held-out", "none", *QUICK[:-1]]
    code, _, err = run_cli(args)
    assert code == 0, err
    grid = json.loads((tmp_path / "paper.json.search" / "final" / "grid.json").read_text())
    tried = {path for path, _, _ in grid["trials"]}
    # the paper's options without a gradient; aggregated_gap acts only with an optimiser
    assert tried == {"checks.tolerance", "checks.uniqueness_gap"}
    report = json.loads((tmp_path / "paper.json.search" / "report.json").read_text())
    assert report["folds"] == [] and report["final"]["grid"] == grid["trials"]
    assert "checks.tolerance" in report["final"]["params"]


def test_the_shipped_searched_parameters_load_and_match(user_folder, tmp_path, run_cli):
    """``tuning/params/searched.json``: the search on the three shared sets."""
    path = Path(__file__).resolve().parents[1] / "tuning" / "params" / "searched.json"
    params = sswjax.load_params(path)
    assert params.optimizer.p2 != sswjax.preset("accurate").optimizer.p2  # a searched value
    assert json.loads(path.read_text())["provenance"]["held_out"]  # with its fold table
    code, _, err = run_cli(["match", user_folder / "top" / "im0.png", user_folder / "top" /
                            "im1.png", "--ndisp", "32", "--params", path, "-o", tmp_path / "d.pfm"])
    assert code == 0, err
    assert (tmp_path / "d.pfm").exists()


@pytest.mark.parametrize("case", ["missing-data", "output-is-params", "resume-without-run"])
def test_bad_requests_are_one_line_and_write_nothing(case, user_folder, tmp_path, run_cli):
    out = tmp_path / "p.json"
    if case == "missing-data":
        argv, message = ["--data", tmp_path / "nope", "-o", out], "--data PATH: no such folder"
    elif case == "output-is-params":
        code, _, _ = run_cli(["params", "--preset", "accurate", "-o", out])
        assert code == 0
        argv, message = (["--data", user_folder, "-o", out, "--params", out],
                         "-o PATH is the --params file: it would be overwritten")
    else:
        argv, message = ["--data", user_folder, "-o", out, "--resume"], \
            "--resume: PATH holds no search run"
    before = out.read_bytes() if out.exists() else None
    code, _, err = run_cli(["search", *argv])
    assert code == 2 and len(err.strip().splitlines()) == 1
    prefix, suffix = message.split("PATH")
    assert err.startswith(f"sswjax: error: {prefix}") and err.strip().endswith(suffix.strip())
    assert (out.read_bytes() if out.exists() else None) == before
    assert not out.with_name("p.json.search").exists()
