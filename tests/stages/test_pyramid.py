"""Halving and doubling of images and volumes, and the half-resolution SGM built on them."""

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.pyramid import double_volume, halve_image, halve_volume
from sswjax.stages.cross_scale import half_resolution_semi_global
from sswjax.stages.sgm import semi_global


def _block_mean(x: np.ndarray, axes) -> np.ndarray:
    """Reference: edge-pad odd axes, then the mean of each 2-block along ``axes``."""
    pad = [(0, x.shape[a] % 2 if a in axes else 0) for a in range(x.ndim)]
    x = np.pad(x, pad, mode="edge")
    for a in axes:
        shape = list(x.shape)
        shape[a:a + 1] = [shape[a] // 2, 2]
        x = x.reshape(shape).mean(axis=a + 1)
    return x


@pytest.mark.parametrize("shape", [(6, 8, 3), (7, 5, 1)])
def test_halve_image_is_the_mean_of_2x2_blocks(shape):
    image = np.random.default_rng(0).random(shape, dtype=np.float32)
    np.testing.assert_allclose(halve_image(jnp.asarray(image)), _block_mean(image, (0, 1)),
                               rtol=1e-6)


def test_halve_volume_is_the_mean_of_2x2x2_blocks():
    cost = np.random.default_rng(1).random((5, 7, 6), dtype=np.float32)
    np.testing.assert_allclose(halve_volume(jnp.asarray(cost)), _block_mean(cost, (0, 1, 2)),
                               rtol=1e-6)


def test_double_volume_keeps_constants_and_is_linear_between_centres():
    coarse = jnp.asarray(np.full((2, 3, 4), 0.7, np.float32))
    np.testing.assert_allclose(double_volume(coarse, shape=(3, 5, 8)), 0.7, rtol=1e-6)
    ramp = jnp.arange(4.0).reshape(1, 1, 4)  # coarse centres at fine 0.5, 2.5, 4.5, 6.5
    fine = double_volume(ramp, shape=(2, 2, 8))
    np.testing.assert_allclose(fine[0, 0], [0, 0.25, 0.75, 1.25, 1.75, 2.25, 2.75, 3.0])


def test_double_volume_rejects_a_shape_it_does_not_halve():
    with pytest.raises(ValueError, match="does not halve"):
        double_volume(jnp.ones((2, 3, 4)), shape=(4, 8, 8))


def test_half_resolution_sgm_equals_its_definition():
    rng = np.random.default_rng(2)
    cost = jnp.asarray(rng.random((8, 10, 12), dtype=np.float32))
    guide = jnp.asarray(rng.random((10, 12, 3), dtype=np.float32))
    out = half_resolution_semi_global(cost, guide, p1=0.1, p2=0.5, sigma=0.05, paths=4,
                                      detail_weight=0.5)
    coarse = semi_global(halve_volume(cost), halve_image(guide), p1=0.1, p2=0.5, sigma=0.05,
                         paths=4)
    expected = 0.5 * cost + double_volume(coarse, shape=cost.shape)
    np.testing.assert_allclose(out, expected, rtol=1e-5, atol=1e-5)
