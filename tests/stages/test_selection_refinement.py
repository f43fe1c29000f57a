"""Tests for sswjax.stages.selection and sswjax.stages.checks and sswjax.stages.background against NumPy references and hand cases."""

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.reference import (left_right_consistency, right_cost_volume, subpixel_parabola,
                                     winner_takes_all)
from sswjax.stages.background import fill_background, fill_invalid
from sswjax.stages.checks import uniqueness_violations
from sswjax.stages.selection import equiangular_refine, fold_winners, no_winners, soft_argmin

# ---------------------------------------------------------------------------------------------
# selection


def test_winner_takes_all_smallest_d_on_ties():
    rng = np.random.default_rng(0)
    cost = rng.integers(0, 3, size=(6, 5, 7)).astype(np.float32)  # many ties
    ours = np.asarray(winner_takes_all(jnp.asarray(cost)))
    assert ours.dtype == np.int32
    reference = np.zeros((5, 7), int)
    for y in range(5):
        for x in range(7):
            best = min(cost[:, y, x])
            reference[y, x] = [d for d in range(6) if cost[d, y, x] == best][0]
    np.testing.assert_array_equal(ours, reference)
    # an all-equal column picks 0
    flat = np.ones((4, 1, 1), np.float32)
    assert int(winner_takes_all(jnp.asarray(flat))[0, 0]) == 0


def _fold_in_blocks(cost, block, limit):
    """Fold ``cost`` (D, H, W) block by block, each block with its two halo slices."""
    ndisp = cost.shape[0]
    padded = np.concatenate([np.full((1,) + cost.shape[1:], 7.0, np.float32), cost,
                             np.full((block + 1,) + cost.shape[1:], 7.0, np.float32)])
    state = no_winners(cost.shape[1:])
    for first in range(0, ndisp, block):
        state = fold_winners(state, jnp.asarray(padded[first : first + block + 2]), jnp.int32(first),
                             limit=limit)
    return state


@pytest.mark.parametrize("block, width", [(1, 9), (3, 9), (8, 9),
                                          # blocks past the image's width, wider than it
                                          (3, 4), (8, 4)])
def test_fold_winners_in_blocks_equals_argmin_of_both_views(block, width):
    """The running fold equals argmin over the whole volume for the left view (with the costs
    at d -/+ 1) and for the right view C_R(x, d) = C(x + d, d), ties to the smaller d,
    disparities at or beyond ``limit`` ignored, whatever the block size."""
    rng = np.random.default_rng(5)
    ndisp, limit = 8, 6
    cost = rng.integers(0, 4, size=(ndisp, 4, width)).astype(np.float32)  # many ties
    state = _fold_in_blocks(cost, block, limit)
    inside = cost[:limit]
    left = np.argmin(inside, axis=0)
    np.testing.assert_array_equal(np.asarray(state.disparity), left)
    np.testing.assert_array_equal(np.asarray(state.cost), np.min(inside, axis=0))
    padded = np.concatenate([np.full((1, 4, width), np.inf), inside,
                             np.full((1, 4, width), np.inf)])
    rows, cols = np.indices(left.shape)
    np.testing.assert_array_equal(np.asarray(state.before), padded[left, rows, cols])
    np.testing.assert_array_equal(np.asarray(state.after), padded[left + 2, rows, cols])
    right = np.asarray(right_cost_volume(jnp.asarray(inside)))
    np.testing.assert_array_equal(np.asarray(state.right_disparity), np.argmin(right, axis=0))
    np.testing.assert_array_equal(np.asarray(state.right_cost), np.min(right, axis=0))


def test_fold_winners_rejects_bad_slices():
    state = no_winners((2, 3))
    with pytest.raises(ValueError, match="at least 3 slices"):
        fold_winners(state, jnp.zeros((2, 2, 3)), 0, limit=4)
    with pytest.raises(ValueError, match="like the state"):
        fold_winners(state, jnp.zeros((3, 2, 4)), 0, limit=4)


