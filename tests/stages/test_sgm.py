"""Tests for sswjax.stages.sgm against a float64 NumPy reference of Hirschmuller's recursion, and
for the paths carried across row windows (sswjax.stages.paths): the whole image's sums."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.graph.volume import fold_volume
from sswjax.stages.paths import Seeds, no_seeds
from sswjax.stages.quantisation import as_volume, quantisation, quantise_cost, sum_planes
from sswjax.stages.sgm import path_penalties, semi_global, semi_global_sums, vertical_shifts

DIRECTIONS = {4: [(0, 1), (0, -1), (1, 0), (-1, 0)],
              8: [(0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, -1), (-1, 1)]}


def penalties_reference(guide, direction, p1, p2, sigma, labels, factor):
    """P1, P2 maps by plain loops: the step from p - r to p (edge-replicated predecessor)."""
    height, width = guide.shape[:2]
    dy, dx = direction
    p1_map, p2_map = np.zeros((height, width)), np.zeros((height, width))
    for y in range(height):
        for x in range(width):
            py, px = min(max(y - dy, 0), height - 1), min(max(x - dx, 0), width - 1)
            change = np.abs(guide[y, x] - guide[py, px]).mean()
            a, b = p1, max(p1, p2 / (1 + change / sigma))
            if labels is not None and labels[y, x] != labels[py, px]:
                a, b = a * factor, b * factor
            p1_map[y, x], p2_map[y, x] = a, b
    return p1_map, p2_map


def semi_global_reference(cost, guide, p1, p2, sigma, paths, labels=None, factor=1.0):
    cost = cost.astype(np.float64)
    ndisp, height, width = cost.shape
    total = np.zeros_like(cost)
    for dy, dx in DIRECTIONS[paths]:
        pen1, pen2 = penalties_reference(guide, (dy, dx), p1, p2, sigma, labels, factor)
        path = np.zeros_like(cost)
        ys = range(height) if dy >= 0 else range(height - 1, -1, -1)
        xs = list(range(width)) if dx >= 0 else list(range(width - 1, -1, -1))
        for y in ys:
            for x in xs:
                py, px = y - dy, x - dx
                if not (0 <= py < height and 0 <= px < width) or (dy == 0 and dx == 0):
                    path[:, y, x] = cost[:, y, x]
                    continue
                previous = path[:, py, px]
                lowest = previous.min()
                for d in range(ndisp):
                    options = [previous[d], lowest + pen2[y, x]]
                    if d > 0:
                        options.append(previous[d - 1] + pen1[y, x])
                    if d < ndisp - 1:
                        options.append(previous[d + 1] + pen1[y, x])
                    path[d, y, x] = cost[d, y, x] + min(options) - lowest
        total += path
    return total


@pytest.mark.parametrize("paths", [4, 8])
@pytest.mark.parametrize("with_labels", [False, True])
def test_semi_global_matches_reference(paths, with_labels):
    rng = np.random.default_rng(paths)
    cost = rng.random((5, 6, 7)).astype(np.float32)
    guide = rng.random((6, 7, 3)).astype(np.float32)
    labels = (np.arange(42).reshape(6, 7) // 9).astype(np.int32) if with_labels else None
    run = jax.jit(lambda c, g, l: semi_global(c, g, p1=0.1, p2=0.6, sigma=0.2, paths=paths,
                                                 labels=l, segment_factor=0.5))
    ours = run(jnp.asarray(cost), jnp.asarray(guide), None if labels is None else jnp.asarray(labels))
    reference = semi_global_reference(cost, guide, 0.1, 0.6, 0.2, paths, labels, 0.5)
    assert ours.shape == cost.shape and ours.dtype == jnp.float32
    np.testing.assert_allclose(ours, reference, atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("paths", [4, 8])
def test_int16_paths_match_the_reference_within_the_quantisation(paths):
    # The int16 recursion is the float one on costs rounded to 1/scale: the sums differ by at
    # most a few steps per path (the rounding of the cost and of the penalties, carried along).
    rng = np.random.default_rng(10 + paths)
    cost = rng.random((6, 7, 9)).astype(np.float32)
    guide = rng.random((7, 9, 3)).astype(np.float32)
    ours = jax.jit(lambda c, g: semi_global(c, g, p1=0.1, p2=0.6, sigma=0.2, paths=paths,
                                             cost_bound=1.0))(jnp.asarray(cost), jnp.asarray(guide))
    reference = semi_global_reference(cost, guide, 0.1, 0.6, 0.2, paths)
    scale = (2 ** 15 - 1 - 2 * paths) / (paths * (2.0 + 0.6))
    assert ours.dtype == jnp.float32
    np.testing.assert_allclose(ours, reference, atol=paths * 4 / scale, rtol=0)
    assert np.abs(np.asarray(ours) - reference).max() > 0          # it did quantise


def test_int16_paths_cannot_overflow_at_the_bound():
    # Costs at twice the bound everywhere but a stripe of zeros, the largest penalties: the
    # sums reach their maximum and must neither wrap around nor go negative.
    cost = np.full((5, 6, 8), 50.0, np.float32)
    cost[2, :, 3:5] = 0.0
    guide = np.zeros((6, 8, 1), np.float32)
    for paths in (4, 8):
        ours = np.asarray(semi_global(jnp.asarray(cost), jnp.asarray(guide), p1=0.9, p2=0.9,
                                      paths=paths, cost_bound=1.0))
        reference = semi_global_reference(np.minimum(cost, 2.0), guide, 0.9, 0.9, 0.05, paths)
        assert ours.min() >= 0
        np.testing.assert_allclose(ours, reference, atol=paths * 4 * 2.9 / 32000, rtol=0)
        np.testing.assert_array_equal(ours.argmin(axis=0), reference.argmin(axis=0))


@pytest.mark.parametrize("paths", [4, 8])
def test_uint8_cost_matches_the_reference_within_its_levels(paths):
    # The cost stored in 255 levels of 2 / 255 (the paths in int16): each path is the float
    # recursion on costs rounded to a level, so the sums differ by at most half a level per
    # path and step of the cost's rounding carried along, plus the penalties' int16 rounding.
    rng = np.random.default_rng(20 + paths)
    cost = rng.random((6, 7, 9)).astype(np.float32)
    guide = rng.random((7, 9, 3)).astype(np.float32)
    run = jax.jit(lambda c, g: semi_global_sums(c, g, p1=0.1, p2=0.6, sigma=0.2, paths=paths,
                                                  cost_bound=1.0, cost_levels=255))
    sums = run(jnp.asarray(cost), jnp.asarray(guide))
    rounded = np.round(cost * 127.5) / 127.5
    reference = semi_global_reference(rounded, guide, 0.1, 0.6, 0.2, paths)
    assert sums.sums.dtype == jnp.int16
    np.testing.assert_allclose(as_volume(sums), reference, atol=paths * 4 / float(sums.scale),
                               rtol=0)
    int16 = semi_global(jnp.asarray(cost), jnp.asarray(guide), p1=0.1, p2=0.6, sigma=0.2,
                        paths=paths, cost_bound=1.0)
    assert np.abs(np.asarray(as_volume(sums)) - np.asarray(int16)).max() > 0   # it is coarser


@pytest.mark.parametrize("cost_levels", [None, 255])
def test_a_stored_cost_gives_the_sums_of_the_float_cost(cost_levels):
    # The pipeline stores each aggregated block with quantise_cost as it is built: the paths
    # on that volume must be exactly those on the float32 volume quantised inside.
    rng = np.random.default_rng(3)
    cost = jnp.asarray(rng.random((5, 6, 8)).astype(np.float32) * 2.5)
    guide = jnp.asarray(rng.random((6, 8, 1)).astype(np.float32))
    options = dict(p1=0.1, p2=0.6, paths=4, cost_bound=1.0, cost_levels=cost_levels)
    quant = quantisation(cost_bound=1.0, paths=4, p1=0.1, p2=0.6, cost_levels=cost_levels)
    stored = jnp.concatenate([quantise_cost(cost[:2], quant), quantise_cost(cost[2:], quant)])
    assert stored.dtype == (jnp.int16 if cost_levels is None else jnp.uint8)
    inside = semi_global_sums(cost, guide, **options)
    outside = semi_global_sums(stored, guide, **options)
    np.testing.assert_array_equal(outside.sums, inside.sums)
    assert float(outside.scale) == float(inside.scale)
    with pytest.raises(ValueError, match="quantise_cost"):
        semi_global_sums(stored.astype(jnp.int32), guide, **options)
    with pytest.raises(ValueError, match="cost_levels"):
        quantisation(cost_bound=1.0, paths=4, p1=0.1, p2=0.6, cost_levels=100)


@pytest.mark.parametrize("channels", [1, 3])
def test_path_penalties_match_reference(channels):
    rng = np.random.default_rng(3)
    guide = rng.random((5, 6, channels)).astype(np.float32)
    labels = rng.integers(0, 3, (5, 6)).astype(np.int32)
    for direction in DIRECTIONS[8]:
        ours = path_penalties(jnp.asarray(guide), direction, p1=0.2, p2=1.0, sigma=0.1,
                              labels=jnp.asarray(labels), segment_factor=0.25)
        reference = penalties_reference(guide, direction, 0.2, 1.0, 0.1, labels, 0.25)
        for a, b in zip(ours, reference):
            np.testing.assert_allclose(a, b, atol=1e-6)


def test_semi_global_fills_a_textureless_band():
    # A disparity-2 scene whose middle columns carry no information (flat cost): the paths
    # carry the neighbours' disparity across, where the raw cost cannot decide.
    cost = np.ones((5, 8, 12), np.float32)
    cost[2] = 0.0
    cost[:, :, 4:8] = 0.5
    summed = semi_global(jnp.asarray(cost), jnp.zeros((8, 12, 1)), p1=0.05, p2=0.3, paths=4)
    assert (np.asarray(summed).argmin(axis=0) == 2).all()


@pytest.mark.parametrize("cost_bound", [None, 2.0])
def test_path_sums_read_as_the_volume(cost_bound):
    # Planes read from the sums as the scans leave them equal the transposed volume's, and the
    # winners folded from either are the same.
    rng = np.random.default_rng(5)
    cost = jnp.asarray(rng.random((7, 6, 9)).astype(np.float32))
    guide = jnp.asarray(rng.random((6, 9, 3)).astype(np.float32))
    sums = semi_global_sums(cost, guide, p1=0.1, p2=0.5, paths=4, cost_bound=cost_bound)
    volume = as_volume(sums)
    assert volume.shape == (7, 6, 9) and volume.dtype == jnp.float32
    planes = sum_planes(sums, jnp.asarray([3, 0, 6]))
    for plane, d in zip(planes, (3, 0, 6)):
        np.testing.assert_allclose(plane, volume[d], rtol=1e-6)
    for chunk in (0, 3):
        ours, reference = fold_volume(sums, 7, chunk), fold_volume(volume, 7, chunk)
        for a, b in zip(ours, reference):   # indices exact, costs to the division's rounding
            np.testing.assert_allclose(a, b, rtol=1e-6)


def test_semi_global_is_differentiable():
    rng = np.random.default_rng(4)
    cost = jnp.asarray(rng.random((4, 5, 6)).astype(np.float32))
    guide = jnp.asarray(rng.random((5, 6, 3)).astype(np.float32))
    grad = jax.grad(lambda p2: semi_global(cost, guide, p1=0.1, p2=p2, paths=8).sum())(0.5)
    assert np.isfinite(float(grad))


def test_entry_checks():
    with pytest.raises(ValueError, match="paths"):
        semi_global(jnp.zeros((2, 4, 4)), jnp.zeros((4, 4, 1)), p1=0.1, p2=0.2, paths=6)
    with pytest.raises(ValueError, match="guide size"):
        semi_global(jnp.zeros((2, 4, 4)), jnp.zeros((4, 5, 1)), p1=0.1, p2=0.2)
    with pytest.raises(ValueError, match="rank"):
        semi_global(jnp.zeros((4, 4)), jnp.zeros((4, 4, 1)), p1=0.1, p2=0.2)


# ---------------------------------------------------------------------------------------------
# bands (per-pixel disparity ranges, sswjax.stages.bands)


def band_semi_global_reference(cost, starts, guide, p1, p2, sigma, paths):
    """Eq. 13 over per-pixel bands, pixel by pixel and disparity by disparity in float64: the
    predecessor's path cost at an absolute disparity it did not search is missing."""
    cost = cost.astype(np.float64)
    width_k, height, width = cost.shape
    total = np.zeros_like(cost)
    for dy, dx in DIRECTIONS[paths]:
        pen1, pen2 = penalties_reference(guide, (dy, dx), p1, p2, sigma, None, 1.0)
        path = np.zeros_like(cost)
        ys = range(height) if dy >= 0 else range(height - 1, -1, -1)
        xs = list(range(width)) if dx >= 0 else list(range(width - 1, -1, -1))
        for y in ys:
            for x in xs:
                py, px = y - dy, x - dx
                if not (0 <= py < height and 0 <= px < width):
                    path[:, y, x] = cost[:, y, x]
                    continue
                previous = {starts[py, px] + k: path[k, py, px] for k in range(width_k)}
                lowest = min(previous.values())
                for k in range(width_k):
                    d = starts[y, x] + k
                    options = [lowest + pen2[y, x]]
                    if d in previous:
                        options.append(previous[d])
                    options += [previous[e] + pen1[y, x] for e in (d - 1, d + 1) if e in previous]
                    path[k, y, x] = cost[k, y, x] + min(options) - lowest
        total += path
    return total


