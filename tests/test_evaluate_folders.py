"""``sswjax evaluate -o OUT`` and what is already there; the optional extras checked first.

A run without ``--resume`` into a folder that is not empty is refused: its old method folders
would stay beside the new ``results.md``. ``--overwrite`` removes what the earlier run's record
(``.sswjax-run.json``) lists, and its summaries, never other files. ``--figure`` without
matplotlib, or a peer without its package, is refused before any scene is matched.

The methods here are stand-ins without JAX (the folder handling is what is tested), registered
as peers the way ``tests/test_interrupts.py`` does; the subprocess tests register theirs in the
child process.
"""

from __future__ import annotations

import importlib.util
import json
import shlex
import subprocess
import sys
import time

import numpy as np
import pytest

from sswjax.cli.common import resume_command
from sswjax.evaluation import methods


@pytest.fixture()
def stand_ins(monkeypatch, middeval3):
    """Methods "one" and "two" without JAX (disparity 3 everywhere); their calls counted."""
    calls = []

    def method(name):
        def run(left, right, ndisp):
            calls.append(name)
            return np.full(left.shape[:2], middeval3.shift, np.float32)
        return methods.Peer(run, "a stand-in")

    monkeypatch.setitem(methods.PEERS, "one", method("one"))
    monkeypatch.setitem(methods.PEERS, "two", method("two"))
    return calls