def test_subpixel_parabola_exact_on_sampled_parabola():
    rng = np.random.default_rng(1)
    ndisp, h, w = 9, 4, 6
    t0 = rng.uniform(0.6, ndisp - 1.6, size=(h, w))  # true minimum, away from the ends
    t0[0, 0] = 3.0  # exactly on a sample
    t0[0, 1] = 4.5 - 1e-3  # near a half-way point
    a = rng.uniform(0.5, 3.0, size=(h, w))
    b = rng.uniform(-1.0, 1.0, size=(h, w))
    d = np.arange(ndisp)[:, None, None]
    cost = (a * (d - t0) ** 2 + b).astype(np.float32)
    winners = winner_takes_all(jnp.asarray(cost))
    np.testing.assert_array_equal(np.asarray(winners), np.rint(t0).astype(int))
    ours = np.asarray(subpixel_parabola(jnp.asarray(cost), winners))
    assert ours.dtype == np.float32
    np.testing.assert_allclose(ours, t0, atol=2e-4, rtol=0)


def test_subpixel_parabola_zero_offset_at_range_ends_and_flat_fits():
    d = np.arange(5.0)[:, None, None]
    # minimum beyond each end of the range: winners 0 and 4, offsets must be 0
    low = (d + 0.3) ** 2
    high = (d - 4.3) ** 2
    cost = np.concatenate([low, high], axis=2).astype(np.float32)  # (5, 1, 2)
    winners = winner_takes_all(jnp.asarray(cost))
    np.testing.assert_array_equal(np.asarray(winners), [[0, 4]])
    ours = np.asarray(subpixel_parabola(jnp.asarray(cost), winners))
    np.testing.assert_array_equal(ours, [[0.0, 4.0]])
    # flat (zero curvature) and concave fits around a given interior disparity: offset 0
    flat = np.array([1.0, 1.0, 1.0, 2.0, 3.0])[:, None, None]
    concave = np.array([0.0, 1.0, 0.5, 2.0, 3.0])[:, None, None]
    cost = np.concatenate([flat, concave], axis=2).astype(np.float32)
    given = jnp.asarray([[1, 1]], jnp.int32)
    np.testing.assert_array_equal(np.asarray(subpixel_parabola(jnp.asarray(cost), given)), [[1.0, 1.0]])
    # a parabola whose vertex is half-way: offset exactly +0.5 (3, 1, 1 -> 1.5)
    half = np.array([3.0, 1.0, 1.0, 3.0, 5.0])[:, None, None].astype(np.float32)
    ours = subpixel_parabola(jnp.asarray(half), winner_takes_all(jnp.asarray(half)))
    np.testing.assert_array_equal(np.asarray(ours), [[1.5]])


def test_subpixel_parabola_asymmetric_v():
    # V shape: c = [2, 0, 1] -> offset (2 - 1) / (2 * 3) = 1/6
    cost = np.array([2.0, 0.0, 1.0])[:, None, None].astype(np.float32)
    ours = subpixel_parabola(jnp.asarray(cost), winner_takes_all(jnp.asarray(cost)))
    np.testing.assert_allclose(np.asarray(ours), [[1 + 1 / 6]], atol=1e-6)


def test_equiangular_fit_exact_on_sampled_v_and_against_a_loop():
    rng = np.random.default_rng(3)
    ndisp, h, w = 9, 5, 6
    t0 = rng.uniform(0.6, ndisp - 1.6, size=(h, w))  # the V's vertex, away from the ends
    t0[0, 0] = 3.0  # on a sample
    slope = rng.uniform(0.5, 3.0, size=(h, w))
    d = np.arange(ndisp)[:, None, None]
    cost = (slope * np.abs(d - t0) + rng.uniform(-1, 1, size=(h, w))).astype(np.float32)
    winners = winner_takes_all(jnp.asarray(cost))

    def costs(cost, winners):
        """The costs at the winners' d - 1, d and d + 1 (clipped to the range)."""
        return [jnp.take_along_axis(jnp.asarray(cost), jnp.clip(
            winners + offset, 0, cost.shape[0] - 1)[None], axis=0)[0] for offset in (-1, 0, 1)]

    ours = np.asarray(equiangular_refine(winners, *costs(cost, winners), ndisp=ndisp))
    assert ours.dtype == np.float32
    np.testing.assert_allclose(ours, t0, atol=2e-4, rtol=0)
    # the parabola on the same V is pulled towards the integers
    parabola = np.asarray(subpixel_parabola(jnp.asarray(cost), winners))
    assert np.abs(parabola - t0).max() > 0.05

    # a loop reference on random costs, the range's ends and flat sides included
    cost = rng.integers(0, 4, size=(5, 4, 7)).astype(np.float32)
    winners = winner_takes_all(jnp.asarray(cost))
    ours = np.asarray(equiangular_refine(winners, *costs(cost, winners), ndisp=5))
    for y in range(4):
        for x in range(7):
            k = int(winners[y, x])
            c = cost[:, y, x]
            expected = float(k)
            if 0 < k < 4 and max(c[k - 1], c[k + 1]) > c[k]:
                offset = (c[k - 1] - c[k + 1]) / (2 * (max(c[k - 1], c[k + 1]) - c[k]))
                expected = k + min(max(offset, -0.5), 0.5)
            assert ours[y, x] == pytest.approx(expected, abs=1e-6), (y, x)


