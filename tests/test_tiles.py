"""Tiles (``ExecutionPlan(tile=S)``, ``--tile S``): the windows, the strips as their one-column
case, the maps against the whole image, the memory guard's choice, and a pair too large for
its budget matched in tiles under it (peak memory measured in a fresh process)."""

from __future__ import annotations

import json
import subprocess
import sys

import imageio.v3 as iio
import numpy as np
import pytest

import sswjax
from sswjax import ExecutionPlan
from sswjax.data.io import read_pfm
from sswjax.runtime.execute import bind_graph, graph_call
from sswjax.runtime.memory import (
    STRIP_HEIGHTS,
    MemoryEstimateError,
    estimate_peak_bytes,
    plan_for_memory,
    worker_peak_bytes,
)
from sswjax.runtime.plan import check_plan
from sswjax.runtime.tiles import (
    CARRIED_COLLAR,
    PREFERRED_CORE,
    TILE_SIZES,
    Tiling,
    in_tiles,
    tile_count,
    tile_windows,
    window_shape,
)

CHEAP = sswjax.Params().replace(segments=None, aggregation={"kind": "box", "radius": 1})


@pytest.mark.parametrize("height, width, tiling", [
    (90, 60, Tiling(16, 16, 8, 12)), (100, 1000, Tiling(32, 64, 5, 40, align=4)),
    (37, 300, Tiling(10, 0, 3, 7)), (64, 64, Tiling(100, 100, 8, 8)), (50, 500, Tiling(7, 9, 0, 2))])
def test_windows_share_one_shape_and_their_cores_partition_the_image(height, width, tiling):
    windows = tile_windows(height, width, tiling)
    h, w = window_shape(height, width, tiling)
    covered = np.zeros((height, width), int)
    for win in windows:
        assert (win.height, win.width) == (h, w)
        assert 0 <= win.top and win.top + h <= height and 0 <= win.left and win.left + w <= width
        covered[win.first:win.last, win.start:win.stop] += 1
        # the collar, and the disparities' columns either side, unless the image ends first
        assert win.first - win.top >= min(win.first, tiling.overlap)
        assert win.top + h - win.last >= min(height - win.last, tiling.overlap)
        if w < width:
            reach = tiling.lead + tiling.overlap
            assert win.start - win.left >= min(win.start, reach)
            assert win.left + w - win.stop >= min(width - win.stop, reach)
            if win.left + w < width - 1 and win.left > 0:
                assert win.left % tiling.align == 0
    assert (covered == 1).all()


def _old_strips(run, left, right, *, rows, overlap):
    """The strips of sswjax before tiles (``runtime/strips.py::in_strips``), the reference."""
    height, window = left.shape[0], rows + 2 * overlap
    if rows <= 0 or window >= height:
        return np.asarray(run(left, right))
    out = np.empty(left.shape[:2], np.float32)
    for first in range(0, height, rows):
        last = min(first + rows, height)
        top = min(max(first - overlap, 0), height - window)
        out[first:last] = np.asarray(run(left[top:top + window], right[top:top + window]))[
            first - top:last - top]
    return out


@pytest.mark.parametrize("rows, overlap", [(4, 1), (7, 3), (20, 0), (3, 10), (0, 5)])
def test_strips_are_the_one_column_tiling_as_before(rows, overlap):
    rng = np.random.default_rng(rows)
    image = rng.random((23, 11, 1), dtype=np.float32)

    def run(left, right):  # depends on where the window starts: context matters
        return np.cumsum(np.asarray(left)[..., 0], axis=0) + np.asarray(right)[..., 0]

    expected = _old_strips(run, image, image, rows=rows, overlap=overlap)
    np.testing.assert_array_equal(
        in_tiles(lambda window, *pair: run(*pair), image, image, Tiling(rows, 0, overlap, 6)),
        expected)


def test_each_window_of_a_padded_pair_is_told_how_much_of_it_is_the_pair():
    # A bucket pads the pair to 128 x 128; tiles of that padded image each run the graph with
    # the part of the pair inside them (traced), so their padding is matched as the edge.
    image = np.zeros((70, 100, 1), np.float32)
    plan = ExecutionPlan(buckets=sswjax.ShapeBuckets(size_step=64, ndisp_step=8))
    left, _, call = graph_call(image, image, 8, plan)
    assert left.shape[:2] == (128, 128) and call["valid_shape"] == (70, 100)
    windows = tile_windows(128, 128, Tiling(48, 48, 8, 8))
    assert len(windows) > 1
    for window in windows:
        bound = bind_graph(lambda *a, **k: k["valid_shape"], CHEAP, call, window=window)
        assert tuple(np.asarray(bound()).tolist()) == (
            min(max(70 - window.top, 0), window.height),
            min(max(100 - window.left, 0), window.width))
    # Some windows reach into the padding, some lie within the pair.
    assert any(w.top + w.height > 70 or w.left + w.width > 100 for w in windows)
    assert any(w.top + w.height <= 70 and w.left + w.width <= 100 for w in windows)
    whole = bind_graph(lambda *a, **k: k["valid_shape"], CHEAP, call)
    assert tuple(np.asarray(whole()).tolist()) == (70, 100)


