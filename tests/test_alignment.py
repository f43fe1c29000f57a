"""The vertical alignment (``params.alignment``): a pair whose right image is moved vertically by
a known affine offset has it measured back (:func:`sswjax.graph.align_right`, the step before
the method), once for the whole pair whatever the plan, and matches better."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.ndimage import gaussian_filter, map_coordinates

import sswjax
from sswjax import ExecutionPlan
from sswjax.api.batch import match_batch
from sswjax.config import LeftRightCheck
from sswjax.graph import align_right, ssw_disparity
from sswjax.graph.alignment import alignment_coefficients, halved_levels
from sswjax.graph.match import carries_paths
from sswjax.runtime.execute import align, graph_call
from sswjax.runtime.memory import MemoryEstimateError, check_memory, estimate_peak_bytes
from sswjax.stages.alignment import tile_offsets

HEIGHT, WIDTH, NDISP = 96, 128, 16
TRUTH = np.array([0.3, -0.25, 0.35])  # c0, c1, c2 of dy = c0 + c1 u + c2 v


def _offsets(coefficients, height=HEIGHT, width=WIDTH):
    u = (np.arange(width) - (width - 1) / 2) / width
    v = (np.arange(height) - (height - 1) / 2) / height
    return coefficients[0] + coefficients[1] * u[None, :] + coefficients[2] * v[:, None]


def _moved_pair(height=HEIGHT, width=WIDTH, dy=None):
    """A smooth random texture (no detail finer than a few pixels, as a photograph's at the
    levels the offset is measured) on two planes (disparities 8 and 12, whole pixels at the levels
    halved once and twice too); the right image is the left
    scene seen ``d`` pixels to the left and ``dy`` rows lower: ``right(y + dy, x - d) =
    left(y, x)``."""
    rng = np.random.default_rng(7)
    texture = gaussian_filter(rng.random((height + 20, width + 40, 3)), (3.0, 3.0, 0))
    texture = (texture - texture.min()) / np.ptp(texture)
    disparity = np.where(np.arange(width)[None, :] < width // 2, 8.0, 12.0) * np.ones((height, 1))
    ys, xs = np.mgrid[0:height, 0:width].astype(float)
    left = np.stack([map_coordinates(texture[..., c], [ys + 10, xs + 20], order=3)
                     for c in range(3)], -1)
    # The right pixel (y', x') shows the left scene at (y' - dy, x' + d) (dy, d varying slowly,
    # read at the right pixel).
    dy = _offsets(TRUTH, height, width) if dy is None else dy
    right_disparity = np.where(xs + 10 < width // 2, 8.0, 12.0)
    right = np.stack([map_coordinates(texture[..., c], [ys - dy + 10, xs + right_disparity + 20],
                                      order=3) for c in range(3)], -1)
    return left.astype(np.float32), right.astype(np.float32), disparity.astype(np.float32)


@pytest.fixture(scope="module")
def moved_pair():
    return _moved_pair()


def _params(**options):
    """``accurate`` aligned (the first pass on the pair halved once). The pair is small: its
    tiles have 192 valid pixels at most at the level halved once, fewer than the default's floor
    (``min_pixels`` 256), which these tests lower."""
    return sswjax.preset("accurate").replace(alignment={"kind": "vertical", "levels": 1,
                                                        "min_pixels": 64, **options})


# Jitted, as the graph runs them: op by op, each of their many small operations compiles alone.
_coefficients = jax.jit(alignment_coefficients, static_argnames=("limit", "scale"))


def _largest_error(params, coefficients):
    """The largest departure from the truth of the pair's offsets from ``coefficients``."""
    offsets = np.asarray(params.alignment.offset_map(coefficients, (HEIGHT, WIDTH)))
    return np.abs(offsets - _offsets(TRUTH)).max()