def test_soft_argmin_tends_to_wta():
    rng = np.random.default_rng(2)
    ndisp, h, w = 7, 4, 5
    cost = rng.random((ndisp, h, w)).astype(np.float32)
    # make the minimum unique with a margin of >= 0.05
    winners = rng.integers(0, ndisp, size=(h, w))
    cost = cost + 0.1
    np.put_along_axis(cost, winners[None], 0.0, axis=0)
    cold = np.asarray(soft_argmin(jnp.asarray(cost), temperature=1e-3))
    np.testing.assert_allclose(cold, winners, atol=1e-4)
    # it moves towards WTA as the temperature falls
    errors = [
        np.abs(np.asarray(soft_argmin(jnp.asarray(cost), temperature=t)) - winners).mean() for t in (1.0, 0.1, 0.01)
    ]
    assert errors[0] > errors[1] > errors[2]
    # very hot: the mean disparity
    hot = np.asarray(soft_argmin(jnp.asarray(cost), temperature=1e6))
    np.testing.assert_allclose(hot, (ndisp - 1) / 2, atol=1e-3)


# ---------------------------------------------------------------------------------------------
# right cost volume and left-right check


def test_right_cost_volume_matches_reference():
    rng = np.random.default_rng(3)
    ndisp, h, w = 5, 3, 8
    cost = rng.random((ndisp, h, w)).astype(np.float32)
    ours = np.asarray(right_cost_volume(jnp.asarray(cost)))
    reference = np.full_like(cost, np.inf)
    for d in range(ndisp):
        for y in range(h):
            for x in range(w):
                if x + d < w:
                    reference[d, y, x] = cost[d, y, x + d]
    np.testing.assert_array_equal(ours, reference)


def test_left_right_consistency_constructed_scene():
    # Background at disparity 2, a foreground object at disparity 5 on left columns 6..9.
    # In the right view the object sits on columns 1..4 and hides the background seen by
    # left columns 3..5 (occluded band); left columns 0, 1 look outside the right image.
    d_left = np.array([[2, 2, 2, 2, 2, 2, 5, 5, 5, 5, 2, 2, 2, 2]], np.float32)
    d_right = np.array([[2, 5, 5, 5, 5, 2, 2, 2, 2, 2, 2, 2, 2, 2]], np.float32)
    expected = np.array([[0, 0, 1, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1]], bool)
    ours = np.asarray(left_right_consistency(jnp.asarray(d_left), jnp.asarray(d_right), tolerance=0.0))
    np.testing.assert_array_equal(ours, expected)

    # a gross mismatch (column 12 says 4: its match says 2) and a sub-pixel disagreement
    # (column 11 says 2.4: rounds to 2, disagrees by 0.4)
    d_left[0, 12] = 4.0
    d_left[0, 11] = 2.4
    tol0 = np.asarray(left_right_consistency(jnp.asarray(d_left), jnp.asarray(d_right), tolerance=0.0))
    tol1 = np.asarray(left_right_consistency(jnp.asarray(d_left), jnp.asarray(d_right), tolerance=1.0))
    expected0 = expected.copy()
    expected0[0, 11] = expected0[0, 12] = False
    expected1 = expected.copy()
    expected1[0, 12] = False
    np.testing.assert_array_equal(tol0, expected0)
    np.testing.assert_array_equal(tol1, expected1)

    # int32 maps (WTA winners) are accepted as well
    as_int = np.asarray(
        left_right_consistency(
            jnp.asarray(d_left.round().astype(np.int32)), jnp.asarray(d_right.astype(np.int32)), tolerance=0
        )
    )
    expected_int = expected.copy()
    expected_int[0, 12] = False
    np.testing.assert_array_equal(as_int, expected_int)


