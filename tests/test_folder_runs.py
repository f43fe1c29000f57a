"""Folder runs (``sswjax match LEFT_DIR RIGHT_DIR -o OUT_DIR``) as a careful user meets them
(issue 72): the output folder is locked for the run, the record says which settings wrote each
map, a bad pair is named while the good ones are written, and ``--workers`` beyond the cores
is capped with a quiet shutdown.

Every pair is 24 x 40 with ndisp 8 and conftest's tiny configuration: one graph.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.data.io import read_pfm

HEIGHT, WIDTH, NDISP, SHIFT = 24, 40, 8, 3

# Takes the lock of the folder argv[1] as a run does, says so, and holds it until stdin closes
# (or the process is killed).
HOLD_LOCK = """
import sys
from sswjax.cli.record import lock_folder
with lock_folder(sys.argv[1]):
    print("held", flush=True)
    sys.stdin.read()
"""

# The command line (argv[2:]) in a process that may use only the cores argv[1] (None: all), so
# that the run sees at most two cores whatever this machine has.
ON_CORES = """
import ast, os, sys
cores = ast.literal_eval(sys.argv[1])
if cores is not None:
    os.sched_setaffinity(0, cores)
from sswjax.cli import main
sys.exit(main(sys.argv[2:]))
"""


def _folders(root, texture, names, *, seed=0):
    left, right = root / "L", root / "R"
    left.mkdir(), right.mkdir()
    for i, name in enumerate(names):
        image = texture(seed + i, (HEIGHT, WIDTH, 3))
        iio.imwrite(left / name, np.roll(image, SHIFT, axis=1))
        iio.imwrite(right / name, image)
    return left, right


def _messages(stderr: str) -> list[str]:
    """The lines of stderr that are sswjax's (not the progress bar's)."""
    return [line for line in stderr.replace("\r", "\n").splitlines() if line.startswith("sswjax:")]


def test_a_folder_in_use_is_refused_and_a_dead_runs_lock_is_taken_over(tmp_path, texture,
                                                                       run_cli, tiny):
    left, right = _folders(tmp_path, texture, ["a.png", "b.png"])
    out = tmp_path / "out"
    out.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LOCK, str(out)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        argv = ["match", left, right, "--ndisp", NDISP, "-o", out, *tiny.args]
        for folder in (left, right):  # a bad pair: not named, the run is refused first
            (folder / "c.png").write_text("not an image\n")
        code, stdout, stderr = run_cli(argv)
        for folder in (left, right):
            (folder / "c.png").unlink()
        assert (code, stdout) == (2, ""), stderr
        assert stderr.count("\n") == 1, stderr
        assert stderr.startswith(f"sswjax: error: {out} is in use by another sswjax run "
                                 f"(pid {holder.pid}, started ")
        assert stderr.endswith("): wait for it or choose another -o\n")
        assert os.listdir(out) == [".sswjax-run.lock"]           # nothing written
    finally:
        holder.kill()                                             # no chance to clean up
        holder.wait(timeout=60)
    code, stdout, stderr = run_cli(argv)
    assert code == 0, stderr
    note = _messages(stderr)[0]
    assert note.startswith(f"sswjax: note: {out} was locked by a run that is no longer running "
                           f"(pid {holder.pid}, started ")
    assert note.endswith("): taking the lock over")
    assert sorted(os.listdir(out)) == [".sswjax-run.json", "a.pfm", "b.pfm"]  # lock released


def test_resume_keeps_only_the_maps_written_with_its_settings(tmp_path, texture, run_cli, tiny):
    left, right = _folders(tmp_path, texture, ["a.png", "b.png"])
    out = tmp_path / "out"
    argv = ["match", left, right, "--ndisp", NDISP, "-o", out, *tiny.args]
    assert run_cli(argv)[0] == 0
    path = out / ".sswjax-run.json"
    record = json.loads(path.read_text())
    digest = record["digest"]
    assert record["maps"] == {"a.pfm": digest, "b.pfm": digest}
    # a.pfm written by another run's settings (two runs into one folder, before the lock)
    record["maps"]["a.pfm"] = "0123456789abcdef"
    path.write_text(json.dumps(record))
    before = {name: (out / name).stat().st_mtime_ns for name in ("a.pfm", "b.pfm")}
    code, stdout, stderr = run_cli([*argv, "--resume"])
    assert code == 0, stderr
    assert "wrote 1 disparity maps" in stdout and "1 kept from before" in stdout
    assert (out / "a.pfm").stat().st_mtime_ns != before["a.pfm"]
    assert (out / "b.pfm").stat().st_mtime_ns == before["b.pfm"]
    assert json.loads(path.read_text())["maps"] == {"a.pfm": digest, "b.pfm": digest}
    # a record of an older version (a list of the maps, all of its settings) still resumes
    path.write_text(json.dumps({"settings": record["settings"], "finished": ["a.pfm", "b.pfm"]}))
    code, stdout, _ = run_cli([*argv, "--resume"])
    assert code == 0 and "wrote 0 disparity maps" in stdout and "2 kept from before" in stdout


@pytest.fixture()
def bad_folders(tmp_path, texture):
    """Four pairs: ``a`` and ``d`` good, ``b``'s left image a text file, ``c``'s right image
    wider than its left."""
    left, right = _folders(tmp_path, texture, ["a.png", "b.png", "c.png", "d.png"])
    (left / "b.png").write_text("not an image\n")
    iio.imwrite(right / "c.png", texture(9, (HEIGHT, WIDTH + 1, 3)))
    return left, right


def test_bad_pairs_are_named_and_the_good_ones_written(bad_folders, tmp_path, run_cli, tiny):
    left, right = bad_folders
    out = tmp_path / "out"
    code, stdout, stderr = run_cli(["match", left, right, "--ndisp", NDISP, "-o", out, *tiny.args])
    assert code == 2
    assert "wrote 2 disparity maps" in stdout and "2 failed" in stdout
    lines = _messages(stderr)
    assert lines[0].startswith(f"sswjax: error: pair b.png: cannot read image {left / 'b.png'}: ")
    assert lines[1] == "sswjax: error: pair c.png: left 40x24 and right 41x24 differ in size"
    assert lines[-1].startswith("sswjax: error: 2 of 4 maps written; 2 pairs failed: b.png, "
                                "c.png")
    assert sorted(os.listdir(out)) == [".sswjax-run.json", "a.pfm", "d.pfm"]
    assert read_pfm(out / "a.pfm").shape == (HEIGHT, WIDTH)
    assert sorted(json.loads((out / ".sswjax-run.json").read_text())["maps"]) == ["a.pfm",
                                                                                 "d.pfm"]


def test_strict_refuses_the_whole_run(bad_folders, tmp_path, run_cli, tiny):
    left, right = bad_folders
    out = tmp_path / "out"
    code, stdout, stderr = run_cli(["match", left, right, "--ndisp", NDISP, "-o", out,
                                    "--strict", *tiny.args])
    assert (code, stdout) == (2, "")
    assert stderr.count("\n") == 1, stderr
    assert stderr.startswith(f"sswjax: error: pair b.png: cannot read image {left / 'b.png'}: ")
    assert stderr.endswith("; 1 more bad pair: c.png\n")
    assert not out.exists()


@pytest.mark.slow  # a fresh process starting a Dask cluster whose workers import JAX and compile
def test_workers_beyond_the_cores_are_capped_and_a_bad_pair_skipped_quietly(tmp_path, texture,
                                                                           tiny):
    pytest.importorskip("distributed")
    left, right = _folders(tmp_path, texture, ["a.png", "b.png", "c.png"])
    (left / "b.png").write_text("not an image\n")
    out = tmp_path / "out"
    cores = sorted(os.sched_getaffinity(0))[:2] if hasattr(os, "sched_getaffinity") else None
    run = subprocess.run([sys.executable, "-c", ON_CORES, repr(cores), "match", str(left),
                          str(right), "--ndisp", str(NDISP), "-o", str(out), "--workers", "64",
                          *tiny.args], capture_output=True, text=True, timeout=400, check=False)
    count = len(cores) if cores is not None else os.cpu_count()
    assert run.returncode == 2, run.stderr
    assert "Traceback" not in run.stderr and "killing" not in run.stderr, run.stderr
    assert "WARNING" not in run.stderr and "ERROR" not in run.stderr, run.stderr
    lines = _messages(run.stderr)
    assert f"sswjax: note: --workers 64 is more than the {count} cores here: using {count}" \
        in lines, run.stderr
    assert any(line.startswith(f"sswjax: note: {count} Dask workers at") for line in lines)
    assert any(line.startswith("sswjax: error: pair b.png: cannot read image") for line in lines)
    assert lines[-1].startswith("sswjax: error: 2 of 3 maps written; 1 pair failed: b.png")
    assert f"on {count} workers" in run.stdout
    assert sorted(os.listdir(out)) == [".sswjax-run.json", "a.pfm", "c.pfm"]
    assert read_pfm(out / "c.pfm").shape == (HEIGHT, WIDTH)
