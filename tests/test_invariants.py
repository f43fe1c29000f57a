"""Properties of every result (hypothesis) and determinism, in one process and across processes.

Any image content, dtype and valid weights give a finite ``(H, W)`` float32 map in
``[0, ndisp - 1]``; the same pair gives the same bits every time. ``ndisp`` 8, as conftest's
``small_pair`` (a pair that compiles once per process for both kinds of test).
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import sswjax
from sswjax import ConfigError, Params
from sswjax.cli import main
from sswjax.data.io import read_image, read_pfm

NDISP = 8
CLI = [sys.executable, "-m", "sswjax.cli"]


# ----------------------------------------------------------------------------- invariants


_IMAGE_KINDS = ("noise", "constant", "zeros", "saturated", "stripes", "checker", "shifted")


def _image_pair(kind: str, shape: tuple, seed: int):
    rng = np.random.default_rng(seed)
    if kind == "noise":
        return rng.random(shape), rng.random(shape)
    if kind == "constant":
        value = rng.random()
        return np.full(shape, value), np.full(shape, value)
    if kind == "zeros":
        return np.zeros(shape), np.zeros(shape)
    if kind == "saturated":
        return (rng.random(shape) > 0.5) * 1.0, np.ones(shape)
    if kind == "stripes":
        row = (np.arange(shape[1]) % 2) * 1.0
        stripes = np.broadcast_to(row[None, :, None] if len(shape) == 3 else row[None], shape)
        return stripes, np.roll(stripes, 1, axis=1)
    if kind == "checker":
        yy, xx = np.indices(shape[:2])
        board = ((yy // 3 + xx // 3) % 2) * 1.0
        board = board[..., None].repeat(shape[2], -1) if len(shape) == 3 else board
        return board, board
    right = rng.random(shape)
    return np.roll(right, int(rng.integers(0, NDISP)), axis=1), right


@settings(max_examples=12, deadline=None)
@given(
    shape=st.sampled_from([(24, 40, 3), (16, 32)]),
    kind=st.sampled_from(_IMAGE_KINDS),
    dtype=st.sampled_from(["uint8", "uint16", "float32", "float64"]),
    seed=st.integers(0, 2**16),
    weights=st.tuples(*[st.floats(0, 1)] * 3),
    truncations=st.tuples(st.floats(1e-3, 1), st.floats(1e-3, 1)),
    segment_weight=st.floats(0, 2),
    lr_tolerance=st.floats(0, 3),
)
def test_pipeline_invariants_on_random_images(shape, kind, dtype, seed, weights, truncations,
                                              segment_weight, lr_tolerance):
    left, right = _image_pair(kind, shape, seed)
    if dtype.startswith("uint"):
        scale = np.iinfo(dtype).max
        left, right = (np.round(im * scale).astype(dtype) for im in (left, right))
    else:
        left, right = left.astype(dtype), right.astype(dtype)
    params = Params().replace(**{
        "cost.tad_weight": weights[0], "cost.gradient_weight": weights[1],
        "cost.census_weight": weights[2], "cost.tad_truncation": truncations[0],
        "cost.gradient_truncation": truncations[1], "aggregation.segment_weight": segment_weight,
        "checks.tolerance": lr_tolerance,
    })
    if sum(weights) == 0:  # no cost at all: refused before anything runs
        with pytest.raises(ConfigError, match="are all 0: no pixel has a cost"):
            sswjax.match(left, right, NDISP, params=params)
    assume(sum(weights) > 0)
    disparity = sswjax.match(left, right, NDISP, params=params)
    assert isinstance(disparity, np.ndarray)
    assert disparity.shape == shape[:2] and disparity.dtype == np.float32
    assert np.isfinite(disparity).all()
    assert disparity.min() >= 0 and disparity.max() <= NDISP - 1


# ----------------------------------------------------------------------------- determinism


def test_same_inputs_bit_identical_in_process(small_pair):
    files = small_pair.folder
    left, right = read_image(files / "left.png"), read_image(files / "right.png")
    first = sswjax.match(left, right, NDISP)
    second = sswjax.match(left.copy(), right.copy(), NDISP)
    assert first.tobytes() == second.tobytes()


def test_same_inputs_bit_identical_across_processes(small_pair, tmp_path):
    files = small_pair.folder
    argv = ["match", str(files / "left.png"), str(files / "right.png"), "--ndisp", str(NDISP)]
    processes = [subprocess.Popen(CLI + argv + ["-o", str(tmp_path / f"p{i}.pfm")],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                 for i in range(2)]  # concurrently: two cores, half the wall time
    for process in processes:
        _, err = process.communicate(timeout=300)
        assert process.returncode == 0, err
    assert main(argv + ["-o", str(tmp_path / "here.pfm")]) == 0
    contents = {(tmp_path / name).read_bytes() for name in ("p0.pfm", "p1.pfm", "here.pfm")}
    assert len(contents) == 1
    expected = sswjax.match(read_image(files / "left.png"), read_image(files / "right.png"), NDISP)
    assert read_pfm(tmp_path / "here.pfm").tobytes() == expected.tobytes()