def test_left_right_consistency_matches_reference_on_random_maps():
    rng = np.random.default_rng(4)
    h, w = 4, 12
    d_left = rng.integers(0, 6, size=(h, w)).astype(np.float32)
    d_right = np.where(rng.random((h, w)) < 0.5, d_left, rng.integers(0, 6, size=(h, w))).astype(np.float32)
    ours = np.asarray(left_right_consistency(jnp.asarray(d_left), jnp.asarray(d_right), tolerance=1.0))
    reference = np.zeros((h, w), bool)
    for y in range(h):
        for x in range(w):
            xr = x - int(d_left[y, x])
            reference[y, x] = xr >= 0 and abs(d_left[y, x] - d_right[y, xr]) <= 1.0
    np.testing.assert_array_equal(ours, reference)


# ---------------------------------------------------------------------------------------------
# filling


def fill_background_reference(disparity, valid, left_band=False):
    out = disparity.astype(np.float64).copy()
    h, w = disparity.shape
    for y in range(h):
        for x in range(w):
            if valid[y, x]:
                continue
            left = [disparity[y, i] for i in range(x - 1, -1, -1) if valid[y, i]][:1]
            right = [disparity[y, i] for i in range(x + 1, w) if valid[y, i]][:1]
            out[y, x] = min(left + right) if left + right else 0.0
            if left_band and right and x < right[0]:
                out[y, x] = right[0]  # the surface on the right has no match at column x
    return out


def test_fill_background_hand_cases():
    nan = np.nan  # invalid pixels may hold anything, even NaN
    d = np.array(
        [
            [9.0, 3.0, nan, 7.0, 1.0, 4.0],  # both sides: min(3, 1)
            [nan, nan, 6.0, 2.0, 8.0, 8.0],  # only a right side, then only a left side
            [5.0, 5.0, 5.0, 5.0, 5.0, 5.0],  # empty row (nothing valid)
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],  # everything valid
        ],
        np.float32,
    )
    v = np.array(
        [
            [1, 1, 0, 0, 1, 1],
            [0, 0, 1, 0, 1, 0],
            [0, 0, 0, 0, 0, 0],
            [1, 1, 1, 1, 1, 1],
        ],
        bool,
    )
    expected = np.array(
        [
            [9.0, 3.0, 1.0, 1.0, 1.0, 4.0],
            [6.0, 6.0, 6.0, 6.0, 8.0, 8.0],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
        ],
        np.float32,
    )
    ours = np.asarray(fill_background(jnp.asarray(d), jnp.asarray(v)))
    np.testing.assert_array_equal(ours, expected)


def test_fill_background_matches_reference_on_random_masks():
    rng = np.random.default_rng(5)
    d = rng.random((6, 15)).astype(np.float32) * 10
    v = rng.random((6, 15)) < 0.4
    v[2] = False
    ours = np.asarray(fill_background(jnp.asarray(d), jnp.asarray(v)))
    np.testing.assert_allclose(ours, fill_background_reference(d, v), rtol=0, atol=0)
    ours = np.asarray(fill_background(jnp.asarray(d), jnp.asarray(v), left_band=True))
    np.testing.assert_allclose(ours, fill_background_reference(d, v, left_band=True), rtol=0,
                               atol=0)


def test_left_band_fill_keeps_the_surface_that_has_no_match():
    # A spurious match of 0 at x = 0, then pixels failing the check, then a surface at d = 5
    # from x = 4: columns 1-3 are left of 5, where that surface has no match in the right view.
    d = jnp.array([[0.0, 0.0, 0.0, 0.0, 5.0, 5.0, 1.0, 0.0, 1.0]])
    v = jnp.array([[True, False, False, False, True, True, True, False, True]])
    assert fill_background(d, v).tolist() == [[0, 0, 0, 0, 5, 5, 1, 1, 1]]
    assert fill_background(d, v, left_band=True).tolist() == [[0, 5, 5, 5, 5, 5, 1, 1, 1]]