def test_plans_with_tiles_are_checked():
    assert check_plan(ExecutionPlan(tile=64)).tile == 64
    with pytest.raises(ValueError, match=r"plan.tile \(64\) and plan.strip_rows \(32\) are both"):
        check_plan(ExecutionPlan(tile=64, strip_rows=32))
    with pytest.raises(ValueError, match="plan.tile must be an integer in"):
        check_plan(ExecutionPlan(tile=-1))
    with pytest.raises(TypeError, match="plan.engine must be None or have an execute method"):
        check_plan(ExecutionPlan(engine="dask"))

    class ExecuteOnly:  # an engine: what runs a call's windows
        def execute(self, *args, **kwargs):
            raise AssertionError("not called")

    assert check_plan(ExecutionPlan(engine=ExecuteOnly())).engine is not None


# The memory guard's choices below were measured (docs/cluster.md) on accurate before its
# vertical alignment, whose constant term (its compile) would move every budget they name.
ACCURATE = sswjax.preset("accurate").replace(alignment=None)


def test_memory_guard_cuts_a_wide_pair_in_tiles():
    accurate = ACCURATE
    shape = (2000, 40000, 256)                           # a satellite strip
    fitted = plan_for_memory(*shape, params=accurate, limit=8e9)
    assert fitted.tile and not fitted.strip_rows          # full-width strips cost more here
    assert estimate_peak_bytes(*shape, params=accurate, plan=fitted) <= 8e9
    # a worker holds only its window: far less than a process holding the pair
    assert worker_peak_bytes(*shape, params=accurate, plan=fitted) < \
        estimate_peak_bytes(*shape, params=accurate, plan=fitted) - 1e9
    with pytest.raises(MemoryEstimateError, match=r"match in tiles with plan=sswjax\."
                                                  r"ExecutionPlan\(tile=\d+\)") as error:
        plan_for_memory(*shape, params=accurate, plan=ExecutionPlan(tile=4096), limit=8e9)
    assert error.value.strips.tile and error.value.strips_estimate <= 8e9
    shared = plan_for_memory(*shape, params=accurate, limit=16e9, share=2, local=False)
    assert estimate_peak_bytes(*shape, params=accurate, plan=shared) <= 8e9


def _computed_pixels(height, width, ndisp, plan):
    tiling = Tiling(plan.tile or plan.strip_rows, plan.tile, plan.strip_overlap, ndisp)
    rows, cols = window_shape(height, width, tiling)
    return tile_count(height, width, tiling) * rows * cols


RESTARTED = ExecutionPlan(carry_paths=False)
"""A plan whose strips restart their paths at each window's edge (the guard's order for them)."""


def test_memory_guard_prefers_cores_of_256_rows_to_thin_strips_that_compute_less():
    # docs/cluster.md: on this pair under 3 GB, strips of 64 rows (the fewest computed pixels)
    # changed 3.36 % of the map against tiles of 1024, tiles of 512 changed 0.03 %
    accurate, shape = ACCURATE, (3000, 4000, 256)
    fitted = plan_for_memory(*shape, params=accurate, plan=RESTARTED, limit=3e9, local=False)
    assert fitted.tile >= PREFERRED_CORE and not fitted.strip_rows
    thin = ExecutionPlan(strip_rows=64, strip_overlap=64)
    assert estimate_peak_bytes(*shape, params=accurate, plan=thin) <= 3e9
    assert _computed_pixels(*shape, thin) < _computed_pixels(*shape, fitted)
    # a budget that no core of 256 rows or more fits still gets the thin strips that fit
    wide = [ExecutionPlan(strip_rows=rows, strip_overlap=min(96, rows))
            for rows in STRIP_HEIGHTS if rows >= PREFERRED_CORE]
    wide += [ExecutionPlan(tile=size) for size in TILE_SIZES if size >= PREFERRED_CORE]
    budget = min(estimate_peak_bytes(*shape, params=accurate, plan=p) for p in wide) - 1
    last_resort = plan_for_memory(*shape, params=accurate, plan=RESTARTED, limit=budget,
                                  local=False)
    assert 0 < (last_resort.strip_rows or last_resort.tile) < PREFERRED_CORE
    assert estimate_peak_bytes(*shape, params=accurate, plan=last_resort) <= budget


