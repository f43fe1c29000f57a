"""Shape buckets (few compilations for many sizes) and the persistent compilation cache."""

from __future__ import annotations

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sswjax
from sswjax.runtime.executables import EXECUTABLES
from sswjax.graph.padding import padding_as_edge
from sswjax.runtime.buckets import ShapeBuckets, bucket_shape

BUCKETS = ShapeBuckets(size_step=64, ndisp_step=16)


def test_bucket_shape_rounds_up_and_keeps_ndisp_below_width():
    assert bucket_shape(375, 450, 64, ShapeBuckets()) == (512, 512, 96)
    assert bucket_shape(497, 741, 190, ShapeBuckets()) == (512, 768, 192)
    assert bucket_shape(40, 60, 16, BUCKETS) == (64, 64, 16)
    assert bucket_shape(30, 60, 70, BUCKETS) == (64, 128, 80)  # width grows to hold ndisp


def test_trainingq_sizes_fall_into_three_buckets():
    sizes = [(496, 718, 73), (277, 347, 64), (497, 659, 160), (497, 741, 70), (497, 741, 70),
             (481, 707, 65), (481, 707, 65), (485, 735, 75), (476, 699, 83), (463, 680, 73),
             (462, 681, 73), (486, 720, 65), (497, 738, 60), (375, 450, 64), (480, 722, 190)]
    assert len({bucket_shape(*s, ShapeBuckets()) for s in sizes}) == 3


def _pair(height, width, shift, seed):
    rng = np.random.default_rng(seed)
    right = (rng.random((height, width, 3)) * 255).astype(np.uint8)
    return np.roll(right, shift, axis=1), right


def test_pairs_of_nearby_sizes_compile_once_and_stay_accurate():
    # the paper's method with few superpixels: the one preset with segments, padded too
    params = sswjax.Params().replace(**{"segments.n_segments": 20})
    EXECUTABLES.clear()
    for (height, width), ndisp in (((40, 60), 12), ((50, 64), 9), ((64, 50), 16)):
        left, right = _pair(height, width, 5, height)
        disparity = sswjax.match(left, right, ndisp, params=params, buckets=BUCKETS)
        assert disparity.shape == (height, width)
        assert disparity.max() <= ndisp - 1
        assert np.median(disparity[:, 12:]) == pytest.approx(5, abs=0.01)
    assert len(EXECUTABLES) == 1  # one bucket, one compiled graph


def test_padded_disparities_are_never_chosen():
    left, right = _pair(40, 60, 2, 1)
    params = sswjax.Params().replace(**{"segments.n_segments": 20})  # the graph of the test above
    disparity = sswjax.match(left, right, 3, params=params, buckets=BUCKETS)  # volume of 16, range 3
    assert disparity.max() <= 2


def test_second_process_reuses_the_compilation_cache(tmp_path):
    # conftest's tiny configuration (the paper's without superpixels, a 3 x 3 box): any graph
    # goes through the cache, a cheap one compiles in the first process in a second
    script = (
        "import numpy as np, sswjax\n"
        "from sswjax.runtime.compilation import enable_compilation_cache\n"
        "enable_compilation_cache()\n"
        "r = np.random.default_rng(0).random((24, 40, 3)).astype(np.float32)\n"
        "params = sswjax.preset('paper').replace(segments=None, "
        "aggregation={'kind': 'box', 'radius': 1})\n"
        "sswjax.match(np.roll(r, 2, axis=1), r, 6, params=params)\n"
    )
    env = dict(os.environ, SSWJAX_CACHE_DIR=str(tmp_path / "cache"))
    subprocess.run([sys.executable, "-c", script], env=env, check=True)
    entries = sorted(p.name for p in (tmp_path / "cache").iterdir())
    assert any("ssw_disparity" in name for name in entries)
    subprocess.run([sys.executable, "-c", script], env=env, check=True)
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == entries  # reused, not re-added


@pytest.mark.slow  # three presets at two shapes each: a minute of compiling per preset
@pytest.mark.parametrize("name", ["accurate", "balanced", "fast"])
def test_a_padded_pair_is_matched_as_at_its_own_size(name):
    # Padding replicates the last row and column of both views; matched as such, the padded
    # columns (left edge copies against the real right image) pulled a corner of the map off
    # along the semi-global paths. The padding now holds no evidence and every filter reads
    # the edge there, as it does at the pair's own size.
    import skimage.data
    left, right, _ = skimage.data.stereo_motorcycle()
    left, right = (image[250:250 + 3 * 75:3, 100:100 + 3 * 203:3] for image in (left, right))
    params = sswjax.preset(name)
    if name == "balanced":
        # Its alignment is accurate's, padded above: here its coarse pass and band.
        params = params.replace(alignment=None)
    own = sswjax.match(left, right, 24, params=params)
    padded = sswjax.match(left, right, 24, params=params,
                          buckets=ShapeBuckets(size_step=64, ndisp_step=32))
    assert bucket_shape(75, 203, 24, ShapeBuckets(size_step=64, ndisp_step=32)) == (128, 256, 32)
    assert np.mean(np.abs(own - padded) > 0.5) < 0.002


@pytest.mark.parametrize("reach", [None, 1, 3, 40])
@pytest.mark.parametrize("valid", [(5, 7), (9, 4), (1, 1), (9, 11)])
def test_padding_as_edge_copies_the_nearest_pixel_of_the_pair(valid, reach):
    # Reference: the pair cropped to its own size and padded by numpy's edge mode. With a
    # reach only that many rows and columns past the edge need be copies, and the
    # padding beyond them in both directions is left as it was.
    values = np.random.default_rng(0).normal(size=(2, 9, 11)).astype(np.float32)
    height, width = valid
    expected = np.pad(values[:, :height, :width], ((0, 0), (0, 9 - height), (0, 11 - width)),
                      mode="edge")
    # jitted, as in the graph: one small compilation per reach instead of one per operation
    edge = jax.jit(padding_as_edge, static_argnames="reach")
    got = np.asarray(edge(jnp.asarray(values), jnp.array(valid, jnp.int32), reach=reach))
    rows, columns = (9, 11) if reach is None else (height + reach, width + reach)
    np.testing.assert_array_equal(got[:, :rows, :columns], expected[:, :rows, :columns])
    if reach is not None:
        np.testing.assert_array_equal(got[:, rows:, columns:], values[:, rows:, columns:])
