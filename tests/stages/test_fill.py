"""Tests for sswjax.stages.fill: the guided weighted median and the vote against brute-force NumPy."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.fill import vote_fill, weighted_median_fill
from sswjax.stages.background import fill_background, fill_invalid


def guided_kernel_reference(guide, r, eps):
    """The guided filter's weights ``W[i, j]`` (He et al., TPAMI 2013, Eq. 11), float64.

    ``q_i = sum_j W[i, j] p_j``; windows run over edge-replicated coordinates, as in the
    package: the output averages the coefficients of the windows centred at the (clamped)
    pixels around ``i``, each fitted over the (clamped) pixels around its centre. ``guide`` is
    (H, W, C); returns (H * W, H * W)."""
    guide = np.asarray(guide, np.float64)
    height, width, channels = guide.shape
    size = (2 * r + 1) ** 2

    def window(y, x):
        return [(min(max(y + dy, 0), height - 1), min(max(x + dx, 0), width - 1))
                for dy in range(-r, r + 1) for dx in range(-r, r + 1)]

    mean, inverse = {}, {}
    for k in np.ndindex(height, width):
        colours = np.array([guide[j] for j in window(*k)])
        mean[k] = colours.mean(0)
        sigma = colours.T @ colours / size - np.outer(mean[k], mean[k])
        inverse[k] = np.linalg.inv(sigma + eps * np.eye(channels))
    weights = np.zeros((height * width, height * width))
    for i in np.ndindex(height, width):
        for k in window(*i):
            for j in window(*k):
                term = 1 + (guide[i] - mean[k]) @ inverse[k] @ (guide[j] - mean[k])
                weights[i[0] * width + i[1], j[0] * width + j[1]] += term / size**2
    return weights


def box_kernel_reference(height, width, r):
    """The edge-replicated box mean's weights, (H * W, H * W)."""
    weights = np.zeros((height * width, height * width))
    for y, x in np.ndindex(height, width):
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                j = min(max(y + dy, 0), height - 1) * width + min(max(x + dx, 0), width - 1)
                weights[y * width + x, j] += 1 / (2 * r + 1) ** 2
    return weights


def weighted_median_reference(filled, valid, weights, *, quantile, source):
    """Each invalid pixel: the first integer disparity ``k`` whose cumulative weight reaches
    ``quantile`` of the total, plus where in ``[k - 1/2, k + 1/2)`` it does (pixels too near a
    tie, in float32, are returned as NaN)."""
    values = np.round(filled).ravel().astype(int)
    counted = np.ones(values.size) if source == "filled" else valid.ravel().astype(float)
    out = filled.astype(np.float64).ravel().copy()  # kept where valid or no weights
    for i in np.flatnonzero(~valid.ravel()):
        w = weights[i] * counted
        target = quantile * w.sum()
        if w.sum() < 0.05 + 1e-4:
            out[i] = np.nan if w.sum() > 0.05 - 1e-4 else out[i]
            continue
        running = np.cumsum([w[values == b].sum() for b in range(values.max() + 1)])
        if np.min(np.abs(running - target)) < 1e-4:
            out[i] = np.nan
        elif (running >= target).any() and np.argmax(running >= target) != values[i]:
            k = np.argmax(running >= target)  # else the fill, in the chosen bin, stays
            below = running[k - 1] if k else 0.0
            share = (target - below) / max(running[k] - below, 1e-6)
            out[i] = k + np.clip(share, 0, 1) - 0.5
    return out.reshape(filled.shape)


def _random_case(seed, shape=(7, 9), levels=6):
    rng = np.random.default_rng(seed)
    disparity = rng.integers(0, levels, shape).astype(np.float32) + rng.uniform(-0.3, 0.3, shape)
    disparity = np.maximum(disparity, 0).astype(np.float32)
    valid = rng.random(shape) < 0.6
    return rng, disparity, valid


@pytest.mark.parametrize("channels, source, quantile", [
    (3, "filled", 0.5), (3, "valid", 0.5), (1, "filled", 0.3), (1, "valid", 0.7)])