def band_fit_reference(d, v, width):
    """Loops: the left-band fill, then each row's pixels left of its first valid one on the
    least-squares line through the valid pixels of the next ``width`` columns, clipped at 0."""
    ours = fill_background_reference(d, v, left_band=True)
    for y in range(d.shape[0]):
        if not v[y].any():
            continue
        x0 = int(np.argmax(v[y]))
        xs = [x for x in range(x0, min(x0 + width, d.shape[1])) if v[y, x]]
        if 3 * len(xs) < width:
            continue
        if len(set(xs)) > 1:
            slope, intercept = np.polyfit(np.array(xs) - x0, d[y, xs].astype(np.float64), 1)
        else:
            slope, intercept = 0.0, float(d[y, xs[0]])
        for x in range(x0):
            ours[y, x] = max(intercept + slope * (x - x0), 0.0)
    return ours


def test_fill_background_band_fit_continues_a_slanted_surface():
    # A surface d = 6 + 0.5 x seen from x = 4 on: the band x < 4 continues it (8.0 at x = 4).
    x = np.arange(12, dtype=np.float32)
    d = (6 + 0.5 * x)[None].repeat(2, axis=0)
    v = np.ones(d.shape, bool)
    v[:, :4] = False
    v[1, 5:11] = False  # row 1: columns 4 .. 9 hold one valid pixel, less than a third of 6
    ours = np.asarray(fill_background(jnp.asarray(d), jnp.asarray(v), left_band=True,
                                      band_fit=6))
    np.testing.assert_allclose(ours[0], d[0], atol=1e-5)
    assert ours[1, :4].tolist() == [8.0] * 4  # the left-band rule's constant
    assert fill_background(jnp.asarray(d), jnp.asarray(v), left_band=True)[0, :4].tolist() == [8.0] * 4


def test_fill_background_band_fit_matches_reference_on_random_maps():
    rng = np.random.default_rng(8)
    d = (rng.random((10, 24)) * 12 + np.arange(24) * 0.3).astype(np.float32)
    v = rng.random(d.shape) < 0.6
    v[:, :3] = False
    v[4] = False  # no valid pixel
    for width in (1, 4, 9):
        ours = np.asarray(fill_background(jnp.asarray(d), jnp.asarray(v), left_band=True,
                                          band_fit=width))
        np.testing.assert_allclose(ours, band_fit_reference(d, v, width), atol=1e-4)