@pytest.mark.parametrize("paths", [4, 8])
def test_band_paths_match_the_loop_reference(paths):
    rng = np.random.default_rng(paths)
    cost = rng.random((4, 6, 7)).astype(np.float32)
    guide = rng.random((6, 7, 3)).astype(np.float32)
    starts = rng.integers(3, 9, size=(6, 7)).astype(np.int32)  # neighbours overlap, or do not
    run = jax.jit(lambda c, g, s: semi_global_sums(c, g, p1=0.1, p2=0.6, sigma=0.2,
                                                   paths=paths, starts=s).sums)
    ours = run(jnp.asarray(cost), jnp.asarray(guide), jnp.asarray(starts))
    reference = band_semi_global_reference(cost, starts, guide, 0.1, 0.6, 0.2, paths)
    np.testing.assert_allclose(ours, reference, atol=1e-5, rtol=1e-5)


def test_band_paths_in_int16_match_the_reference_within_the_quantisation():
    rng = np.random.default_rng(3)
    cost = rng.random((5, 6, 9)).astype(np.float32)
    guide = rng.random((6, 9, 1)).astype(np.float32)
    starts = rng.integers(0, 4, size=(6, 9)).astype(np.int32)
    quant = quantisation(cost_bound=1.0, paths=4, p1=0.1, p2=0.6, cost_levels=255)
    stored = quantise_cost(jnp.asarray(cost), quant)
    ours = as_volume(semi_global_sums(stored, jnp.asarray(guide), p1=0.1, p2=0.6, sigma=0.2,
                                      paths=4, cost_bound=1.0, cost_levels=255,
                                      starts=jnp.asarray(starts)))
    levels = np.asarray(stored, np.float64) * (2.0 / 255)  # the cost the paths saw
    reference = band_semi_global_reference(levels, starts, guide, 0.1, 0.6, 0.2, 4)
    np.testing.assert_allclose(ours, reference, atol=4 * 4 / float(quant.scale) + 1e-4)


