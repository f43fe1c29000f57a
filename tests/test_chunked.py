"""Disparities in chunks (running minimum over lax.scan) give the whole-volume result.

The reference is ``chunk=0`` (the whole cost volume at once), not the default ``chunk`` (4)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sswjax
from sswjax.api.images import prepare_pair
from sswjax.config import Params
from sswjax.graph import ssw_disparity

NDISP = 12


@pytest.fixture(scope="module")
def pair():
    rng = np.random.default_rng(5)
    right = rng.random((36, 64, 3), dtype=np.float32)
    # two depth layers so that LR check, filling and refinement all have work to do
    left = np.roll(right, 3, axis=1)
    left[10:26, 20:44] = np.roll(right, 8, axis=1)[10:26, 20:44]
    return tuple(map(jnp.asarray, prepare_pair(left, right)))


@pytest.mark.parametrize("chunk", [5, 4, 11])
def test_chunked_winners_are_identical(pair, chunk):
    base = Params().replace(**{"selection.subpixel": False, "segments.n_segments": 24})
    whole = ssw_disparity(*pair, base, ndisp=NDISP, chunk=0)
    chunked = ssw_disparity(*pair, base, ndisp=NDISP, chunk=chunk)
    np.testing.assert_array_equal(np.asarray(whole), np.asarray(chunked))


@pytest.mark.parametrize("changes", [{}, {"aggregation.window_selection": "guide"},
                                     {"aggregation": "gf", "segments": None}])
def test_chunked_subpixel_matches_to_rounding(pair, changes):
    base = Params().replace(**{"segments.n_segments": 24}).replace(**changes)  # gf: no superpixels left
    whole = np.asarray(ssw_disparity(*pair, base, ndisp=NDISP, chunk=0))
    chunked = np.asarray(ssw_disparity(*pair, base, ndisp=NDISP, chunk=5))
    # Same winners; the parabola's inputs may differ in the last bit between XLA fusions.
    np.testing.assert_allclose(chunked, whole, rtol=0, atol=1e-4)
    if "aggregation" not in changes:  # GF's radius 9 is wider than the near layer
        assert np.median(whole[12:24, 26:40]) == pytest.approx(8, abs=0.01)


def test_chunked_under_vmap(pair):
    params = Params().replace(**{"segments.n_segments": 24})
    lefts = jnp.stack([pair[0], pair[0][:, ::-1]])
    rights = jnp.stack([pair[1], pair[1][:, ::-1]])
    batched = jax.vmap(lambda l, r: ssw_disparity(l, r, params, ndisp=NDISP, chunk=5))(lefts, rights)
    single = ssw_disparity(lefts[1], rights[1], params, ndisp=NDISP, chunk=5)
    np.testing.assert_allclose(np.asarray(batched[1]), np.asarray(single), atol=1e-5)


@pytest.mark.parametrize("chunk", [1, 5])
def test_optimized_volume_folds_in_chunks_like_the_whole_volume(chunk):
    # With an optimizer the volume is aggregated (in blocks), optimised whole, then folded in
    # blocks: the same winners and values as the unrolled fold of the whole volume.
    rng = np.random.default_rng(7)
    right = rng.random((30, 50, 3), dtype=np.float32)
    left = np.roll(right, 4, axis=1)
    params = sswjax.preset("accurate").replace(alignment=None)  # accurate has no superpixels
    whole = ssw_disparity(jnp.asarray(left), jnp.asarray(right), params, ndisp=11, chunk=0)
    blocks = ssw_disparity(jnp.asarray(left), jnp.asarray(right), params, ndisp=11, chunk=chunk)
    np.testing.assert_allclose(np.asarray(blocks), np.asarray(whole), atol=1e-4, rtol=0)
