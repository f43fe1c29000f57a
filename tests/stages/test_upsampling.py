"""Doubling of coarse disparity maps (the coarse-to-fine stage) against a per-pixel reference."""

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.pyramid import halve_image
from sswjax.stages.upsampling import double_nearest, upsample_disparity


def _reference(coarse: np.ndarray, guide: np.ndarray, small: np.ndarray, jump: float) -> np.ndarray:
    """The rule written pixel by pixel: bilinear between the centres (coarse ``i`` at fine
    ``2 i + 0.5``, clamped at the borders) where the four neighbours agree within ``jump``, else
    the neighbour of the nearest mean colour (the first such in row-major order)."""
    height, width = guide.shape[:2]
    h, w = coarse.shape
    out = np.zeros((height, width))
    for y in range(height):
        py = (y + 0.5) / 2 - 0.5
        y0 = int(np.floor(py))
        wy = py - y0
        for x in range(width):
            px = (x + 0.5) / 2 - 0.5
            x0 = int(np.floor(px))
            wx = px - x0
            values, weights, distances = [], [], []
            for cy, fy in ((y0, 1 - wy), (y0 + 1, wy)):
                for cx, fx in ((x0, 1 - wx), (x0 + 1, wx)):
                    cy_, cx_ = min(max(cy, 0), h - 1), min(max(cx, 0), w - 1)
                    values.append(2 * coarse[cy_, cx_])
                    weights.append(fy * fx)
                    distances.append(np.abs(guide[y, x] - small[cy_, cx_]).mean())
            if max(values) - min(values) <= jump:
                out[y, x] = np.dot(values, weights)
            else:
                out[y, x] = values[int(np.argmin(distances))]
    return out


@pytest.mark.parametrize("shape", [(9, 12, 3), (8, 7, 1)])
@pytest.mark.parametrize("jump", [0.0, 3.0, 100.0])
def test_upsample_disparity_matches_the_per_pixel_rule(shape, jump):
    rng = np.random.default_rng(3)
    guide = rng.random(shape, dtype=np.float32)
    small = np.asarray(halve_image(jnp.asarray(guide)))
    coarse = rng.integers(0, 4, small.shape[:2]).astype(np.float32) * rng.choice([0.5, 3.0])
    result = upsample_disparity(jnp.asarray(coarse), jnp.asarray(guide), jnp.asarray(small),
                                jump=jump)
    np.testing.assert_allclose(result, _reference(coarse, guide, small, jump), atol=1e-5)


def test_planes_are_doubled_exactly_inside_the_border():
    yy, xx = np.mgrid[0:10, 0:12].astype(np.float32)
    coarse = 0.3 * xx - 0.2 * yy + 5.0  # in coarse pixels, centres at fine 2 i + 0.5
    guide = np.random.default_rng(0).random((20, 24, 3), dtype=np.float32)
    fine = upsample_disparity(jnp.asarray(coarse), jnp.asarray(guide),
                              halve_image(jnp.asarray(guide)), jump=4.0)
    fy, fx = np.mgrid[0:20, 0:24]
    expected = 2 * (0.3 * ((fx + 0.5) / 2 - 0.5) - 0.2 * ((fy + 0.5) / 2 - 0.5) + 5.0)
    np.testing.assert_allclose(fine[1:-1, 1:-1], expected[1:-1, 1:-1], atol=1e-4)


def test_a_depth_edge_inside_a_coarse_pixel_follows_the_fine_colour():
    # Fine columns 0-4 are dark at disparity 10, columns 5-11 bright at 2: the edge falls
    # inside coarse pixel 2 (fine columns 4 and 5).
    guide = np.zeros((4, 12, 1), np.float32)
    guide[:, 5:] = 1.0
    fine_truth = np.where(np.arange(12) < 5, 10.0, 2.0)
    small = halve_image(jnp.asarray(guide))
    coarse = np.tile(np.where(np.arange(6) < 2, 5.0, 1.0), (2, 1)).astype(np.float32)
    fine = upsample_disparity(jnp.asarray(coarse), jnp.asarray(guide), small, jump=1.0)
    # Column 4 (dark) takes the dark neighbour's 10 though its own coarse pixel says 2.
    np.testing.assert_allclose(fine[0], fine_truth)


def test_sizes_and_ranks_are_checked():
    guide = jnp.zeros((8, 10, 3))
    with pytest.raises(ValueError, match="must be 4 x 5"):
        upsample_disparity(jnp.zeros((4, 4)), guide, halve_image(guide), jump=1.0)
    with pytest.raises(ValueError, match="rank"):
        upsample_disparity(jnp.zeros((4, 5, 1)), guide, halve_image(guide), jump=1.0)
    with pytest.raises(ValueError, match="same channels"):
        upsample_disparity(jnp.zeros((4, 5)), guide, jnp.zeros((4, 5, 1)), jump=1.0)


def test_double_nearest_repeats_each_coarse_pixel():
    values = jnp.arange(6).reshape(2, 3)
    np.testing.assert_array_equal(double_nearest(values, shape=(3, 5)),
                                  [[0, 0, 1, 1, 2], [0, 0, 1, 1, 2], [3, 3, 4, 4, 5]])