@pytest.mark.parametrize("paths", [4, 8])
def test_a_band_that_is_the_whole_range_is_the_full_recursion(paths):
    rng = np.random.default_rng(7)
    cost = jnp.asarray(rng.random((6, 5, 8)).astype(np.float32))
    guide = jnp.asarray(rng.random((5, 8, 3)).astype(np.float32))
    options = dict(p1=0.1, p2=0.5, sigma=0.1, paths=paths)
    full = semi_global_sums(cost, guide, **options).sums
    band = semi_global_sums(cost, guide, starts=jnp.zeros((5, 8), jnp.int32), **options).sums
    np.testing.assert_allclose(band, full, atol=1e-6)


CARRIED_OPTIONS = dict(p1=0.1, p2=0.6, sigma=0.2)


def _windows(height, core, overlap):
    """(top, first, last) of row windows of ``core`` rows with ``overlap`` rows either side."""
    size = core + 2 * overlap
    spans = []
    for first in range(0, height, core):
        top = min(max(first - overlap, 0), height - size)
        spans.append((top, first, min(first + core, height)))
    return size, spans


def _carried_sums(cost, guide, paths, core, overlap, **options):
    """The sums of each row window with its vertical paths carried from its neighbours, stitched
    by cores: a sweep down keeps the forward states each window leaves for the next, a sweep up
    runs each window with them and with the backward states of the window below."""
    ndisp, height, width = cost.shape
    size, spans = _windows(height, core, overlap)
    last, enter = len(spans) - 1, overlap // 2
    run = jax.jit(lambda c, g, s: semi_global_sums(c, g, paths=paths, seeds=s, **options))
    dtype = jnp.float32 if options.get("cost_bound") is None else jnp.int16
    zero = no_seeds((ndisp, width), len(vertical_shifts(paths)), dtype)

    def window(k, seeds):
        top = spans[k][0]
        return run(cost[:, top:top + size], guide[top:top + size], seeds)

    def gap(k):  # rows from window k's top to window k + 1's
        return spans[k + 1][0] - spans[k][0]

    left_below = [None] * len(spans)  # the forward states window k leaves for window k + 1
    forward = zero.forward
    for k in range(last):
        seeds = zero._replace(forward=forward, entry=jnp.array([enter if k else 0, 0]),
                              capture=jnp.array([gap(k) + enter - 1, 0]))
        forward = left_below[k] = window(k, seeds).carried.forward
    out, backward = np.zeros(cost.shape, np.float64), zero.backward
    for k in range(last, -1, -1):
        seeds = Seeds(left_below[k - 1] if k else zero.forward, backward,
                      jnp.array([enter if k else 0, enter if k < last else 0]),
                      jnp.array([0, gap(k - 1) + enter - 1 if k else 0]))
        result = window(k, seeds)
        backward = result.carried.backward
        sums = np.asarray(result.sums, np.float64)  # as the scans leave them (int16 unscaled)
        top, first, stop = spans[k]
        out[:, first:stop] = sums[:, first - top:stop - top]
    return out