def test_guided_weighted_median_matches_brute_force(channels, source, quantile):
    rng, disparity, valid = _random_case(channels * 10 + int(quantile * 10))
    guide = rng.random(disparity.shape + (channels,)).astype(np.float32)
    fill = jax.jit(weighted_median_fill, static_argnames=("radius", "source", "left_band"))
    out = np.asarray(fill(jnp.asarray(disparity), jnp.asarray(valid), radius=1,
                          guide=jnp.asarray(guide), eps=0.05, quantile=quantile, source=source))
    filled = np.asarray(fill_background(jnp.asarray(disparity), jnp.asarray(valid), left_band=True))
    expected = weighted_median_reference(filled, valid, guided_kernel_reference(guide, 1, 0.05),
                                         quantile=quantile, source=source)
    known = np.isfinite(expected)
    assert known.sum() >= disparity.size - 3
    np.testing.assert_allclose(out[known], expected[known], atol=1e-5)
    np.testing.assert_array_equal(out[valid], disparity[valid])


@pytest.mark.parametrize("source", ["filled", "valid"])
def test_box_weighted_median_is_the_window_quantile(source):
    _, disparity, valid = _random_case(3, shape=(8, 10))
    # quantile 0.45: with counts of 25ths, half the valid count would often tie exactly
    out = np.asarray(weighted_median_fill(jnp.asarray(disparity), jnp.asarray(valid), radius=2,
                                          quantile=0.45, source=source, left_band=False))
    filled = np.asarray(fill_background(jnp.asarray(disparity), jnp.asarray(valid)))
    expected = weighted_median_reference(filled, valid, box_kernel_reference(8, 10, 2),
                                         quantile=0.45, source=source)
    known = np.isfinite(expected)
    assert known.sum() >= disparity.size - 3
    np.testing.assert_allclose(out[known], expected[known], atol=1e-5)


def test_colour_edge_keeps_the_pixel_on_its_own_surface():
    # Two surfaces (disparity 2 on the left, 6 on the right) meeting at a colour edge; the
    # rejected column right of the edge takes the right surface with the colour guide, while
    # a plain box median (mostly the left surface in its window) takes the other one.
    disparity = np.where(np.arange(12) < 6, 2.0, 6.0)[None].repeat(9, 0).astype(np.float32)
    guide = np.where(np.arange(12) < 6, 0.1, 0.9)[None, :, None].repeat(9, 0).astype(np.float32)
    valid = np.ones(disparity.shape, bool)
    valid[:, 6:8] = False
    disparity[~valid] = 0.0
    args = dict(radius=3, source="valid", left_band=False)
    guided = weighted_median_fill(jnp.asarray(disparity), jnp.asarray(valid),
                                  guide=jnp.asarray(guide), eps=1e-4, **args)
    box = weighted_median_fill(jnp.asarray(disparity), jnp.asarray(valid), **args)
    np.testing.assert_allclose(np.asarray(guided)[:, 6], 6.0, atol=0.01)
    np.testing.assert_allclose(np.asarray(box)[:, 6], 2.0, atol=0.01)


def test_no_counted_neighbour_keeps_the_background_fill():
    # Far from the valid columns the window counts nothing: the running sum (0) would "reach"
    # the target (0) at bin 0 without the guard on the total.
    disparity = np.full((5, 20), 4.0, np.float32)
    valid = np.zeros((5, 20), bool)
    valid[:, :2] = True
    out = weighted_median_fill(jnp.asarray(disparity), jnp.asarray(valid), radius=1,
                               source="valid")
    assert np.all(np.asarray(out) == 4.0)


@pytest.mark.parametrize("kwargs, message", [
    (dict(radius=0), "radius must be an integer >= 1"),
    (dict(radius=1, source="all"), "source must be one of"),
    (dict(radius=1, quantile=0.0), r"quantile must be in \(0, 1\]"),
    (dict(radius=1, eps=0.0), "eps must be > 0"),
    (dict(radius=1, guide=jnp.zeros((3, 4, 2))), "guide"),
])
def test_bad_arguments(kwargs, message):
    with pytest.raises(ValueError, match=message):
        weighted_median_fill(jnp.zeros((4, 5)), jnp.ones((4, 5), bool), **kwargs)


@pytest.mark.parametrize("content, message", [
    ('{"fill_source": "all"}', "parameters in the old flat names ('fill_source'): convert the file"),
    ('{"fill": {"kind": "wmedian", "source": "all"}}',
     "parameter fill.source must be one of 'filled', 'valid', got 'all'"),
])
def test_cli_bad_fill_parameters(small_pair, tmp_path, run_cli, content, message):
    params = tmp_path / "params.json"
    params.write_text(content)
    code, _, err = run_cli(["match", small_pair.folder / "left.png", small_pair.folder / "right.png",
                            "--ndisp", 8, "-o", tmp_path / "d.pfm", "--params", params])
    assert code == 2 and err.startswith("sswjax: error: ") and err.count("\n") == 1, err
    assert message in err and not (tmp_path / "d.pfm").exists()