def test_memory_guard_prefers_tiles_with_the_whole_collar_to_thin_strips_with_less():
    # docs/cluster.md: KITTI 2012 000103 under 1 GB, strips of 48 rows (collar capped at 48)
    # changed 13.5 % of the map, tiles of 128 with the collar of 96 1.7 %
    accurate, shape = ACCURATE, (376, 1241, 128)
    thin = ExecutionPlan(strip_rows=48, strip_overlap=48)
    tiles = ExecutionPlan(tile=128, strip_overlap=96)
    budget = max(estimate_peak_bytes(*shape, params=accurate, plan=plan) for plan in (thin, tiles))
    assert _computed_pixels(*shape, thin) < _computed_pixels(*shape, tiles)
    fitted = plan_for_memory(*shape, params=accurate, plan=RESTARTED, limit=budget, local=False)
    assert fitted.strip_overlap == ExecutionPlan().strip_overlap == 96
    assert fitted.tile and not fitted.strip_rows
    assert estimate_peak_bytes(*shape, params=accurate, plan=fitted) <= budget


def test_carried_strips_thinner_than_the_least_collar_keep_it():
    # docs/cluster.md: KITTI 000122 (216 disparities) under 1 GB (the model of 2026-12-04),
    # strips of 32 rows with their collar capped at 32 changed 1.44 % of the map, strips of 16
    # with a collar of 48 0.002 %. The budget: what those strips of 16 need, by the model.
    accurate, shape = ACCURATE, (375, 1242, 216)
    kept = ExecutionPlan(strip_rows=16, strip_overlap=CARRIED_COLLAR)
    budget = estimate_peak_bytes(*shape, params=accurate, plan=kept)
    whole_collar = ExecutionPlan(strip_rows=32, strip_overlap=CARRIED_COLLAR)
    assert estimate_peak_bytes(*shape, params=accurate, plan=whole_collar) > budget
    fitted = plan_for_memory(*shape, params=accurate, limit=budget, local=False)
    assert (fitted.strip_rows, fitted.strip_overlap) == (16, CARRIED_COLLAR)
    capped = ExecutionPlan(strip_rows=32, strip_overlap=32)
    assert estimate_peak_bytes(*shape, params=accurate, plan=capped) <= budget
    assert _computed_pixels(*shape, capped) < _computed_pixels(*shape, fitted)


@pytest.mark.parametrize("shape, limit", [((3000, 4000, 256), 3e9), ((376, 1241, 128), 1.0e9)])
def test_memory_guard_prefers_strips_when_the_paths_are_carried(shape, limit):
    # Carried, a strip's paths along the rows are the whole image's whatever its height
    # (docs/cluster.md: KITTI 000104 in strips of 64 rows, 0 pixels changed, against 3.55 % in
    # tiles of 192), so strips come before any tiling that cuts the columns.
    accurate = ACCURATE
    fitted = plan_for_memory(*shape, params=accurate, limit=limit, local=False)
    assert fitted.strip_rows and not fitted.tile and fitted.carry_paths
    assert estimate_peak_bytes(*shape, params=accurate, plan=fitted) <= limit
    # fast runs coarse-to-fine: its paths are not carried, and its order is the restarted one
    fast = plan_for_memory(*shape, params=sswjax.preset("fast"), limit=limit, local=False)
    assert fast == plan_for_memory(*shape, params=sswjax.preset("fast"), plan=RESTARTED,
                                   limit=limit, local=False)._replace(carry_paths=True)
    # a budget that no whole collar fits still gets the thin strips that fit
    budget = min(estimate_peak_bytes(*shape, params=accurate, plan=plan) for plan in
                 [ExecutionPlan(tile=size) for size in TILE_SIZES]
                 + [ExecutionPlan(strip_rows=rows) for rows in STRIP_HEIGHTS if 96 <= rows < 376]) - 1
    last_resort = plan_for_memory(*shape, params=accurate, limit=budget, local=False)
    assert 0 < last_resort.strip_rows < 96 and last_resort.strip_overlap == last_resort.strip_rows


