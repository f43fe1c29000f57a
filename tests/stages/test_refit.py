"""Tests for sswjax.stages.refit and the graph's refit on the full-resolution cost
(``sswjax.graph.coarse.refit_on_cost``) against plain loops over pixels."""

import jax.numpy as jnp
import numpy as np
import pytest

import sswjax
from sswjax.graph.coarse import refit_on_cost
from sswjax.stages.reference import cost_volume
from sswjax.stages.refit import refit_centres, refit_disparity


def _fit_by_loops(disparity, cost, limit):
    """The refit of one map by loops: round, then the equiangular lines where they apply."""
    height, width = disparity.shape
    out = disparity.astype(np.float32).copy()
    for y in range(height):
        for x in range(width):
            c = min(max(int(np.round(disparity[y, x])), 0), limit - 1)
            before, centre, after = cost[:, y, x]
            rise = max(before, after) - centre
            if 0 < c < limit - 1 and rise > 0:
                out[y, x] = c + min(max((before - after) / (2 * rise), -0.5), 0.5)
    return out


def test_centres_round_and_stay_in_the_range():
    d = np.array([[-0.3, 0.49, 0.51, 3.5, 4.5, 8.9, 12.0]], np.float32)
    ours = np.asarray(refit_centres(jnp.asarray(d), limit=9))
    assert ours.dtype == np.int32
    assert ours.tolist() == [[0, 0, 1, 4, 4, 8, 8]]  # halves to even, as jnp.round


def test_refit_disparity_by_loops():
    rng = np.random.default_rng(0)
    disparity = (rng.random((9, 11)) * 12).astype(np.float32)
    disparity[0, :3] = [0.2, 11.8, 5.0]  # the range's ends and an integer
    cost = rng.random((3, 9, 11)).astype(np.float32)
    cost[:, 1, :4] = [[1.0], [1.0], [1.0]]  # flat: no fit
    cost[:, 2, :4] = [[0.2], [0.9], [0.4]]  # a peak at the centre: no fit
    cost[:, 3, :4] = [[0.5], [0.1], [0.5]]  # a symmetric V: the centre itself
    centres = refit_centres(jnp.asarray(disparity), limit=12)
    ours = np.asarray(refit_disparity(jnp.asarray(disparity), centres, *jnp.asarray(cost),
                                      limit=12))
    reference = _fit_by_loops(disparity, cost, 12)
    np.testing.assert_allclose(ours, reference, atol=1e-6)
    assert (ours[1, :4] == disparity[1, :4]).all() and (ours[2, :4] == disparity[2, :4]).all()
    np.testing.assert_array_equal(ours[3, :4], np.round(disparity[3, :4]))
    kept = ours == disparity  # elsewhere within half a pixel of the rounded map
    assert (np.abs(ours - np.round(disparity))[~kept] <= 0.5 + 1e-6).all()


def test_refit_disparity_checks_its_inputs():
    d = jnp.zeros((4, 5))
    planes = [jnp.zeros((4, 5))] * 3
    with pytest.raises(ValueError, match="after"):
        refit_disparity(d, refit_centres(d, limit=3), *planes[:2], jnp.zeros((4, 6)), limit=3)
    with pytest.raises(TypeError):
        refit_disparity(d, d, *planes, limit=3)


@pytest.mark.parametrize("radius", [1, 2])
def test_refit_on_cost_by_loops(radius):
    """The graph's refit: each pixel's cost at its rounded disparity and the two beside it,
    from the whole cost volume, averaged over the edge-replicated window in which each
    neighbour reads its own centre's planes, then fitted."""
    rng = np.random.default_rng(1)
    height, width, ndisp = 10, 24, 7
    left = rng.random((height, width, 3)).astype(np.float32)
    right = rng.random((height, width, 3)).astype(np.float32)
    disparity = (rng.random((height, width)) * (ndisp - 1)).astype(np.float32)
    params = sswjax.preset("fast").replace(**{"coarse.refit_radius": radius})
    ours = np.asarray(refit_on_cost(jnp.asarray(left), jnp.asarray(right), params,
                                    jnp.asarray(disparity), limit=ndisp))
    c = params.cost
    volume = np.asarray(cost_volume(jnp.asarray(left), jnp.asarray(right), ndisp=ndisp,
                                    tad_weight=c.tad_weight, gradient_weight=c.gradient_weight,
                                    census_weight=c.census_weight,
                                    tad_truncation=c.tad_truncation,
                                    gradient_truncation=c.gradient_truncation,
                                    census_height=c.census_height, census_width=c.census_width))
    centres = np.clip(np.round(disparity), 0, ndisp - 1).astype(int)
    cost = np.zeros((3, height, width), np.float64)
    for y in range(height):
        for x in range(width):
            for k in range(3):
                total = 0.0
                for dy in range(-radius, radius + 1):
                    for dx in range(-radius, radius + 1):
                        yy = min(max(y + dy, 0), height - 1)
                        xx = min(max(x + dx, 0), width - 1)
                        plane = min(max(centres[yy, xx] + k - 1, 0), ndisp - 1)
                        total += volume[plane, yy, xx]
                cost[k, y, x] = total / (2 * radius + 1) ** 2
    reference = _fit_by_loops(disparity, cost.astype(np.float32), ndisp)
    np.testing.assert_allclose(ours, reference, atol=1e-4)


def test_refit_on_cost_moves_a_map_towards_a_sub_pixel_shift():
    """A smooth texture moved by 6.3 pixels: a map of 6.0 everywhere comes back closer."""
    rng = np.random.default_rng(2)
    height, width, shift = 32, 96, 6.3
    columns = np.arange(width + 16, dtype=np.float64)
    texture = np.stack([np.interp(columns, columns[::3], rng.random(len(columns[::3])))
                        for _ in range(height)])
    right = texture[:, 8:8 + width]
    left = np.stack([np.interp(np.arange(width) + 8 - shift, columns, row) for row in texture])
    pair = [np.repeat(image[..., None], 3, -1).astype(np.float32) for image in (left, right)]
    start = np.full((height, width), 6.0, np.float32)
    ours = np.asarray(refit_on_cost(*map(jnp.asarray, pair), sswjax.preset("fast").replace(
        **{"coarse.refit_radius": 2}), jnp.asarray(start), limit=16))
    inner = ours[4:-4, 16:-8]
    assert abs(float(np.median(inner)) - shift) < 0.15, np.median(inner)
    assert np.mean(np.abs(inner - shift)) < np.mean(np.abs(start[4:-4, 16:-8] - shift))
