"""The memory guard: the estimate against measured peaks, free memory, refusals (API and CLI)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import sswjax
from sswjax import ExecutionPlan
from sswjax.runtime import memory
from sswjax.runtime.memory import (MemoryEstimateError, available_bytes, check_memory,
                                   estimate_peak_bytes, plan_for_memory)

MEASURE = r"""
import json, sys
import numpy as np
import sswjax
height, width, ndisp, preset = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
right = (np.random.default_rng(0).random((height, width, 3)) * 255).astype(np.uint8)
sswjax.match(np.roll(right, 5, axis=1), right, ndisp, params=sswjax.preset(preset))
# VmHWM, the peak RSS of this process's own memory: ru_maxrss would keep the peak of the
# parent (pytest, gigabytes in a full run) from before the exec.
status = open("/proc/self/status").read().split("VmHWM:")[1].split()
print(json.dumps(int(status[0]) * 1024))
"""


@pytest.mark.parametrize("preset, height, width, ndisp", [("paper", 400, 600, 96),
                                                          ("accurate", 480, 640, 192),
                                                          ("fast", 1000, 1600, 320)])
def test_estimate_is_above_the_measured_peak_within_the_stated_margin(preset, height, width, ndisp,
                                                                      user_environment):
    # sizes the fit never saw, above the compile floor. fast's full-resolution stages (the
    # window term) were fitted to 0 before fast was measured, and its estimate fell below its
    # peak at these sizes (1728 x 1216 x 256: 1.22 GB against 1.32 measured).
    run = subprocess.run([sys.executable, "-c", MEASURE, str(height), str(width), str(ndisp), preset],
                         capture_output=True, text=True, timeout=600, env=user_environment)
    assert run.returncode == 0, run.stderr
    peak = json.loads(run.stdout.strip().splitlines()[-1])
    estimate = estimate_peak_bytes(height, width, ndisp, params=sswjax.preset(preset))
    assert peak <= estimate <= memory.STATED_RATIO * peak, (peak, estimate)


def test_estimate_follows_the_parameters():
    accurate = sswjax.preset("accurate")
    whole = estimate_peak_bytes(1988, 2964, 280, params=accurate)
    strips = estimate_peak_bytes(1988, 2964, 280, params=accurate,
                                 plan=ExecutionPlan(strip_rows=64))
    assert strips < whole / 3
    paper = sswjax.Params()
    assert estimate_peak_bytes(497, 741, 70, params=paper, plan=ExecutionPlan(disparity_chunk=0)) > \
        estimate_peak_bytes(497, 741, 70, params=paper)
    assert estimate_peak_bytes(497, 741, 70, params=paper.replace(segments=None)) < \
        estimate_peak_bytes(497, 741, 70, params=paper)
    # (the default preset's estimate at this size is its compile floor: the terms show on paper's)
    assert estimate_peak_bytes(497, 741, 70, params=paper,
                               plan=ExecutionPlan(buckets=sswjax.ShapeBuckets())) > \
        estimate_peak_bytes(497, 741, 70, params=paper)
    assert estimate_peak_bytes(497, 741, 70, params=paper, channels=1) < \
        estimate_peak_bytes(497, 741, 70, params=paper)
    with pytest.raises(ValueError, match="ndisp must be a positive integer, got 0"):
        estimate_peak_bytes(10, 10, 0)
    with pytest.raises(ValueError, match="channels must be 1 or 3"):
        estimate_peak_bytes(10, 10, 4, channels=4)


def test_available_bytes_reads_meminfo_and_the_cgroup(tmp_path):
    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal:       24000000 kB\nMemAvailable:    2000000 kB\n")
    cgroup = tmp_path / "cgroup"
    cgroup.mkdir()
    assert available_bytes(meminfo=meminfo, cgroup=cgroup) == 2_048_000_000
    (cgroup / "memory.max").write_text("1000000000\n")
    (cgroup / "memory.current").write_text("400000000\n")
    assert available_bytes(meminfo=meminfo, cgroup=cgroup) == 600_000_000
    (cgroup / "memory.max").write_text("max\n")
    assert available_bytes(meminfo=meminfo, cgroup=cgroup) == 2_048_000_000
    assert available_bytes(meminfo=tmp_path / "absent", cgroup=tmp_path / "absent") is None


def test_check_memory_says_what_to_change():
    accurate = sswjax.preset("accurate")
    estimate = estimate_peak_bytes(1988, 2964, 280, params=accurate)
    with pytest.raises(MemoryEstimateError) as error:
        check_memory(1988, 2964, 280, params=accurate, limit=4.5e9)
    message = str(error.value)
    assert "\n" not in message and f"needs about {estimate / 1e9:.2f} GB" in message
    assert "more than the limit (4.50 GB)" in message
    assert "plan=sswjax.ExecutionPlan(strip_rows=" in message  # the API's own terms
    refusal = error.value
    assert isinstance(refusal, MemoryError) and refusal.estimate == estimate
    assert (refusal.limit, refusal.bound, refusal.shape) == (4.5e9, "the limit", (2964, 1988, 280))
    rows = int(message.split("strip_rows=")[1].split(")")[0])
    assert refusal.strips == ExecutionPlan(strip_rows=rows)
    assert refusal.strips_estimate == estimate_peak_bytes(1988, 2964, 280, params=accurate,
                                                          plan=refusal.strips) <= 4.5e9
    with pytest.raises(MemoryEstimateError, match="a smaller ndisp or image"):
        check_memory(1988, 2964, 280, params=accurate, limit=1e8)


def test_plan_for_memory_chooses_the_tallest_strips_that_fit():
    accurate = sswjax.preset("accurate")
    whole = ExecutionPlan()
    assert plan_for_memory(497, 741, 70, params=accurate, plan=whole, limit=1e12) is whole
    fitted = plan_for_memory(1988, 2964, 280, params=accurate, limit=6e9)
    rows = fitted.strip_rows
    assert rows in memory.STRIP_HEIGHTS and fitted.strip_overlap <= rows
    assert estimate_peak_bytes(1988, 2964, 280, params=accurate, plan=fitted) <= 6e9
    taller = [r for r in memory.STRIP_HEIGHTS if r > rows]
    assert all(estimate_peak_bytes(1988, 2964, 280, params=accurate,
                                   plan=ExecutionPlan(strip_rows=r)) > 6e9 for r in taller)
    assert fitted._replace(strip_rows=0, strip_overlap=whole.strip_overlap) == whole  # the rest kept
    explicit = ExecutionPlan(strip_rows=rows)                            # the user's strips stay
    assert plan_for_memory(1988, 2964, 280, params=accurate, plan=explicit, limit=6e9) is explicit
    with pytest.raises(MemoryEstimateError, match="more than the limit"):
        plan_for_memory(1988, 2964, 280, params=accurate, plan=ExecutionPlan(strip_rows=1024),
                        limit=6e9)
    with pytest.raises(MemoryEstimateError, match="even strips of 16 rows do not fit") as error:
        plan_for_memory(1988, 2964, 280, params=accurate, limit=1e8)
    assert error.value.strips is None and error.value.strips_estimate is None


def test_api_matches_in_strips_when_the_whole_pair_does_not_fit(monkeypatch, texture):
    right = texture(0, shape=(120, 40, 3))
    left = np.roll(right, 3, axis=1)
    params = sswjax.Params()
    # A model in which only strips of at most 64 rows fit in the 1 GB "available".
    monkeypatch.setattr(memory, "available_bytes", lambda: 10**9)
    monkeypatch.setattr(memory, "estimate_peak_bytes",
                        lambda h, w, d, *, plan, **_: (plan.strip_rows or 10**4) * 1.5e7)
    automatic = sswjax.match(left, right, 8, params=params)
    explicit = sswjax.match(left, right, 8, params=params, plan=ExecutionPlan(strip_rows=64),
                            check_memory=False)
    np.testing.assert_array_equal(automatic, explicit)


def test_api_refuses_what_does_not_fit_unless_told(monkeypatch, texture):
    right = texture(0)
    left = np.roll(right, 3, axis=1)
    monkeypatch.setattr(memory, "available_bytes", lambda: 10**8)
    with pytest.raises(MemoryEstimateError, match="more than the available memory"):
        sswjax.match(left, right, 8)
    assert sswjax.match(left, right, 8, check_memory=False).shape == left.shape[:2]


def test_cli_refuses_with_max_memory(small_pair, tmp_path, run_cli):
    out = tmp_path / "out.pfm"
    code, stdout, stderr = run_cli(["match", small_pair.folder / "left.png",
                                    small_pair.folder / "right.png", "--ndisp", 8, "-o", out,
                                    "--max-memory", "0.1"])
    assert code == 2 and stdout == "" and not out.exists()
    assert stderr.count("\n") == 1
    assert stderr.startswith("sswjax: error: a 40x24 pair with ndisp 8 needs about ")
    assert "more than the limit (0.10 GB)" in stderr
    for bad in ("0", "-1", "lots", "inf"):
        code, _, stderr = run_cli(["match", small_pair.folder / "left.png",
                                   small_pair.folder / "right.png", "--ndisp", 8, "-o", out,
                                   "--max-memory", bad])
        assert code == 2 and f"argument --max-memory: must be a number of GB > 0, got '{bad}'" in stderr