def vote_reference(disparity, valid, guide, median_radius, radius, step, sigma, tolerance):
    """Loops: each invalid pixel's candidates (median fill, nearest valid left and right on
    the row) and their votes over the clamped sampled window."""
    filled = np.asarray(fill_invalid(jnp.asarray(disparity), jnp.asarray(valid),
                                     radius=median_radius, left_band=True, median="separable"))
    intensity = guide.mean(-1)
    height, width = disparity.shape
    reach = radius // step * step
    out = disparity.astype(np.float32).copy()
    for y, x in zip(*np.nonzero(~valid)):
        left = [disparity[y, i] for i in range(x) if valid[y, i]]
        right = [disparity[y, i] for i in range(x + 1, width) if valid[y, i]]
        candidates = [filled[y, x], left[-1] if left else filled[y, x],
                      right[0] if right else filled[y, x]]
        support = [0.0, 0.0, 0.0]
        for dy in range(-reach, reach + 1, step):
            for dx in range(-reach, reach + 1, step):
                q = (min(max(y + dy, 0), height - 1), min(max(x + dx, 0), width - 1))
                weight = 1 / (1 + 3 * abs(intensity[q] - intensity[y, x]) / sigma)
                for k, c in enumerate(candidates):
                    if abs(filled[q] - c) <= tolerance:
                        support[k] += weight
        best = 0
        for k in (1, 2):
            if support[k] > support[best] + 1e-5:
                best = k
        out[y, x] = candidates[best]
    return out


@pytest.mark.parametrize("radius, step, tolerance", [(2, 1, 0.5), (4, 2, 1.0), (5, 4, 2.0)])
def test_vote_fill_matches_brute_force(radius, step, tolerance):
    rng = np.random.default_rng(radius)
    disparity = np.repeat(np.array([2.0] * 7 + [9.0] * 7, np.float32)[None], 9, axis=0)
    disparity += rng.integers(-1, 2, disparity.shape)
    valid = rng.random(disparity.shape) < 0.55
    guide = np.where(disparity[..., None] > 5, 0.8, 0.2) + 0.05 * rng.random((9, 14, 3))
    guide = guide.astype(np.float32)
    ours = np.asarray(vote_fill(jnp.asarray(disparity), jnp.asarray(valid), guide=jnp.asarray(guide),
                                median_radius=1, radius=radius, step=step, sigma=0.2,
                                tolerance=tolerance))
    expected = vote_reference(disparity, valid, guide, 1, radius, step, 0.2, tolerance)
    np.testing.assert_allclose(ours, expected, atol=1e-6)


def test_vote_fill_follows_the_colour_across_a_rejected_band():
    # Columns 3-4 rejected between surfaces 1 (dark) and 5 (bright); column 3 is dark. The
    # left-band fill gives both 5 (x < 5: the bright surface has no match there), the vote
    # gives column 3 the dark surface's 1.
    d = jnp.array([[1., 1., 1., 0., 0., 5., 5., 5.]] * 5)
    guide = jnp.array([[0., 0., 0., 0., 1., 1., 1., 1.]] * 5)
    background = fill_invalid(d, d > 0, radius=0, left_band=True)
    assert background[2].tolist() == [1, 1, 1, 5, 5, 5, 5, 5]
    voted = vote_fill(d, d > 0, guide=guide, median_radius=0, radius=2, step=1)
    assert voted[2].tolist() == [1, 1, 1, 1, 5, 5, 5, 5]


@pytest.mark.parametrize("kwargs, message", [
    (dict(radius=0), "radius must be an integer >= 1"),
    (dict(step=0), "step must be an integer >= 1"),
    (dict(sigma=0.0), "sigma must be > 0"),
    (dict(tolerance=-1.0), "tolerance must be >= 0"),
    (dict(guide=jnp.zeros((3, 4, 2))), "guide"),
])
def test_vote_fill_bad_arguments(kwargs, message):
    kwargs = {"guide": jnp.zeros((4, 5)), "median_radius": 1, **kwargs}
    with pytest.raises(ValueError, match=message):
        vote_fill(jnp.zeros((4, 5)), jnp.ones((4, 5), bool), **kwargs)


