"""Tests for sswjax.stages.baselines and sswjax.stages.guided against NumPy references (float64, tiny arrays, plain loops)."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.baselines import bilateral_filter, box_filter, median_cost_filter
from sswjax.stages.guided import guided_filter, iterated_guided_filter

# ---------------------------------------------------------------------------------------------
# NumPy references. Leading axes of a map are a batch; windows are (2r+1) x (2r+1), edge padding.


def edge_pad(image, r):
    """Edge-replicated padding by r on both sides of a 2-D image (float64)."""
    return np.pad(np.asarray(image, np.float64), r, mode="edge")


def windows(image, r):
    """Yield (y, x, window) over a 2-D image, window (2r+1, 2r+1) from the edge-padded image."""
    padded = edge_pad(image, r)
    for y in range(image.shape[0]):
        for x in range(image.shape[1]):
            yield y, x, padded[y : y + 2 * r + 1, x : x + 2 * r + 1]


def box_reference(x, r):
    x = np.asarray(x, np.float64)
    out = np.zeros(x.shape)
    for lead in np.ndindex(*x.shape[:-2]):
        for y, xx, window in windows(x[lead], r):
            out[(*lead, y, xx)] = window.mean()
    return out


def median_reference(x, r):
    x = np.asarray(x, np.float64)
    out = np.zeros(x.shape)
    for lead in np.ndindex(*x.shape[:-2]):
        for y, xx, window in windows(x[lead], r):
            out[(*lead, y, xx)] = np.median(window)
    return out


def guided_reference(p, guide, r, eps):
    """He, Sun & Tang 2013, Algorithm 1 (gray) and Eq. 19-21 (colour), float64, brute-force means.

    ``p`` is (H, W), ``guide`` (H, W, C) with C in {1, 3}; per-pixel inverse by np.linalg.inv.
    """
    p = np.asarray(p, np.float64)
    guide = np.asarray(guide, np.float64)
    channels = guide.shape[-1]
    mean = functools.partial(box_reference, r=r)
    mean_i = np.stack([mean(guide[..., c]) for c in range(channels)], -1)  # (H, W, C)
    mean_p = mean(p)
    cov_ip = np.stack([mean(guide[..., c] * p) for c in range(channels)], -1) - mean_i * mean_p[
        ..., None
    ]
    sigma = np.empty(p.shape + (channels, channels))
    for i in range(channels):
        for j in range(channels):
            sigma[..., i, j] = mean(guide[..., i] * guide[..., j]) - mean_i[..., i] * mean_i[..., j]
    a = np.empty(p.shape + (channels,))
    for y, x in np.ndindex(*p.shape):
        a[y, x] = np.linalg.inv(sigma[y, x] + eps * np.eye(channels)) @ cov_ip[y, x]
    b = mean_p - (a * mean_i).sum(-1)
    mean_a = np.stack([mean(a[..., c]) for c in range(channels)], -1)
    return (mean_a * guide).sum(-1) + mean(b)


def bilateral_reference(x, guide, r, sigma_space, sigma_color):
    """Yoon & Kweon weights from the edge-padded guide; normalised weighted mean, per pixel."""
    x = np.asarray(x, np.float64)
    guide = np.asarray(guide, np.float64)
    if guide.ndim == 2:
        guide = guide[..., None]
    g_padded = np.pad(guide, [(r, r), (r, r), (0, 0)], mode="edge")
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
    out = np.zeros(x.shape)
    height, width = x.shape[-2:]
    for y in range(height):
        for xx in range(width):
            neighbours = g_padded[y : y + 2 * r + 1, xx : xx + 2 * r + 1]
            colour = ((neighbours - guide[y, xx]) ** 2).sum(-1)
            w = np.exp(-(dy**2 + dx**2) / (2 * sigma_space**2) - colour / (2 * sigma_color**2))
            for lead in np.ndindex(*x.shape[:-2]):
                window = edge_pad(x[lead], r)[y : y + 2 * r + 1, xx : xx + 2 * r + 1]
                out[(*lead, y, xx)] = (w * window).sum() / w.sum()
    return out


def gaussian_box_reference(x, r, sigma_space):
    """Normalised Gaussian-weighted window mean (the bilateral filter without its range term)."""
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
    kernel = np.exp(-(dy**2 + dx**2) / (2 * sigma_space**2))
    kernel /= kernel.sum()
    x = np.asarray(x, np.float64)
    out = np.zeros(x.shape)
    for lead in np.ndindex(*x.shape[:-2]):
        for y, xx, window in windows(x[lead], r):
            out[(*lead, y, xx)] = (kernel * window).sum()
    return out


def random(shape, seed):
    return np.random.default_rng(seed).random(shape).astype(np.float32)


def jitted(fn, **static):
    """fn with keyword options bound, under jax.jit (one compile per test shape)."""
    return jax.jit(functools.partial(fn, **static))


# ---------------------------------------------------------------------------------------------
# Box filter.


@pytest.mark.parametrize(("shape", "r"), [((2, 7, 9), 1), ((2, 7, 9), 2), ((5, 6), 4)])
def test_box_filter_matches_brute_force(shape, r):
    x = random(shape, 0)
    out = jitted(box_filter, radius=r)(x)
    assert out.dtype == jnp.float32 and out.shape == shape
    np.testing.assert_allclose(out, box_reference(x, r), atol=1e-5)


# ---------------------------------------------------------------------------------------------
# Guided filter.


@pytest.mark.parametrize("channels", [1, 3])
def test_guided_filter_matches_he_et_al_reference(channels):
    cost = random((2, 12, 15), 1)
    guide = random((12, 15, channels), 2)
    out = jitted(guided_filter, radius=2, eps=1e-3)(cost, guide)
    assert out.dtype == jnp.float32 and out.shape == cost.shape
    for d in range(cost.shape[0]):
        np.testing.assert_allclose(out[d], guided_reference(cost[d], guide, 2, 1e-3), atol=1e-4)


def test_guided_filter_ill_conditioned_colour_edge():
    """A hard edge between two saturated colours: Sigma + eps U is nearly singular (cond ~ 1e4).

    Plain float32 adjugate/determinant is off by ~5e-3 here; the opponent basis, centring and
    Newton-Schulz step bring it to ~2e-5.
    """
    guide = np.empty((10, 12, 3), np.float32)
    guide[:, :6] = (0.9, 0.2, 0.1)
    guide[:, 6:] = (0.1, 0.6, 0.9)
    cost = np.zeros((1, 10, 12), np.float32)
    cost[:, :, 6:] = 1.0
    cost[:, 3, 2] = 0.5
    out = jitted(guided_filter, radius=2, eps=1e-4)(cost, guide)
    np.testing.assert_allclose(out[0], guided_reference(cost[0], guide, 2, 1e-4), atol=1e-4)


def test_guided_filter_gray_guide_rank_two_equals_one_channel():
    cost, guide = random((2, 8, 9), 3), random((8, 9), 4)
    gf = jitted(guided_filter, radius=2, eps=1e-3)
    np.testing.assert_allclose(gf(cost, guide), gf(cost, guide[..., None]), atol=1e-6)


@pytest.mark.parametrize("channels", [1, 3])
def test_guided_filter_with_constant_guide_is_a_box_filter(channels):
    """Constant guide: var = 0, so a = 0 and b = mean(p); q = mean(b), the box filter applied twice.

    (So "GF = box filter" holds for the box-of-box, a box filter with a pyramid kernel.)
    """
    cost = random((2, 9, 11), 5)
    guide = np.full((9, 11, channels), 0.4, np.float32)
    out = jitted(guided_filter, radius=2, eps=1e-3)(cost, guide)
    twice = box_reference(box_reference(cost, 2), 2)
    np.testing.assert_allclose(out, twice, atol=1e-5)


def test_guided_filter_keeps_a_step_edge_sharper_than_box():
    guide = np.zeros((8, 12, 3), np.float32)
    guide[:, 6:] = 0.8
    step = np.zeros((2, 8, 12), np.float32)
    step[:, :, 6:] = 1.0
    gf = np.asarray(jitted(guided_filter, radius=3, eps=1e-3)(step, guide))
    box = np.asarray(jitted(box_filter, radius=3)(step))
    gf_error, box_error = np.abs(gf - step).max(), np.abs(box - step).max()
    assert gf_error < 0.01 < 0.4 < box_error
    # The jump between the two columns at the edge stays (almost) the full step.
    assert gf[0, 4, 6] - gf[0, 4, 5] > 0.98 > 0.2 > box[0, 4, 6] - box[0, 4, 5]


def test_guided_filter_traced_eps_under_jit():
    cost, guide = random((2, 8, 9), 6), random((8, 9, 3), 7)
    fn = jax.jit(guided_filter, static_argnames="radius")
    traced = fn(cost, guide, radius=2, eps=jnp.float32(1e-3))
    static = jitted(guided_filter, radius=2, eps=1e-3)(cost, guide)
    np.testing.assert_allclose(traced, static, atol=1e-6)


# ---------------------------------------------------------------------------------------------
# Iterated guided filter.


def test_iterated_guided_filter_one_iteration_is_guided_filter():
    cost, guide = random((3, 10, 12), 8), random((10, 12, 3), 9)
    once = jitted(iterated_guided_filter, radius=2, eps=1e-3, iterations=1)(cost, guide)
    gf = jitted(guided_filter, radius=2, eps=1e-3)
    np.testing.assert_allclose(once, gf(cost, guide), atol=1e-6)
    twice = jitted(iterated_guided_filter, radius=2, eps=1e-3, iterations=2)(cost, guide)
    np.testing.assert_allclose(twice, gf(gf(cost, guide), guide), atol=1e-5)


# ---------------------------------------------------------------------------------------------
# Bilateral filter.


@pytest.mark.parametrize("channels", [1, 3])
def test_bilateral_filter_matches_brute_force(channels):
    cost = random((2, 6, 7), 10)
    guide = random((6, 7, channels), 11)
    options = dict(radius=2, sigma_space=1.5, sigma_color=0.2)
    out = jitted(bilateral_filter, **options)(cost, guide)
    assert out.dtype == jnp.float32 and out.shape == cost.shape
    reference = bilateral_reference(cost, guide, 2, 1.5, 0.2)
    np.testing.assert_allclose(out, reference, atol=1e-5)


def test_bilateral_filter_defaults_match_brute_force():
    cost, guide = random((1, 10, 11), 12), random((10, 11, 3), 13) * 0.1  # colours within ~0.1
    out = jitted(bilateral_filter)(cost, guide)
    np.testing.assert_allclose(out, bilateral_reference(cost, guide, 4, 4.5, 0.03), atol=1e-5)


def test_bilateral_filter_without_range_term_is_gaussian_box():
    cost, guide = random((2, 7, 8), 14), random((7, 8, 3), 15)
    out = jitted(bilateral_filter, radius=2, sigma_space=1.2, sigma_color=1e6)(cost, guide)
    np.testing.assert_allclose(out, gaussian_box_reference(cost, 2, 1.2), atol=1e-5)


# ---------------------------------------------------------------------------------------------
# Median filter.


@pytest.mark.parametrize("r", [1, 2])
def test_median_cost_filter_matches_np_median(r):
    x = random((2, 7, 8), 16)
    out = jitted(median_cost_filter, radius=r)(x)
    assert out.dtype == jnp.float32 and out.shape == x.shape
    np.testing.assert_allclose(out, median_reference(x, r), atol=0)


# ---------------------------------------------------------------------------------------------
# Entry checks.


def test_entry_checks():
    cost, guide = jnp.zeros((2, 6, 7)), jnp.zeros((6, 7, 3))
    with pytest.raises(ValueError, match="rank"):
        box_filter(jnp.zeros(5), radius=1)
    with pytest.raises(TypeError, match="floating"):
        median_cost_filter(jnp.zeros((6, 7), jnp.int32), radius=1)
    with pytest.raises(ValueError, match="radius"):
        box_filter(cost, radius=0)
    with pytest.raises(ValueError, match="guide size"):
        guided_filter(cost, jnp.zeros((6, 8, 3)), radius=1)
    with pytest.raises(ValueError, match="channels"):
        guided_filter(cost, jnp.zeros((6, 7, 2)), radius=1)
    with pytest.raises(ValueError, match="eps"):
        guided_filter(cost, guide, radius=1, eps=0.0)
    with pytest.raises(ValueError, match="iterations"):
        iterated_guided_filter(cost, guide, radius=1, iterations=0)
    with pytest.raises(ValueError, match="sigma_color"):
        bilateral_filter(cost, guide, radius=1, sigma_color=-1.0)


def test_the_box_mean_differentiates_under_jit():
    """The search differentiates the box aggregation inside jit: a traced initial value of the
    window sum made JAX's reduction the generic one, which has no transpose ("Linearization
    failed"). d/ds sum(box(s x)) = sum(box(x)), exactly for a constant x."""
    x = jnp.ones((2, 7, 9), jnp.float32)
    gradient = jax.jit(jax.grad(lambda s: box_filter(x * s, radius=1).sum()))(1.0)
    assert float(gradient) == pytest.approx(float(box_filter(x, radius=1).sum()))