def _problem(seed, ndisp, height, width, channels=3):
    """A random float32 cost volume (ndisp, height, width) and guide (height, width, C)."""
    rng = np.random.default_rng(seed)
    return (rng.random((ndisp, height, width)).astype(np.float32),
            rng.random((height, width, channels)).astype(np.float32))


@pytest.mark.parametrize("paths", [4, 8])
def test_carried_paths_give_the_whole_images_sums(paths):
    cost, guide = _problem(paths, 5, 29, 9)
    ours = _carried_sums(jnp.asarray(cost), jnp.asarray(guide), paths, core=5, overlap=4,
                         **CARRIED_OPTIONS)
    reference = semi_global_reference(cost, guide, 0.1, 0.6, 0.2, paths)
    np.testing.assert_allclose(ours, reference, atol=1e-4, rtol=1e-5)


def test_carried_int16_paths_equal_the_whole_images_exactly():
    cost, guide = (jnp.asarray(a) for a in _problem(3, 6, 40, 11, 1))
    whole = semi_global_sums(cost, guide, paths=4, cost_bound=1.0, **CARRIED_OPTIONS)
    ours = _carried_sums(cost, guide, 4, core=7, overlap=6, cost_bound=1.0, **CARRIED_OPTIONS)
    assert np.array_equal(ours, np.asarray(whole.sums, np.float64))


def test_uncarried_windows_differ_from_the_whole_image():
    # The test above can fail: cut without seeds, the vertical paths restart in each window.
    cost, guide = _problem(4, 5, 29, 9)
    size, spans = _windows(29, 5, 4)
    cut = np.zeros(cost.shape)
    for top, first, last in spans:
        window = semi_global_sums(jnp.asarray(cost[:, top:top + size]),
                                  jnp.asarray(guide[top:top + size]), paths=4, **CARRIED_OPTIONS)
        cut[:, first:last] = np.asarray(window.sums)[:, first - top:last - top]
    assert not np.allclose(cut, semi_global_reference(cost, guide, 0.1, 0.6, 0.2, 4), atol=1e-3)


def test_no_seeds_are_the_unseeded_scan():
    cost, guide = (jnp.asarray(a) for a in _problem(5, 4, 10, 6, 1))
    plain = semi_global_sums(cost, guide, paths=8, cost_bound=1.0, **CARRIED_OPTIONS)
    seeded = semi_global_sums(cost, guide, paths=8, cost_bound=1.0,
                              seeds=no_seeds((4, 6), 3, jnp.int16), **CARRIED_OPTIONS)
    assert np.array_equal(plain.sums, seeded.sums) and plain.carried is None