def test_fill_background_band_fit_reads_nothing_beyond_its_row():
    # Row 0's steep line goes on above every disparity of the map, and row 1's falls to 0:
    # no bound read from the map (which a window of strips or tiles would see otherwise).
    d = np.array([[0, 0, 0, 4, 3, 2, 1], [0, 0, 0, 1, 2, 3, 4]], np.float32)
    v = np.array([[0, 0, 0, 1, 1, 1, 1], [0, 0, 0, 1, 1, 1, 1]], bool)
    ours = np.asarray(fill_background(jnp.asarray(d), jnp.asarray(v), left_band=True,
                                      band_fit=4))
    np.testing.assert_allclose(ours[0, :3], [7.0, 6.0, 5.0], atol=1e-5)
    np.testing.assert_allclose(ours[1, :3], [0.0, 0.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(ours, band_fit_reference(d, v, 4), atol=1e-5)
    assert np.array_equal(ours[:1], np.asarray(fill_background(jnp.asarray(d[:1]),
                                                               jnp.asarray(v[:1]),
                                                               left_band=True, band_fit=4)))


def test_fill_background_band_fit_needs_the_left_band():
    with pytest.raises(ValueError, match="band_fit > 0 needs left_band=True"):
        fill_background(jnp.zeros((2, 3)), jnp.ones((2, 3), bool), band_fit=3)


@pytest.mark.parametrize("median", ["square", "separable"])
@pytest.mark.parametrize("radius", [0, 1, 2])
def test_fill_invalid(radius, median):
    rng = np.random.default_rng(6 + radius)
    d = (rng.random((8, 13)) * 10).astype(np.float32)
    v = rng.random((8, 13)) < 0.5
    v[3] = False  # a row with no valid pixel
    d[~v & (rng.random((8, 13)) < 0.3)] = np.nan  # garbage under invalid pixels
    ours = np.asarray(fill_invalid(jnp.asarray(d), jnp.asarray(v), radius=radius, median=median))
    assert ours.shape == d.shape and ours.dtype == np.float32
    assert np.isfinite(ours).all()
    np.testing.assert_array_equal(ours[v], d[v])  # valid pixels are untouched
    filled = fill_background_reference(d, v)
    if radius == 0:
        np.testing.assert_allclose(ours, filled, rtol=0, atol=0)
    else:
        # invalid pixels: median of the (2r+1)^2 window of the filled map, edge-replicated
        padded = np.pad(filled, radius, mode="edge")
        size = 2 * radius + 1
        for y, x in zip(*np.nonzero(~v)):
            window = padded[y : y + size, x : x + size]
            # separable: the median of the window's column medians
            expected = np.median(window) if median == "square" else np.median(np.median(window, axis=0))
            assert ours[y, x] == pytest.approx(expected, abs=1e-6), (y, x)


def test_fill_invalid_rejects_an_unknown_median():
    d = jnp.zeros((4, 4))
    with pytest.raises(ValueError, match="median must be one of"):
        fill_invalid(d, d > 0, radius=1, median="mean")


def uniqueness_reference(disparity, cost, gap):
    """Loops: per row and right pixel, the cheapest claim (ties: the largest disparity) beats
    every dearer claim whose disparity is at least ``gap`` away from it."""
    height, width = disparity.shape
    lose = np.zeros(disparity.shape, bool)
    for y in range(height):
        claims = {}
        for x in range(width):
            if x - disparity[y, x] >= 0:
                claims.setdefault(x - disparity[y, x], []).append(x)
        for xs in claims.values():
            best = min(cost[y, x] for x in xs)
            winner = max(disparity[y, x] for x in xs if cost[y, x] <= best)
            for x in xs:
                lose[y, x] = cost[y, x] > best and abs(winner - disparity[y, x]) >= gap
    return lose


@pytest.mark.parametrize("gap", [1, 2, 4])
def test_uniqueness_violations_matches_reference(gap):
    rng = np.random.default_rng(gap)
    disparity = rng.integers(0, 8, size=(6, 30))
    cost = rng.choice([0.1, 0.2, 0.3, 0.5], size=disparity.shape).astype(np.float32)  # ties too
    ours = np.asarray(uniqueness_violations(jnp.asarray(disparity, jnp.int32), jnp.asarray(cost),
                                            gap=gap))
    expected = uniqueness_reference(disparity, cost, gap)
    np.testing.assert_array_equal(ours, expected)
    assert expected.any() and not expected.all()


def test_uniqueness_violations_occlusion_scene():
    """A foreground (d = 4) fattened by two pixels over the occluded background (d = 1): the
    fattened pixels claim the right pixels of the visible background at a higher cost and
    lose; a slanted surface (neighbours' disparities at most one apart) never does."""
    d = np.array([[1, 1, 1, 1, 1, 1, 4, 4, 4, 4, 4, 4]])
    cost = np.array([[0., 0., 0., 0., 0., 0., .6, .6, 0., 0., 0., 0.]], np.float32)
    lose = np.asarray(uniqueness_violations(jnp.asarray(d, jnp.int32), jnp.asarray(cost), gap=2))
    assert lose.tolist() == [[False] * 6 + [True, True] + [False] * 4]
    slant = jnp.array([[0, 0, 1, 1, 2, 2, 3, 3, 4]], jnp.int32)
    assert not uniqueness_violations(slant, jnp.linspace(0, 1, 9)[None], gap=2).any()


def test_uniqueness_violations_rejects_bad_gap():
    with pytest.raises(ValueError, match="gap must be an integer >= 1"):
        uniqueness_violations(jnp.zeros((2, 3), jnp.int32), jnp.zeros((2, 3)), gap=0)
