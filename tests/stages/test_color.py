"""Tests for sswjax.stages.color against scikit-image and NumPy references."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from skimage import color as skcolor
from skimage import data

from sswjax.stages.color import rgb_to_gray, rgb_to_lab


@pytest.fixture(scope="module")
def random_rgb():
    rng = np.random.default_rng(0)
    image = rng.uniform(0.0, 1.0, size=(32, 48, 3)).astype(np.float32)
    # Include the extremes and values around the sRGB / CIE linear-segment thresholds.
    image[0, :6] = [[0, 0, 0], [1, 1, 1], [0.04, 0.04, 0.04], [0.05, 0.0, 1.0], [1, 0, 0], [0, 0, 1]]
    image[1, :3] = [[0.001, 0.002, 0.003], [0.0404, 0.0405, 0.0406], [0.5, 0.5, 0.5]]
    return image


def test_rgb_to_lab_matches_skimage_random(random_rgb):
    ours = np.asarray(rgb_to_lab(jnp.asarray(random_rgb)))
    reference = skcolor.rgb2lab(random_rgb.astype(np.float64))
    assert ours.dtype == np.float32
    assert ours.shape == random_rgb.shape
    np.testing.assert_allclose(ours, reference, atol=1e-3, rtol=0)


def test_rgb_to_lab_matches_skimage_real_image():
    image = (data.astronaut()[::4, ::4] / 255.0).astype(np.float32)
    ours = np.asarray(jax.jit(rgb_to_lab)(jnp.asarray(image)))
    np.testing.assert_allclose(ours, skcolor.rgb2lab(image.astype(np.float64)), atol=1e-3, rtol=0)


def test_rgb_to_lab_white_and_black():
    lab = np.asarray(rgb_to_lab(jnp.asarray([[[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]]])))
    # a*, b* of white are ~5e-3, not 0: the sRGB matrix rows do not sum exactly to D65
    # (scikit-image gives the same values).
    np.testing.assert_allclose(lab[0, 0], [100.0, 0.0, 0.0], atol=1e-2)
    np.testing.assert_allclose(lab[0, 1], [0.0, 0.0, 0.0], atol=1e-3)


def test_rgb_to_lab_gradient_is_finite(random_rgb):
    gradient = jax.grad(lambda image: jnp.sum(rgb_to_lab(image)))(jnp.asarray(random_rgb))
    assert np.all(np.isfinite(np.asarray(gradient)))


def test_rgb_to_gray_bt601(random_rgb):
    ours = np.asarray(jax.jit(rgb_to_gray)(jnp.asarray(random_rgb)))
    reference = random_rgb @ np.array([0.299, 0.587, 0.114])
    assert ours.shape == random_rgb.shape[:2]
    assert ours.dtype == np.float32
    np.testing.assert_allclose(ours, reference, atol=1e-6)


def test_rgb_to_gray_passes_gray_through(random_rgb):
    gray = random_rgb[..., 0]
    np.testing.assert_array_equal(np.asarray(rgb_to_gray(jnp.asarray(gray))), gray)


@pytest.mark.parametrize(
    ("function", "bad_image", "error"),
    [
        (rgb_to_lab, np.zeros((4, 4), np.float32), ValueError),
        (rgb_to_lab, np.zeros((4, 4, 4), np.float32), ValueError),
        (rgb_to_lab, np.zeros((4, 4, 3), np.uint8), TypeError),
        (rgb_to_gray, np.zeros((4,), np.float32), ValueError),
        (rgb_to_gray, np.zeros((4, 4, 2), np.float32), ValueError),
        (rgb_to_gray, np.zeros((4, 4, 3), np.int32), TypeError),
    ],
)
def test_entry_checks(function, bad_image, error):
    with pytest.raises(error):
        function(bad_image)
