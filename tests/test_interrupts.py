"""Nothing lost on Ctrl-C: finished scenes are kept, ``--resume`` continues, outputs survive.

The SIGINT test sends a real signal to a ``sswjax evaluate`` process (with conftest's
``tiny`` configuration: the mechanics are what is tested); the others interrupt in process,
with a fake method that needs no JAX. Scenes are conftest's ``middeval3`` folders (24 rows,
disparity 3, ndisp 8).
"""

from __future__ import annotations

import gc
import shlex
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

import sswjax
from sswjax.cli import match as cli_match
from sswjax.cli.common import interrupt_flag
from sswjax.data.io import read_pfm, write_pfm
from sswjax.evaluation import methods

CLI = [sys.executable, "-m", "sswjax.cli"]


def _popen_with_default_sigint(argv, **kwargs) -> subprocess.Popen:
    """``Popen`` whose child handles SIGINT as in an interactive terminal.

    A shell without job control starts background jobs with SIGINT ignored, and children
    inherit that; only then is the default disposition restored in the child (which needs a
    ``preexec_fn``, so a fork of this multithreaded process: JAX warns about it).
    """
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        return subprocess.Popen(argv, **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return subprocess.Popen(
            argv, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL), **kwargs
        )


@pytest.mark.slow  # two fresh processes, one stopped by a real signal
def test_evaluate_sigint_keeps_finished_scenes_and_resume_skips_them(tmp_path, middeval3, tiny):
    root = middeval3(tmp_path / "MiddEval3")
    scenes, height, shift = middeval3.scenes, middeval3.height, middeval3.shift
    params = tmp_path / "tiny.json"  # faster compilation; the mechanics are what is tested
    sswjax.save_params(params, tiny.params)
    out = tmp_path / "out"
    argv = ["evaluate", "--data", str(root), "--methods", "ssw", "--params", str(params), "-o", str(out)]
    first_done = out / "ssw" / scenes[0][0] / "timeSSW.txt"  # written after the scene's PFM
    with open(tmp_path / "stderr1.txt", "w") as err_file:
        process = _popen_with_default_sigint(CLI + argv, stdout=subprocess.DEVNULL, stderr=err_file)
        try:
            deadline = time.monotonic() + 240
            while not first_done.exists():
                assert process.poll() is None, (tmp_path / "stderr1.txt").read_text()
                assert time.monotonic() < deadline, "no scene finished within 240 s"
                time.sleep(0.01)
            process.send_signal(signal.SIGINT)
            code = process.wait(timeout=240)
        finally:
            if process.poll() is None:
                process.kill()
    err = (tmp_path / "stderr1.txt").read_text()
    assert code == 130, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    prefix = "sswjax: interrupted; "
    assert last.startswith(prefix)
    assert f"of 3 scene results are saved in {out}; continue with: sswjax " in last
    finished = [name for name, _ in scenes if (out / "ssw" / name / "disp0SSW.pfm").exists()
                and (out / "ssw" / name / "timeSSW.txt").exists()]
    assert 1 <= len(finished) < 3 and finished == [name for name, _ in scenes[: len(finished)]]
    assert last.startswith(f"{prefix}{len(finished)} of 3 scene results")
    assert not (out / "results.md").exists()  # only written at the end
    assert not list(out.rglob("*.tmp"))
    saved = {}
    for name in finished:
        pfm = out / "ssw" / name / "disp0SSW.pfm"
        assert read_pfm(pfm).shape == (height, dict(scenes)[name])  # complete and readable
        saved[name] = (pfm.read_bytes(), pfm.stat().st_mtime_ns)

    # run exactly the command that the message suggests
    command = shlex.split(last.split("continue with: ", 1)[1])
    assert command[0] == "sswjax" and command[-1] == "--resume"
    resumed = subprocess.run(CLI + command[1:], capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert f"ssw: resumed {len(finished)} of 3 scenes from {out / 'ssw'}" in resumed.stderr
    for name, (content, mtime) in saved.items():  # not recomputed, not rewritten
        pfm = out / "ssw" / name / "disp0SSW.pfm"
        assert pfm.read_bytes() == content and pfm.stat().st_mtime_ns == mtime
    for name, width in scenes:
        disparity = read_pfm(out / "ssw" / name / "disp0SSW.pfm")
        assert disparity.shape == (height, width)
        assert np.median(disparity[:, 12:]) == pytest.approx(shift, abs=0.05)
    results = (out / "results.md").read_text()
    assert "| ssw |" in results and all(f"| {name} |" in results for name, _ in scenes)
    assert len((out / "metrics.csv").read_text().splitlines()) == 1 + 3 * 2
    assert "wrote" in resumed.stdout


def test_match_interrupted_keeps_existing_output(small_pair, tmp_path, run_cli, monkeypatch):
    out = tmp_path / "d.pfm"
    write_pfm(out, np.full((2, 3), 7, np.float32))

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_match, "match", interrupted)
    files = small_pair.folder
    argv = ["match", files / "left.png", files / "right.png", "--ndisp", small_pair.ndisp, "-o", out]
    code, _, err = run_cli(argv)
    assert code == 130 and err == "sswjax: interrupted\n"
    assert (read_pfm(out) == 7).all() and [p.name for p in tmp_path.iterdir()] == ["d.pfm"]