def _files(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


NOT_EMPTY = ("{out} is not empty: add --resume to continue its run or --overwrite to replace "
             "what an earlier run wrote there")


def test_a_second_run_into_a_folder_is_refused_before_any_work(tmp_path, run_cli, middeval3,
                                                               stand_ins):
    root = middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "ev1"
    assert run_cli(["evaluate", "--data", root, "--methods", "one", "-o", out])[0] == 0
    before = {path: (out / path).read_bytes() for path in _files(out)}
    stand_ins.clear()
    code, stdout, err = run_cli(["evaluate", "--data", root, "--methods", "two", "-o", out])
    assert (code, stdout, stand_ins) == (2, "", [])
    assert err == f"sswjax: error: {NOT_EMPTY.format(out=out)}\n"
    assert {path: (out / path).read_bytes() for path in _files(out)} == before
    # a folder of the user's own, too
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    code, _, err = run_cli(["evaluate", "--data", root, "--methods", "two", "-o", mine])
    assert code == 2 and err == f"sswjax: error: {NOT_EMPTY.format(out=mine)}\n"
    assert _files(mine) == ["notes.txt"] and stand_ins == []
    # an empty folder is fine
    empty = tmp_path / "empty"
    empty.mkdir()
    assert run_cli(["evaluate", "--data", root, "--methods", "two", "-o", empty])[0] == 0


def test_overwrite_removes_only_what_the_earlier_run_wrote(tmp_path, run_cli, middeval3,
                                                          stand_ins):
    root = middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "ev1"
    assert run_cli(["evaluate", "--data", root, "--methods", "one", "-o", out])[0] == 0
    (out / "notes.txt").write_text("mine")
    (out / "one" / "Teddy" / "mine.txt").write_text("mine too")
    code, _, err = run_cli(["evaluate", "--data", root, "--methods", "two", "-o", out,
                            "--overwrite"])
    assert code == 0, err
    scenes = [name for name, _ in middeval3.scenes]
    assert _files(out) == sorted(
        [".sswjax-run.json", "metrics.csv", "notes.txt", "one/Teddy/mine.txt", "results.md"]
        + [f"two/{scene}/{name}TWO.{ext}" for scene in scenes
           for name, ext in (("disp0", "pfm"), ("time", "txt"))])
    assert "| one |" not in (out / "results.md").read_text()
    assert {row.split(",")[0] for row in (out / "metrics.csv").read_text().splitlines()[1:]} \
        == {"two"}
    record = json.loads((out / ".sswjax-run.json").read_text())
    names = record["maps"] if "maps" in record else record["finished"]  # either version's
    assert sorted(names) == [f"two/{scene}" for scene in scenes]


def test_overwrite_keeps_a_folder_no_evaluate_run_recorded(tmp_path, run_cli, middeval3,
                                                          stand_ins):
    root = middeval3(tmp_path / "MiddEval3")
    mine = tmp_path / "mine"
    (mine / "one" / "Teddy").mkdir(parents=True)
    (mine / "one" / "Teddy" / "disp0ONE.pfm").write_text("not from a recorded run")
    code, stdout, err = run_cli(["evaluate", "--data", root, "--methods", "one", "-o", mine,
                                 "--overwrite"])
    assert (code, stdout, stand_ins) == (2, "", [])
    assert err == (f"sswjax: error: {mine} holds no record of an earlier sswjax evaluate run "
                   "(.sswjax-run.json): --overwrite replaces only what such a run wrote; empty "
                   "the folder or choose another\n")
    assert _files(mine) == ["one/Teddy/disp0ONE.pfm"]


@pytest.mark.parametrize("extra, message", [
    (["--resume", "--overwrite"], "--resume continues the run in {out} and --overwrite "
                                  "replaces it: give one"),
    (["--figure"], "--figure writes comparison.png into the -o folder: give -o DIR"),
])
def test_option_conflicts_are_refused_first(tmp_path, run_cli, middeval3, stand_ins, extra,
                                            message):
    root = middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "out"
    argv = ["evaluate", "--data", root, "--methods", "one", *extra]
    code, stdout, err = run_cli(argv + (["-o", out] if "--resume" in extra else []))
    assert (code, stdout, stand_ins) == (2, "", [])
    assert err == f"sswjax: error: {message.format(out=out)}\n"
    assert not out.exists()


_CHILD = """
import sys
for name in {blocked!r}:
    sys.modules[name] = None  # as where it is not installed: its import fails
import numpy as np
from sswjax.evaluation import methods
calls = []
def one(left, right, ndisp):
    calls.append(1)
    return np.full(left.shape[:2], 3, np.float32)
methods.PEERS["one"] = methods.Peer(one, "a stand-in")
from sswjax.cli import main
code = main({argv!r})
print("calls", len(calls))
sys.exit(code)
"""


@pytest.mark.parametrize("blocked, extra, message", [
    (["matplotlib"], ["--figure"], "--figure needs matplotlib: pip install 'sswjax[bench]'"),
    (["cv2"], ["--methods", "one,sgbm"], "method sgbm needs OpenCV: pip install "
                                         "'sswjax[bench]'"),
])
def test_a_missing_extra_is_refused_before_any_scene(tmp_path, middeval3, blocked, extra,
                                                     message):
    root = middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "out"
    argv = ["evaluate", "--data", str(root), "--methods", "one", "-o", str(out), *extra]
    start = time.perf_counter()
    run = subprocess.run([sys.executable, "-c", _CHILD.format(blocked=blocked, argv=argv)],
                         capture_output=True, text=True, timeout=300)
    assert (run.returncode, run.stdout, run.stderr) == (2, "calls 0\n",
                                                        f"sswjax: error: {message}\n")
    assert not out.exists()
    assert time.perf_counter() - start < 60


def test_pandora_without_pandora_is_refused_before_any_scene(tmp_path, run_cli, middeval3,
                                                             stand_ins):
    if importlib.util.find_spec("pandora") is not None:
        pytest.skip("CNES Pandora is installed here")
    root = middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "out"
    code, stdout, err = run_cli(["evaluate", "--data", root, "--methods", "one,pandora", "-o",
                                 out])
    assert (code, stdout, stand_ins) == (2, "", [])
    assert err == "sswjax: error: method pandora needs CNES Pandora: pip install " \
                  "'sswjax[pandora]'\n"
    assert not out.exists()


def test_an_interrupted_overwrite_resumes_without_overwrite(tmp_path, run_cli, middeval3,
                                                            monkeypatch):
    root = middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "ev1"
    calls = []

    def interrupted(left, right, ndisp):
        calls.append(1)
        if len(calls) == 2 and getattr(interrupted, "armed", False):
            raise KeyboardInterrupt
        return np.full(left.shape[:2], middeval3.shift, np.float32)

    monkeypatch.setitem(methods.PEERS, "one", methods.Peer(interrupted, "a stand-in"))
    assert run_cli(["evaluate", "--data", root, "--methods", "one", "-o", out])[0] == 0
    interrupted.armed = True
    calls.clear()
    code, _, err = run_cli(["evaluate", "--data", root, "--methods", "one", "-o", out,
                            "--overwrite"])
    assert code == 130
    assert resume_command(["evaluate", "--data", str(root), "--methods", "one", "-o", str(out),
                           "--overwrite"]) == \
        f"sswjax evaluate --data {root} --methods one -o {out} --resume"
    resume = shlex.split(err.strip().splitlines()[-1].split("continue with: ", 1)[1])
    assert resume[0] == "sswjax" and resume[-1] == "--resume" and "--overwrite" not in resume
    interrupted.armed = False
    calls.clear()
    code, _, err = run_cli(resume[1:])  # the command the message suggests
    assert code == 0, err
    assert len(calls) == 2  # the scene kept by the interrupted run is not matched again