@pytest.mark.parametrize("model", ["plane", "grid"])
def test_the_offset_is_measured_at_the_true_map(moved_pair, model):
    left, right, disparity = moved_pair
    params = _params(model=model)
    small_left, small_right, _, _, _ = halved_levels(jnp.asarray(left), jnp.asarray(right), NDISP,
                                                     None, 1)
    small_map = jnp.asarray(disparity[::2, ::2] / 2)
    # At the pair's level, and at the level halved once (the pair, its map and its disparities
    # halved), in the pair's pixels again.
    for images, disparities, limit, scale, atol in [
            ((left, right), disparity, NDISP, 1, 0.06),
            ((small_left, small_right), small_map, NDISP // 2 + 1, 2, 0.08)]:
        coefficients = _coefficients(
            *map(jnp.asarray, images), params, jnp.asarray(disparities),
            jnp.zeros(disparities.shape, bool), limit=limit, scale=scale)
        if model == "plane":
            np.testing.assert_allclose(np.asarray(coefficients), TRUTH, atol=atol)
        # Every pixel's offset within 1.5 atol of the truth (measured: the plane 0.05 and
        # 0.07 px at most, the grid 0.06 and 0.08: its tiles' own departures are noise here).
        assert _largest_error(params, coefficients) < 1.5 * atol


def test_the_grid_follows_a_bent_offset_the_plane_cannot():
    # A bow: the rows sag by 1 px more in the middle columns than at the sides (a lens
    # distortion left by the calibration), over the affine offset.
    u = (np.arange(WIDTH) - (WIDTH - 1) / 2) / WIDTH
    dy = _offsets(TRUTH) + 1.0 * (0.25 - 4 * u[None, :] ** 2) * np.ones((HEIGHT, 1))
    left, right, disparity = _moved_pair(dy=dy)
    errors = {}
    for model in ("plane", "grid"):
        params = _params(model=model, tiles=4)
        coefficients = _coefficients(
            jnp.asarray(left), jnp.asarray(right), params, jnp.asarray(disparity),
            jnp.zeros(disparity.shape, bool), limit=NDISP)
        assert coefficients.shape == ((3,) if model == "plane" else (3 + 16,))
        measured = np.asarray(params.alignment.offset_map(coefficients, disparity.shape))
        # Between the outer tiles' centres (beyond them the grid keeps the edge tiles' values).
        errors[model] = np.mean(np.abs(measured - dy)[12:-12, 16:-16])
    # The plane leaves the bow (0.16 px off on average); the grid follows it to within its
    # bilinear steps and the tiles' own blur (0.10: each tile's mean cost mixes the offsets
    # across it, and the first tile's valid pixels start past its left columns).
    assert errors["grid"] < 0.75 * errors["plane"], errors


def test_the_graph_aligns_then_matches_better(moved_pair):
    left, right, disparity = moved_pair
    params = _params()
    moved, coefficients = align_right(jnp.asarray(left), jnp.asarray(right), params, ndisp=NDISP)
    assert _largest_error(params, coefficients) < 0.12
    aligned = np.asarray(sswjax.match(left, right, NDISP, params=params))
    plain = np.asarray(sswjax.match(left, right, NDISP,
                                    params=sswjax.preset("accurate").replace(alignment=None)))
    inner = (slice(8, -8), slice(28, -8))
    aligned_error = np.abs(aligned - disparity)[inner]
    plain_error = np.abs(plain - disparity)[inner]
    # The texture is strong enough for the plain match to stay within half a pixel almost
    # everywhere (2 % beyond); the offset shows in its precision (median 0.017 against 0.007).
    assert np.median(aligned_error) < 0.5 * np.median(plain_error)
    assert np.mean(aligned_error > 0.1) < 0.9 * np.mean(plain_error > 0.1)


def test_strips_align_once_on_the_whole_pair(moved_pair):
    left, right, _ = moved_pair
    params = _params()
    assert carries_paths(params)  # the method's: the alignment runs before it
    whole = sswjax.match(left, right, NDISP, params=params)
    strips = sswjax.match(left, right, NDISP, params=params,
                          plan=ExecutionPlan(strip_rows=32, strip_overlap=16))
    # The right image is moved once, on the whole pair, and the method's strips carry its
    # paths: the whole pair's map, but for the right image moved apart from the method's
    # program (the same computation compiled apart, under 1e-6 off), which moves 1.7 % of these
    # disparities by at most 0.025 px.
    assert np.abs(strips - whole).max() < 0.1


def test_tiles_run_the_method_on_the_pair_aligned_once():
    """Under tiles, the right image is moved once on the whole pair (:func:`align`, the graph
    :func:`align_right`), then the method's tiles run on it: the maps of the method's tiles on
    that pair, the alignment left out."""
    left, right, _ = _moved_pair()
    params = _params()
    tiles = ExecutionPlan(tile=48, strip_overlap=8)
    padded_left, padded_right, call = graph_call(left, right, NDISP, tiles)
    moved = align(padded_left, padded_right, params=params, call=call)
    np.testing.assert_array_equal(
        moved, np.asarray(align_right(jnp.asarray(left), jnp.asarray(right), params,
                                      ndisp=NDISP)[0]))
    np.testing.assert_array_equal(
        sswjax.match(left, right, NDISP, params=params, plan=tiles),
        sswjax.match(left, moved, NDISP, params=params.replace(alignment=None), plan=tiles))


def test_the_method_refuses_the_alignment_and_composes_after_it_under_vmap(moved_pair):
    left, right, _ = moved_pair
    params = _params()
    with pytest.raises(ValueError, match="params.alignment is a step before the method"):
        ssw_disparity(jnp.asarray(left), jnp.asarray(right), params, ndisp=NDISP)

    # match_batch composes them under jax.vmap as ssw_disparity's docstring shows.
    batched = match_batch(left[None], right[None], NDISP, params=params)
    np.testing.assert_allclose(batched[0], sswjax.match(left, right, NDISP, params=params),
                               atol=0.05)


def test_the_first_pass_is_estimated_as_a_call_of_its_own():
    """The memory model estimates the alignment's first pass (the pair halved, whole) like any
    call: an aligned call needs the larger of it and the method; a limit the method's strips
    fit but the first pass does not is refused in one line that says so."""
    params = sswjax.preset("accurate")
    first = params.alignment.first_pass(params)
    method = estimate_peak_bytes(3000, 4000, 256, params=params.replace(alignment=None),
                                 plan=ExecutionPlan(strip_rows=64))
    alone = estimate_peak_bytes(1500, 2000, 129, params=first)
    aligned = estimate_peak_bytes(3000, 4000, 256, params=params,
                                  plan=ExecutionPlan(strip_rows=64))
    assert alone > method and aligned >= alone
    assert estimate_peak_bytes(3000, 4000, 256, params=params) == estimate_peak_bytes(
        3000, 4000, 256, params=params.replace(alignment=None))  # the method's is larger
    with pytest.raises(MemoryEstimateError, match="the vertical alignment's first pass"):
        check_memory(3000, 4000, 256, params=params, plan=ExecutionPlan(strip_rows=64),
                     limit=(method + alone) / 2)


def test_an_aligned_pair_is_unchanged_when_nothing_is_off():
    rng = np.random.default_rng(1)
    image = gaussian_filter(rng.random((64, 96, 1)), (1.0, 1.0, 0)).astype(np.float32)
    image = (image - image.min()) / np.ptp(image)
    left, right = image[:, :-8], image[:, 8:]  # disparity 8 everywhere, no vertical offset
    coefficients = _coefficients(jnp.asarray(left), jnp.asarray(right), _params(),
                                 jnp.full(left.shape[:2], 8.0), jnp.zeros(left.shape[:2], bool),
                                 limit=12)
    assert np.abs(np.asarray(coefficients)).max() < 0.03


def test_the_first_pass_is_the_whole_volume_method():
    fast = sswjax.preset("fast")
    for checks, expected in [("method", fast.checks), ("none", None),
                             ("left-right", LeftRightCheck(tolerance=fast.checks.tolerance))]:
        first = _params(checks=checks).alignment.first_pass(fast.replace(
            alignment={"kind": "vertical"}))
        assert first.alignment is None and first.smoothing is None and first.coarse is None
        assert first.refinement is None and first.band is None
        assert first.optimizer == fast.optimizer and first.checks == expected


@pytest.mark.parametrize("tiles, levels", [(4, 1), (3, 2), (6, 1)])
def test_a_pair_too_small_for_a_tile_is_not_measured(tiles, levels):
    """``measurable`` bounds from above the valid pixels of ``tile_offsets``' largest tile (its
    weight over a cost curve of curvature 2 at every pixel) for any own size within a padded
    shape: where it says no, no tile reaches the floor."""
    alignment = sswjax.config.VerticalAlignment(tiles=tiles, levels=levels)
    pixels = jax.jit(lambda costs, valid, size: tile_offsets(
        costs, valid, step=1.0, tiles=tiles, min_pixels=1, size=size)[:, 3] / 2)
    for height, width in [(20, 30), (60, 90), (100, 100), (129, 131), (150, 200), (300, 150)]:
        small = [height, width]
        for _ in range(levels):
            small = [(size + 1) // 2 for size in small]
        costs = jnp.broadcast_to(jnp.array([1.0, 0.0, 1.0])[:, None, None], (3, *small))
        largest = 0
        for own in [small, [small[0] - 3, small[1]], [small[0], small[1] - 5],
                    [small[0] - 1, small[1] - 2]]:
            valid = (np.arange(small[0])[:, None] < own[0]) & (np.arange(small[1]) < own[1])
            largest = max(largest, round(float(pixels(costs, valid, jnp.array(own)).max())))
        assert alignment.measurable((height, width)) or largest < alignment.min_pixels
    assert not alignment.measurable((20, 30)) and alignment.measurable((300, 300))


def test_a_pair_too_small_is_matched_unaligned():
    """Below the floor the stage is left out of the graph: the default's map is the unaligned
    method's, exactly, in one call and in strips."""
    left, right, _ = _moved_pair(48, 96)
    params = sswjax.preset("accurate")
    assert not params.alignment.measurable(left.shape[:2])
    plain = sswjax.match(left, right, NDISP, params=params.replace(alignment=None))
    np.testing.assert_array_equal(sswjax.match(left, right, NDISP, params=params), plain)
    strips = ExecutionPlan(strip_rows=24, strip_overlap=8)
    np.testing.assert_array_equal(
        sswjax.match(left, right, NDISP, params=params, plan=strips),
        sswjax.match(left, right, NDISP, params=params.replace(alignment=None), plan=strips))


def test_the_first_pass_runs_under_the_alignments_scope():
    # benchmarks/speed.py counts an operation under its outermost stage: the first pass's paths
    # are the alignment's time, not the method's (docs/limits.md). Only the first pass runs
    # paths inside the alignment, so before its stages were nested there, none were found.
    left, right, _ = _moved_pair(160, 200)
    text = align_right.lower(jnp.asarray(left), jnp.asarray(right), sswjax.preset("accurate"),
                             ndisp=NDISP).as_text(debug_info=True)
    assert "/alignment/optimization/" in text
    assert "/alignment/cost/" in text