def test_tiles_of_a_local_method_equal_the_whole_image(tmp_path, run_cli, square_pair):
    # the cheap method sees a few pixels around each (census, box, medians) and, through the
    # left-right check, the disparities' columns either side: tiles with a collar reproduce
    # the whole image bit for bit, every output (--tile through the command line)
    left, right = (np.round(image * 255).astype(np.uint8) for image in square_pair)
    iio.imwrite(tmp_path / "l.png", left)
    iio.imwrite(tmp_path / "r.png", right)
    out = {name: tmp_path / name for name in ("d.pfm", "c.pfm", "v.png")}
    argv = ["match", tmp_path / "l.png", tmp_path / "r.png", "--ndisp", 12, "-o", out["d.pfm"],
            "--confidence", out["c.pfm"], "--validity", out["v.png"], "--preset", "paper",
            "--set", "segments=none", "--set", "aggregation=box", "--set", "aggregation.radius=1"]
    code, _, err = run_cli(argv + ["--tile", 16, "--strip-overlap", 8])
    assert code == 0, err
    whole = sswjax.match_with_confidence(left, right, 12, params=CHEAP)
    np.testing.assert_array_equal(read_pfm(out["d.pfm"]), whole.disparity)
    np.testing.assert_array_equal(read_pfm(out["c.pfm"]), whole.confidence)
    np.testing.assert_array_equal(iio.imread(out["v.png"]), whole.validity)
    code, _, err = run_cli(argv + ["--tile", 12, "--strip-rows", 8])
    assert code == 2 and err == ("sswjax: error: --tile 12 and --strip-rows 8 both cut the "
                                 "pair: give one\n")
    code, _, err = run_cli(argv + ["--workers", 0])
    assert code == 2 and "argument --workers: must be an integer >= 1, got '0'" in err


PEAK = r"""
import json, sys
from sswjax.cli import main
codes = [main(sys.argv[2:] + ["--tile", "256", "-o", "256.pfm", "--max-memory", sys.argv[1]])]
status = open("/proc/self/status").read().split("VmHWM:")[1].split()   # the tiles of 256's
codes.append(main(sys.argv[2:] + ["--tile", "512", "-o", "512.pfm"]))  # 1.26 GB: no budget
print(json.dumps([codes, int(status[0]) * 1024]))
"""


def test_a_pair_too_large_for_the_budget_is_matched_in_tiles_under_it(tmp_path, texture,
                                                                      user_environment):
    # 640 x 960 x 128 disparities, the cheap method with 4 semi-global paths: 1.40 GB whole by
    # the model, too much for 1.0 GB (the guard would cut it); in tiles of 256 it runs, its
    # peak (VmHWM of a fresh process) under the budget, and its map equals the tiles of 512's
    # but on a few pixels of the seams, where the paths restart. A collar of 32: with the
    # default's, the windows of 512 would hold the whole pair (the full size is
    # benchmarks/large_pair.py).
    height, width, ndisp, budget = 640, 960, 128, 1.0
    right = texture(5, (height, width, 3))
    iio.imwrite(tmp_path / "right.png", right)
    iio.imwrite(tmp_path / "left.png", np.roll(right, 9, axis=1))
    semi_global = CHEAP.replace(optimizer={"kind": "sgm", "paths": 4, "dtype": "uint8"})
    assert estimate_peak_bytes(height, width, ndisp, params=semi_global) > budget * 1e9
    fitted = plan_for_memory(height, width, ndisp, params=semi_global, limit=budget * 1e9)
    assert fitted.tile or fitted.strip_rows                  # the guard would cut it too
    argv = ["--no-cache", "match", "left.png", "right.png", "--ndisp", str(ndisp),
            "--preset", "paper", "--set", "segments=none", "--set", "aggregation=box",
            "--set", "aggregation.radius=1", "--set",
            'optimizer={"kind": "sgm", "paths": 4, "dtype": "uint8"}', "--strip-overlap", "32"]
    run = subprocess.run([sys.executable, "-c", PEAK, str(budget), *argv], capture_output=True,
                         text=True, timeout=600, cwd=tmp_path, check=False, env=user_environment)
    assert run.returncode == 0, run.stderr
    codes, peak = json.loads(run.stdout.strip().splitlines()[-1])
    assert codes == [0, 0] and peak <= budget * 1e9, (peak, run.stderr)
    small, large = read_pfm(tmp_path / "256.pfm"), read_pfm(tmp_path / "512.pfm")
    assert np.mean(small != large) < 0.005
    assert np.median(small[:, ndisp:]) == pytest.approx(9, abs=0.01)
