"""Tests for sswjax.stages.preprocess against a float64 NumPy reference."""

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.preprocess import local_contrast_normalization


def lcn_reference(image, radius, eps):
    padded = np.pad(image.astype(np.float64), ((radius, radius), (radius, radius), (0, 0)), mode="edge")
    out = np.zeros(image.shape)
    height, width = image.shape[:2]
    for y in range(height):
        for x in range(width):
            window = padded[y : y + 2 * radius + 1, x : x + 2 * radius + 1]
            mean, std = window.mean(axis=(0, 1)), window.std(axis=(0, 1))
            out[y, x] = 0.5 * (1 + np.tanh(0.5 * (image[y, x] - mean) / (std + eps)))
    return out


@pytest.mark.parametrize("channels", [1, 3])
def test_matches_reference(channels):
    image = np.random.default_rng(channels).random((9, 11, channels)).astype(np.float32)
    ours = local_contrast_normalization(jnp.asarray(image), radius=2, eps=0.02)
    assert ours.shape == image.shape and ours.dtype == jnp.float32
    np.testing.assert_allclose(ours, lcn_reference(image, 2, 0.02), atol=1e-4)


def test_dark_and_bright_textures_look_alike():
    texture = np.random.default_rng(0).random((16, 16, 1)).astype(np.float32)
    dark = local_contrast_normalization(jnp.asarray(0.05 * texture), radius=3, eps=1e-4)
    bright = local_contrast_normalization(jnp.asarray(0.5 + 0.5 * texture), radius=3, eps=1e-4)
    assert float(jnp.abs(dark - bright).max()) < 0.01
    assert 0.0 <= float(dark.min()) and float(dark.max()) <= 1.0


def test_entry_checks():
    with pytest.raises(ValueError, match="rank"):
        local_contrast_normalization(jnp.zeros((4, 4)))
    with pytest.raises(TypeError, match="floating"):
        local_contrast_normalization(jnp.zeros((4, 4, 1), jnp.int32))
    with pytest.raises(ValueError, match="radius"):
        local_contrast_normalization(jnp.zeros((4, 4, 1)), radius=0)