def _sigint_in_a_gc_callback() -> None:
    """Ctrl-C as it often lands in JAX: its handler runs inside a garbage-collection callback.
    Raised there, the ``KeyboardInterrupt`` would be printed as "Exception ignored" with its
    traceback and dropped; the handler only remembers it there, so nothing is dropped."""
    fired = []

    def callback(phase, info):
        if not fired:
            fired.append(phase)
            signal.raise_signal(signal.SIGINT)  # the handler runs here, before it returns

    dropped = []
    hook, sys.unraisablehook = sys.unraisablehook, dropped.append
    gc.callbacks.append(callback)
    try:
        gc.collect()
    finally:
        gc.callbacks.remove(callback)
        sys.unraisablehook = hook
    assert fired and [d.exc_type for d in dropped] == []


def test_the_search_flag_is_set_by_a_first_ctrl_c_and_a_second_interrupts():
    with interrupt_flag() as interrupted:
        assert not interrupted()
        signal.raise_signal(signal.SIGINT)      # the first: remembered, nothing raised
        assert interrupted()
        _sigint_in_a_gc_callback()              # a second in a GC callback: nothing dropped
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)  # elsewhere: raised where it lands


@pytest.fixture()
def fake_method(monkeypatch, middeval3):
    """A method "fake" without JAX: disparity 3 everywhere; counts its calls per scene width."""
    calls = []

    def fake(left, right, ndisp):
        calls.append(left.shape[1])
        if getattr(fake, "interrupt_at", None) == len(calls):
            raise KeyboardInterrupt
        if getattr(fake, "dropped_interrupt_at", None) == len(calls):
            _sigint_in_a_gc_callback()
        return np.full(left.shape[:2], middeval3.shift, np.float32)

    monkeypatch.setitem(methods.PEERS, "fake", methods.Peer(fake, "a stand-in without JAX"))
    fake.calls = calls
    return fake


def test_evaluate_interrupted_in_process_messages(tmp_path, run_cli, middeval3, fake_method):
    root = middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "out"
    fake_method.interrupt_at = 2
    code, stdout, err = run_cli(["evaluate", "--data", root, "--methods", "fake", "-o", out])
    assert code == 130 and stdout == ""
    # the command the user typed, --resume added: run_cli types --quiet before the command
    expected = (f"sswjax: interrupted; 1 of 3 scene results are saved in {out}; continue with: "
                f"sswjax --quiet evaluate --data {root} --methods fake -o {out} --resume")
    assert err.strip().splitlines()[-1] == expected
    assert sorted(p.name for p in (out / "fake").iterdir()) == ["Adirondack"]
    # without -o nothing can be kept, and the message says so
    fake_method.calls.clear()
    code, _, err = run_cli(["evaluate", "--data", root, "--methods", "fake"])
    assert code == 130
    assert err.strip().splitlines()[-1] == ("sswjax: interrupted; nothing was saved (with -o DIR "
                                            "finished scenes are kept and --resume continues)")


def test_a_ctrl_c_dropped_in_a_gc_callback_still_interrupts_after_the_scene(tmp_path, run_cli,
                                                                          middeval3, fake_method):
    root = middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "out"
    fake_method.dropped_interrupt_at = 2
    code, _, err = run_cli(["evaluate", "--data", root, "--methods", "fake", "-o", out])
    assert code == 130, err
    assert "Traceback" not in err and "Exception ignored" not in err
    assert err.strip().splitlines()[-1].startswith(
        f"sswjax: interrupted; 2 of 3 scene results are saved in {out}; continue with: ")
    assert fake_method.calls == [40, 44]
    assert sorted(p.name for p in (out / "fake").iterdir()) == ["Adirondack", "Teddy"]


def test_evaluate_resume_recomputes_only_missing_or_damaged_scenes(tmp_path, run_cli, middeval3,
                                                                  fake_method):
    root = middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "out"
    assert run_cli(["evaluate", "--data", root, "--methods", "fake", "-o", out])[0] == 0
    first_csv = (out / "metrics.csv").read_text()
    assert fake_method.calls == [40, 44, 48]
    folders = {name: out / "fake" / name for name, _ in middeval3.scenes}
    (folders["Adirondack"] / "timeFAKE.txt").write_text("12.5\n")  # a recorded time is kept
    kept_mtime = (folders["Adirondack"] / "disp0FAKE.pfm").stat().st_mtime_ns
    pfm = folders["Teddy"] / "disp0FAKE.pfm"
    pfm.write_bytes(pfm.read_bytes()[:-10])  # damaged by hand: recomputed
    (folders["Vintage"] / "timeFAKE.txt").unlink()  # interrupted between the two writes
    fake_method.calls.clear()
    code, _, err = run_cli(["evaluate", "--data", root, "--methods", "fake", "-o", out, "--resume"])
    assert code == 0, err
    assert fake_method.calls == [44, 48]
    assert f"fake Teddy: saved result unusable (PFM file {pfm} is truncated: " in err
    assert f"fake: resumed 1 of 3 scenes from {out / 'fake'}" in err
    assert (folders["Adirondack"] / "disp0FAKE.pfm").stat().st_mtime_ns == kept_mtime
    assert read_pfm(pfm).shape == (middeval3.height, 44)
    def expected(row: str) -> str:  # the "seconds" column is the fourth
        cells = row.split(",")
        if cells[1] == "Adirondack":  # resumed: its recorded time
            return ",".join(cells[:3] + ["12.500"] + cells[4:])
        # recomputed: the same metrics; its time is measured again (a busy host takes ms)
        return ",".join(cells[:3] + ["*"] + cells[4:])

    def seen(row: str) -> str:
        cells = row.split(",")
        return row if cells[1] == "Adirondack" else ",".join(cells[:3] + ["*"] + cells[4:])

    rows = (out / "metrics.csv").read_text().splitlines()
    assert [seen(r) for r in rows[1:]] == [expected(r) for r in first_csv.splitlines()[1:]]
