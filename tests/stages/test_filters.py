"""Tests for sswjax.stages.filters and sswjax.stages.medians against brute-force NumPy references (tiny arrays, plain loops)."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.filters import (select_side_window_mean, side_window_box_filter,
                                  side_window_index, side_window_means)
from sswjax.stages.medians import (median_filter, median_of_stack, separable_median_filter,
                                  side_window_median_filter)

# ---------------------------------------------------------------------------------------------
# NumPy references. A window is (rows, cols) relative to the centre, inclusive ranges.


def window_extents(r):
    """The eight side windows in the order L R U D NW NE SW SE as ((y0, y1), (x0, x1))."""
    up, down, full = (-r, 0), (0, r), (-r, r)
    left, right = (-r, 0), (0, r)
    return [
        (full, left),  # L: (2r+1) x (r+1), centre on the right edge
        (full, right),  # R
        (up, full),  # U: (r+1) x (2r+1), centre on the bottom edge
        (down, full),  # D
        (up, left),  # NW: (r+1) x (r+1)
        (up, right),  # NE
        (down, left),  # SW
        (down, right),  # SE
    ]


def edge_pad(image, r):
    """Edge-replicated padding by r on both sides of a 2-D image (float64)."""
    return np.pad(np.asarray(image, np.float64), r, mode="edge")


def window_values(padded, r, y, x, extent):
    """Values in one window around (y, x) of an image padded by r (edge replication)."""
    (y0, y1), (x0, x1) = extent
    return padded[y + r + y0 : y + r + y1 + 1, x + r + x0 : x + r + x1 + 1].ravel()


def side_window_means_reference(x, r):
    """(8, ..., H, W) means, pixel by pixel."""
    x = np.asarray(x, np.float64)
    out = np.zeros((8,) + x.shape)
    for lead in np.ndindex(*x.shape[:-2]):
        padded = edge_pad(x[lead], r)
        for k, extent in enumerate(window_extents(r)):
            for y in range(x.shape[-2]):
                for xx in range(x.shape[-1]):
                    out[(k, *lead, y, xx)] = window_values(padded, r, y, xx, extent).mean()
    return out


def index_reference(guide, r):
    g = guide if guide.ndim == 3 else guide[None]
    means = side_window_means_reference(g, r)  # (8, C, H, W)
    distance = np.abs(means - np.asarray(g, np.float64)[None]).sum(axis=1)  # (8, H, W)
    return distance.argmin(axis=0)  # first index on ties


def select_reference(means, index):
    """means (8, ..., H, W), index (H, W) -> (..., H, W)."""
    return np.take_along_axis(means, np.broadcast_to(index, means.shape[1:])[None], axis=0)[0]


def closest_mean_reference(x, r):
    means = side_window_means_reference(x, r)
    k = np.abs(means - np.asarray(x, np.float64)[None]).argmin(axis=0)
    return np.take_along_axis(means, k[None], axis=0)[0]


def lower_median(values, axis=0):
    s = np.sort(values, axis=axis)
    n = s.shape[axis]
    return np.take(s, (n - 1) // 2, axis=axis)


def median_filter_reference(x, r):
    x = np.asarray(x, np.float64)
    out = np.zeros_like(x)
    full = ((-r, r), (-r, r))
    for lead in np.ndindex(*x.shape[:-2]):
        padded = edge_pad(x[lead], r)
        for y in range(x.shape[-2]):
            for xx in range(x.shape[-1]):
                out[(*lead, y, xx)] = lower_median(window_values(padded, r, y, xx, full))
    return out


def side_window_median_reference(x, r, iterations):
    x = np.asarray(x, np.float64)
    for _ in range(iterations):
        out = np.zeros_like(x)
        for lead in np.ndindex(*x.shape[:-2]):
            image = x[lead]
            padded = edge_pad(image, r)
            for y in range(image.shape[0]):
                for xx in range(image.shape[1]):
                    medians = [
                        lower_median(window_values(padded, r, y, xx, extent)) for extent in window_extents(r)
                    ]
                    distances = [abs(m - image[y, xx]) for m in medians]
                    out[(*lead, y, xx)] = medians[int(np.argmin(distances))]  # first on ties
        x = out
    return x


def jitted(fn, *arrays, **static):
    """Run ``fn`` under ``jax.jit`` (static keyword arguments); one compile beats many eager ops."""
    return np.asarray(jax.jit(functools.partial(fn, **static))(*(jnp.asarray(a) for a in arrays)))


@pytest.fixture
def rng():
    return np.random.default_rng(123)


# ---------------------------------------------------------------------------------------------
# side-window means


@pytest.mark.parametrize("method", ["slices", "cumsum", "reduce_window"])
@pytest.mark.parametrize("radius", [1, 2, 3])
def test_side_window_means_2d(radius, method):
    x = np.random.default_rng(radius).random((9, 11)).astype(np.float32)
    ours = jitted(side_window_means, x, radius=radius, method=method)
    assert ours.shape == (8, 9, 11)
    np.testing.assert_allclose(ours, side_window_means_reference(x, radius), atol=1e-5, rtol=0)


@pytest.mark.parametrize("method", ["slices", "cumsum", "reduce_window"])
@pytest.mark.parametrize("radius", [1, 2, 3])
def test_side_window_means_batched(radius, method):
    x = np.random.default_rng(10 + radius).random((2, 9, 11)).astype(np.float32)
    ours = jitted(side_window_means, x, radius=radius, method=method)
    assert ours.shape == (8, 2, 9, 11)
    np.testing.assert_allclose(ours, side_window_means_reference(x, radius), atol=1e-5, rtol=0)


def test_side_window_means_radius_larger_than_image():
    # radius beyond the image: everything comes from the edge replication
    x = np.random.default_rng(5).random((3, 4)).astype(np.float32)
    for method in ("slices", "cumsum", "reduce_window"):
        ours = jitted(side_window_means, x, radius=5, method=method)
        np.testing.assert_allclose(ours, side_window_means_reference(x, 5), atol=1e-5, rtol=0)


def test_side_window_means_rejects_bad_method():
    with pytest.raises(ValueError, match="method"):
        side_window_means(jnp.zeros((4, 4)), radius=1, method="fft")


# ---------------------------------------------------------------------------------------------
# window selection


@pytest.mark.parametrize("method", ["slices", "cumsum", "reduce_window"])
@pytest.mark.parametrize("channels", [None, 1, 3])
def test_side_window_index(channels, method, rng):
    shape = (9, 11) if channels is None else (channels, 9, 11)
    guide = rng.random(shape).astype(np.float32)
    channels_last = guide if channels is None else np.moveaxis(guide, 0, -1)  # (H, W, C) layout
    ours = jitted(side_window_index, channels_last, radius=2, method=method)
    assert ours.dtype == np.int32
    np.testing.assert_array_equal(ours, index_reference(guide, 2))
    # most of the eight windows occur on random data (the test is not vacuous)
    assert len(np.unique(ours)) >= 6


@pytest.mark.parametrize("method", ["slices", "cumsum", "reduce_window"])
def test_side_window_index_first_window_on_ties(method, rng):
    # a flat guide: all eight windows are equally close, the first (L) wins (zeros: every
    # window mean is exactly 0 whatever the rounding of 1 / count, so the distances tie)
    flat = np.zeros((9, 11, 2), np.float32)
    np.testing.assert_array_equal(jitted(side_window_index, flat, radius=2, method=method), 0)
    x = rng.random((9, 11)).astype(np.float32)
    guided = jitted(
        lambda x, g: side_window_box_filter(x, radius=2, iterations=1, guide=g, method=method), x, flat
    )
    np.testing.assert_allclose(guided, side_window_means_reference(x, 2)[0], atol=1e-5, rtol=0)


@pytest.mark.parametrize("method", ["slices", "cumsum", "reduce_window"])
def test_select_side_window_mean(method, rng):
    guide = rng.random((3, 9, 11)).astype(np.float32)
    x = rng.random((4, 9, 11)).astype(np.float32)
    index = index_reference(guide, 2).astype(np.int32)
    ours = jitted(select_side_window_mean, x, index, radius=2, method=method)
    reference = select_reference(side_window_means_reference(x, 2), index)
    np.testing.assert_allclose(ours, reference, atol=1e-5, rtol=0)


# ---------------------------------------------------------------------------------------------
# side-window box filter


@pytest.mark.parametrize("method", ["slices", "cumsum", "reduce_window"])
def test_side_window_box_filter_per_slice(method, rng):
    x = rng.random((2, 9, 11)).astype(np.float32)
    ours = jitted(side_window_box_filter, x, radius=2, iterations=3, method=method)
    reference = x.astype(np.float64)
    for _ in range(3):
        reference = closest_mean_reference(reference, 2)
    np.testing.assert_allclose(ours, reference, atol=1e-5, rtol=0)


@pytest.mark.parametrize("method", ["slices", "cumsum", "reduce_window"])
@pytest.mark.parametrize("guide_channels", [None, 3])
def test_side_window_box_filter_guided(guide_channels, method, rng):
    shape = (9, 11) if guide_channels is None else (guide_channels, 9, 11)
    guide = rng.random(shape).astype(np.float32)
    x = rng.random((3, 9, 11)).astype(np.float32)
    channels_last = guide if guide_channels is None else np.moveaxis(guide, 0, -1)
    ours = jitted(
        lambda x, guide: side_window_box_filter(x, radius=1, iterations=2, guide=guide, method=method),
        x, channels_last,
    )
    ref_x, ref_guide = x.astype(np.float64), guide.astype(np.float64)
    for _ in range(2):
        index = index_reference(ref_guide, 1)
        ref_x = select_reference(side_window_means_reference(ref_x, 1), index)
        ref_guide = select_reference(side_window_means_reference(ref_guide, 1), index)
    np.testing.assert_allclose(ours, ref_x, atol=1e-5, rtol=0)
    # the guide evolves: not the same as two passes with windows chosen on the initial guide
    fixed = x.astype(np.float64)
    index = index_reference(guide.astype(np.float64), 1)
    for _ in range(2):
        fixed = select_reference(side_window_means_reference(fixed, 1), index)
    assert np.abs(fixed - ref_x).max() > 1e-3


def test_side_window_box_filter_zero_iterations_is_identity(rng):
    x = rng.random((9, 11)).astype(np.float32)
    np.testing.assert_array_equal(np.asarray(side_window_box_filter(jnp.asarray(x), radius=2, iterations=0)), x)


@pytest.mark.parametrize("method", ["slices", "cumsum", "reduce_window"])
def test_side_window_box_filter_preserves_step_edges(method):
    vertical = np.zeros((9, 11), np.float32)
    vertical[:, 5:] = 1.0
    horizontal = np.zeros((9, 11), np.float32)
    horizontal[4:, :] = 1.0
    corner = np.zeros((9, 11), np.float32)
    corner[4:, 6:] = 1.0  # a convex corner: kept by the quadrant windows
    plain = jax.jit(lambda x: side_window_box_filter(x, radius=2, iterations=3, method=method))
    guided = jax.jit(lambda x: side_window_box_filter(x[None], radius=2, iterations=2, guide=x, method=method)[0])
    for step in (vertical, horizontal, corner):
        np.testing.assert_array_equal(np.asarray(plain(jnp.asarray(step))), step)
        np.testing.assert_array_equal(np.asarray(guided(jnp.asarray(step))), step)
    # and eagerly (no jit) too
    np.testing.assert_array_equal(
        np.asarray(side_window_box_filter(jnp.asarray(corner), radius=1, iterations=1, method=method)), corner
    )


def test_side_window_box_filter_rejects_guide_of_other_size():
    with pytest.raises(ValueError):
        side_window_box_filter(jnp.zeros((2, 6, 6)), radius=1, guide=jnp.zeros((6, 7)))


# ---------------------------------------------------------------------------------------------
# medians


@pytest.mark.parametrize("n", range(1, 27))
def test_median_of_stack_is_lower_median(n):
    rng = np.random.default_rng(1000 + n)
    # small integer values: many duplicates; plus a few distinct floats
    values = rng.integers(0, 4, size=(n, 6, 7)).astype(np.float32)
    values[:, 0, :] = rng.random((n, 7))
    values[:, 1, 0] = -np.arange(n)  # sorted descending
    values[:, 1, 1] = np.arange(n)  # sorted ascending
    ours = np.asarray(median_of_stack([jnp.asarray(v) for v in values]))
    reference = lower_median(values)
    np.testing.assert_array_equal(ours, reference)
    if n % 2 == 1:
        np.testing.assert_array_equal(ours, np.median(values, axis=0))


def test_median_of_stack_all_permutations_of_5():
    # exhaustive over orderings of distinct values and of a multiset with duplicates
    import itertools

    for base in ([0.0, 1.0, 2.0, 3.0, 4.0], [1.0, 1.0, 2.0, 2.0, 3.0]):
        perms = np.array(list(itertools.permutations(base)), np.float32).T  # (5, 120)
        ours = np.asarray(median_of_stack([jnp.asarray(p) for p in perms]))
        np.testing.assert_array_equal(ours, np.median(perms, axis=0))


def test_median_of_stack_rejects_empty():
    with pytest.raises(ValueError):
        median_of_stack([])


@pytest.mark.parametrize("radius", [1, 2])
def test_median_filter(radius, rng):
    x = rng.integers(0, 5, size=(2, 9, 11)).astype(np.float32)
    x[1] = rng.random((9, 11))
    ours = np.asarray(median_filter(jnp.asarray(x), radius=radius))
    np.testing.assert_array_equal(ours, median_filter_reference(x, radius).astype(np.float32))


def separable_median_reference(x, r):
    """Median over each row window of the medians over each column window, edge-replicated."""
    x = np.asarray(x, np.float64)
    out = np.zeros_like(x)
    for lead in np.ndindex(*x.shape[:-2]):
        padded = edge_pad(x[lead], r)
        height, width = x.shape[-2:]
        columns = np.array([[np.median(padded[y:y + 2 * r + 1, xx]) for xx in range(width + 2 * r)]
                            for y in range(height)])
        out[lead] = [[np.median(columns[y, xx:xx + 2 * r + 1]) for xx in range(width)]
                     for y in range(height)]
    return out


@pytest.mark.parametrize("radius", [1, 2, 4])
def test_separable_median_filter(radius, rng):
    x = rng.integers(0, 5, size=(2, 9, 11)).astype(np.float32)
    x[1] = rng.random((9, 11))
    ours = jitted(separable_median_filter, x, radius=radius)
    np.testing.assert_array_equal(ours, separable_median_reference(x, radius).astype(np.float32))


def test_separable_median_differs_from_the_square_one(rng):
    # Not the same filter: the median of column medians is not the window's median in general.
    x = rng.random((12, 12)).astype(np.float32)
    assert not np.array_equal(jitted(separable_median_filter, x, radius=2),
                              jitted(median_filter, x, radius=2))


@pytest.mark.parametrize("iterations", [1, 2])
@pytest.mark.parametrize("radius", [1, 2])
def test_side_window_median_filter(radius, iterations, rng):
    x = rng.integers(0, 6, size=(9, 11)).astype(np.float32)  # duplicates: ties in distance
    y = rng.random((9, 11)).astype(np.float32)
    for image in (x, y):
        ours = np.asarray(side_window_median_filter(jnp.asarray(image), radius=radius, iterations=iterations))
        reference = side_window_median_reference(image, radius, iterations).astype(np.float32)
        np.testing.assert_array_equal(ours, reference)


def test_side_window_median_filter_batched(rng):
    x = rng.integers(0, 6, size=(2, 9, 11)).astype(np.float32)
    ours = np.asarray(side_window_median_filter(jnp.asarray(x), radius=1))
    np.testing.assert_array_equal(ours, side_window_median_reference(x, 1, 1).astype(np.float32))
