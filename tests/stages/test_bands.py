"""Tests for sswjax.stages.bands against plain loops over pixels and disparities (the band
recursion of the semi-global paths is tested in test_sgm.py, beside its reference)."""

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.bands import (align_band, band_cost, band_right_view, band_starts,
                                 band_winners)
from sswjax.stages.cost import matching_features
from sswjax.stages.reference import cost_volume

TERMS = dict(tad_weight=0.2, gradient_weight=0.3, census_weight=0.5, tad_truncation=0.1,
             gradient_truncation=0.05)


def test_band_starts_centre_and_clip():
    estimate = np.array([[0.0, 2.4, 2.6, 7.5, 9.0, 30.0]], np.float32)
    ours = np.asarray(band_starts(jnp.asarray(estimate), width=5, limit=10))
    reference = [min(max(int(np.round(e)) - 2, 0), 10 - 5) for e in estimate[0]]
    assert ours.tolist() == [reference]
    assert np.asarray(band_starts(jnp.asarray(estimate), width=12, limit=10)).max() == 0


def test_band_starts_around_the_spread_by_loops():
    rng = np.random.default_rng(4)
    estimate = (rng.random((7, 9)) * 12).astype(np.float32)
    estimate[:, 5:] += 20.0  # an edge wider than any band here
    width, limit, r = 7, 40, 1
    ours = np.asarray(band_starts(jnp.asarray(estimate), width=width, limit=limit,
                                  spread_radius=r))
    rounded = np.round(estimate).astype(int)
    for y in range(7):
        for x in range(9):
            window = [rounded[min(max(y + dy, 0), 6), min(max(x + dx, 0), 8)]
                      for dy in range(-r, r + 1) for dx in range(-r, r + 1)]
            low, high = min(window), max(window)
            if high - low < width:
                start = low - (width - 1 - (high - low)) // 2
                assert start <= low and high <= start + width - 1  # the band holds the range
            else:
                start = rounded[y, x] - (width - 1) // 2
            assert ours[y, x] == min(max(start, 0), limit - width)


def test_band_starts_over_the_superpixel_by_loops():
    rng = np.random.default_rng(5)
    estimate = (rng.random((8, 10)) * 6).astype(np.float32)
    estimate[:, 6:] += 25.0
    labels = np.repeat(np.arange(5)[None], 8, 0).repeat(2, 1)  # 2-column segments
    labels[5:, :] += 5                                          # and a lower row of them
    estimate[5:, 2:4] = np.array([0.0, 30.0])                   # one segment too wide to fit
    width, limit, r = 7, 40, 1
    ours = np.asarray(band_starts(jnp.asarray(estimate), width=width, limit=limit,
                                  spread_radius=r, labels=jnp.asarray(labels),
                                  num_segments=10))
    rounded = np.round(estimate).astype(int)
    for y in range(8):
        for x in range(10):
            inside = rounded[labels == labels[y, x]]
            window = [rounded[min(max(y + dy, 0), 7), min(max(x + dx, 0), 9)]
                      for dy in range(-r, r + 1) for dx in range(-r, r + 1)]
            start = rounded[y, x] - (width - 1) // 2
            for low, high in ((min(window), max(window)), (inside.min(), inside.max())):
                if high - low < width:  # the segment's range, where it fits, decides
                    start = low - (width - 1 - (high - low)) // 2
            assert ours[y, x] == min(max(start, 0), limit - width)


def test_band_cost_is_the_volume_read_at_the_band():
    rng = np.random.default_rng(0)
    left = rng.random((6, 20, 3)).astype(np.float32)
    right = np.roll(left, -3, axis=1)
    starts = rng.integers(0, 8, size=(6, 20)).astype(np.int32)
    features = matching_features(jnp.asarray(left), jnp.asarray(right))
    ours = np.asarray(band_cost(features, jnp.asarray(starts), width=4, **TERMS))
    volume = np.asarray(cost_volume(jnp.asarray(left), jnp.asarray(right), ndisp=12, **TERMS))
    for k in range(4):
        for y in range(6):
            for x in range(20):
                assert ours[k, y, x] == pytest.approx(volume[starts[y, x] + k, y, x], abs=1e-6)


def test_align_band_by_loops():
    rng = np.random.default_rng(1)
    previous = rng.random((5, 9)).astype(np.float32)
    delta = rng.integers(-6, 7, size=9).astype(np.int32)
    fill = np.full(9, -1.0, np.float32)
    ours = np.asarray(align_band(jnp.asarray(previous), jnp.asarray(delta), jnp.asarray(fill)))
    for j in range(7):
        for n in range(9):
            k = j - 1 + delta[n]
            assert ours[j, n] == (previous[k, n] if 0 <= k < 5 else -1.0)


def test_band_winners_and_right_view_by_loops():
    rng = np.random.default_rng(2)
    width_k, height, width = 4, 3, 12
    cost = rng.integers(0, 5, size=(width_k, height, width)).astype(np.float32)  # ties
    starts = rng.integers(0, 5, size=(height, width)).astype(np.int32)
    winners = band_winners(jnp.asarray(cost), jnp.asarray(starts))
    for y in range(height):
        for x in range(width):
            k = int(np.argmin(cost[:, y, x]))
            assert int(winners.disparity[y, x]) == starts[y, x] + k
            # On the band's edge the missing neighbour is the winner's own cost.
            assert float(winners.before[y, x]) == cost[k - 1 if k > 0 else k, y, x]
            assert float(winners.after[y, x]) == cost[k + 1 if k < width_k - 1 else k, y, x]
    # The right view: the cheapest left pixel whose band reaches each right pixel.
    for y in range(height):
        for xr in range(width):
            claims = []
            for x in range(xr, width):
                k = x - xr - starts[y, x]
                if 0 <= k < width_k:
                    claims.append((cost[k, y, x], x - xr))
            expected = min(claims)[1] if claims else np.iinfo(np.int32).max
            assert int(winners.right_disparity[y, xr]) == expected
    disparity, cost_right = band_right_view(jnp.asarray(cost), jnp.asarray(starts))
    assert np.array_equal(disparity, winners.right_disparity)
    assert np.isinf(np.asarray(cost_right)[np.asarray(disparity) == np.iinfo(np.int32).max]).all()
    # Integer volumes take the packed scatter: the same winners, costs as stored.
    for dtype in (np.uint8, np.int16):
        packed, packed_cost = band_right_view(jnp.asarray(cost.astype(dtype)), jnp.asarray(starts))
        assert np.array_equal(packed, disparity)
        reached = np.asarray(disparity) != np.iinfo(np.int32).max
        assert np.array_equal(np.asarray(packed_cost)[reached], np.asarray(cost_right)[reached])
