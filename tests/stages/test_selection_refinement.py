"""Tests for sswjax.stages.selection and sswjax.stages.refinement against NumPy references and hand cases."""

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.refinement import fill_background, fill_invalid, left_right_consistency, right_cost_volume
from sswjax.stages.selection import fold_winners, no_winners, soft_argmin, subpixel_parabola, winner_takes_all

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


@pytest.mark.parametrize("block", [1, 3, 8])
def test_fold_winners_in_blocks_equals_argmin_of_both_views(block):
    """The running fold equals argmin over the whole volume for the left view (with the costs
    at d -/+ 1) and for the right view C_R(x, d) = C(x + d, d), ties to the smaller d,
    disparities at or beyond ``limit`` ignored, whatever the block size."""
    rng = np.random.default_rng(5)
    ndisp, limit = 8, 6
    cost = rng.integers(0, 4, size=(ndisp, 4, 9)).astype(np.float32)  # many ties
    state = _fold_in_blocks(cost, block, limit)
    inside = cost[:limit]
    left = np.argmin(inside, axis=0)
    np.testing.assert_array_equal(np.asarray(state.disparity), left)
    np.testing.assert_array_equal(np.asarray(state.cost), np.min(inside, axis=0))
    padded = np.concatenate([np.full((1, 4, 9), np.inf), inside, np.full((1, 4, 9), np.inf)])
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
