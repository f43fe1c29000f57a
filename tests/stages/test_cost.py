"""Tests for sswjax.stages.cost against brute-force NumPy references (tiny arrays, plain loops)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.cost import (
    census_transform,
    hamming_distance,
    matching_cost,
    matching_cost_at,
    matching_features,
    sobel_gradient_magnitude,
)
from sswjax.stages.reference import cost_volume

LUMA = np.array([0.299, 0.587, 0.114])


# ---------------------------------------------------------------------------------------------
# NumPy references


def census_reference(gray: np.ndarray, height: int, width: int) -> np.ndarray:
    """Brute-force census: bit k set when the k-th neighbour (row-major, centre skipped) of the
    height x width window is strictly darker than the centre; edge-replicated borders."""
    h, w = gray.shape
    ry, rx = height // 2, width // 2
    n_bits = height * width - 1
    n_words = -(-n_bits // 32)
    out = np.zeros((n_words, h, w), np.uint64)
    for y in range(h):
        for x in range(w):
            centre = gray[y, x]
            k = 0
            for wy in range(height):
                for wx in range(width):
                    if (wy, wx) == (ry, rx):
                        continue
                    yy = min(max(y + wy - ry, 0), h - 1)
                    xx = min(max(x + wx - rx, 0), w - 1)
                    if gray[yy, xx] < centre:
                        out[k // 32, y, x] |= np.uint64(1) << np.uint64(k % 32)
                    k += 1
            assert k == n_bits
    return out.astype(np.uint32)


def hamming_reference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros(a.shape[1:], np.int64)
    for index in np.ndindex(*a.shape[1:]):
        out[index] = sum(bin(int(a[(k, *index)]) ^ int(b[(k, *index)])).count("1") for k in range(a.shape[0]))
    return out


def sobel_reference(gray: np.ndarray) -> np.ndarray:
    """Sobel magnitude with kernels / 8, edge-replicated, by explicit loops (float64)."""
    h, w = gray.shape
    kx = np.array([[-1, 0, 1], [-2, 0, 2], [-1, 0, 1]], float) / 8  # d/dx, x to the right
    ky = kx.T  # d/dy, y downwards
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            gx = gy = 0.0
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    v = gray[min(max(y + dy, 0), h - 1), min(max(x + dx, 0), w - 1)]
                    gx += kx[dy + 1, dx + 1] * v
                    gy += ky[dy + 1, dx + 1] * v
            out[y, x] = np.hypot(gx, gy)
    return out


def gray_reference(image: np.ndarray) -> np.ndarray:
    return image[..., 0] if image.shape[-1] == 1 else image.astype(np.float32) @ LUMA.astype(np.float32)


def cost_volume_reference(left, right, ndisp, alpha, beta, gamma, tau_c, tau_g, ch, cw):
    """Eq. (5) per disparity, pixel by pixel."""
    h, w, _ = left.shape
    gray_l, gray_r = gray_reference(left), gray_reference(right)
    grad_l, grad_r = sobel_reference(gray_l), sobel_reference(gray_r)
    census_l, census_r = census_reference(gray_l, ch, cw), census_reference(gray_r, ch, cw)
    n_bits = ch * cw - 1
    out = np.zeros((ndisp, h, w))
    for d in range(ndisp):
        for y in range(h):
            for x in range(w):
                if x < d:
                    out[d, y, x] = alpha + beta + gamma
                    continue
                xr = x - d
                tad = np.abs(left[y, x].astype(float) - right[y, xr]).mean()
                gm = abs(grad_l[y, x] - grad_r[y, xr])
                ct = sum(
                    bin(int(census_l[k, y, x]) ^ int(census_r[k, y, xr])).count("1")
                    for k in range(census_l.shape[0])
                )
                out[d, y, x] = (
                    alpha * min(tad, tau_c) / tau_c + beta * min(gm, tau_g) / tau_g + gamma * ct / n_bits
                )
    return out


# ---------------------------------------------------------------------------------------------
# census and Hamming


@pytest.mark.parametrize("height, width", [(3, 3), (7, 9), (5, 7)])
def test_census_transform_matches_brute_force(height, width):
    rng = np.random.default_rng(height * 100 + width)
    gray = rng.random((12, 20)).astype(np.float32)
    # plateaus: equal neighbours must not set a bit ("strictly darker")
    gray[2:5, 3:7] = 0.5
    gray[8, :] = 0.25
    codes = np.asarray(census_transform(jnp.asarray(gray), height=height, width=width))
    reference = census_reference(gray, height, width)
    n_words = -(-(height * width - 1) // 32)
    assert codes.dtype == np.uint32
    assert codes.shape == (n_words, 12, 20)
    np.testing.assert_array_equal(codes, reference)


def test_census_transform_7x9_uses_two_words_and_high_bits():
    # 62 bits: the second word holds bits 32..61; a centre brighter than everything sets all
    gray = np.zeros((9, 11), np.float32)
    gray[4, 5] = 1.0
    codes = np.asarray(census_transform(jnp.asarray(gray), height=7, width=9))
    assert codes.shape == (2, 9, 11)
    assert codes[0, 4, 5] == 0xFFFFFFFF
    assert codes[1, 4, 5] == (1 << 30) - 1
    # a pixel that is darker than nothing has no bit set
    assert codes[:, 0, 0].tolist() == [0, 0]


def test_census_transform_bit_order():
    # 3x3 window: bit k <-> neighbour k in row-major order with the centre skipped
    gray = np.full((3, 3), 0.5, np.float32)
    neighbours = [(0, 0), (0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1), (2, 2)]
    for k, (y, x) in enumerate(neighbours):
        image = gray.copy()
        image[y, x] = 0.1
        code = int(np.asarray(census_transform(jnp.asarray(image), height=3, width=3))[0, 1, 1])
        assert code == 1 << k, (k, code)


def test_hamming_distance_matches_bit_counting():
    rng = np.random.default_rng(1)
    a = rng.integers(0, 2**32, size=(3, 4, 5), dtype=np.uint64).astype(np.uint32)
    b = rng.integers(0, 2**32, size=(3, 4, 5), dtype=np.uint64).astype(np.uint32)
    b[0, 0, 0] = a[0, 0, 0]  # zero distance in one word
    b[:, 1, 1] = ~a[:, 1, 1]  # all 96 bits differ
    ours = np.asarray(hamming_distance(jnp.asarray(a), jnp.asarray(b)))
    reference = hamming_reference(a, b)
    assert ours.shape == (4, 5)
    np.testing.assert_array_equal(ours, reference)
    assert ours[1, 1] == 96


def test_hamming_distance_rejects_non_uint32():
    a = jnp.zeros((1, 2, 2), jnp.int32)
    with pytest.raises(TypeError):
        hamming_distance(a, a)


# ---------------------------------------------------------------------------------------------
# Sobel


def test_sobel_gradient_magnitude_matches_reference():
    rng = np.random.default_rng(2)
    gray = rng.random((12, 20)).astype(np.float32)
    ours = np.asarray(sobel_gradient_magnitude(jnp.asarray(gray)))
    np.testing.assert_allclose(ours, sobel_reference(gray.astype(float)), atol=1e-6, rtol=0)


def test_sobel_gradient_magnitude_of_ramps():
    # unit ramps have magnitude 1 in the interior; the edge-replicated border halves it
    ramp_x = np.tile(np.arange(8.0, dtype=np.float32), (6, 1))
    gx = np.asarray(sobel_gradient_magnitude(jnp.asarray(ramp_x)))
    np.testing.assert_allclose(gx[:, 1:-1], 1.0, atol=1e-6)
    np.testing.assert_allclose(gx[:, [0, -1]], 0.5, atol=1e-6)
    gy = np.asarray(sobel_gradient_magnitude(jnp.asarray(ramp_x.T.copy())))
    np.testing.assert_allclose(gy[1:-1, :], 1.0, atol=1e-6)


# ---------------------------------------------------------------------------------------------
# cost volume


@pytest.fixture(scope="module")
def pair():
    rng = np.random.default_rng(3)
    right = rng.random((10, 16, 3)).astype(np.float32)
    # left = right shifted by 2 plus a little noise: the d = 2 slice has small TAD / GM
    # (below the truncations) while other slices are truncated, so both regimes are tested
    left = np.empty_like(right)
    left[:, 2:] = right[:, :-2]
    left[:, :2] = rng.random((10, 2, 3))
    left = np.clip(left + rng.normal(0, 0.02, left.shape), 0, 1).astype(np.float32)
    return left, right


@pytest.mark.parametrize("census_size", [(7, 9), (3, 5)])
def test_cost_volume_matches_eq5_reference(pair, census_size):
    left, right = pair
    weights = dict(alpha=0.3, beta=0.5, gamma=0.7, tau_c=0.1, tau_g=0.05)
    ours = cost_volume(
        jnp.asarray(left),
        jnp.asarray(right),
        ndisp=5,
        tad_weight=weights["alpha"],
        gradient_weight=weights["beta"],
        census_weight=weights["gamma"],
        tad_truncation=weights["tau_c"],
        gradient_truncation=weights["tau_g"],
        census_height=census_size[0],
        census_width=census_size[1],
    )
    ours = np.asarray(ours)
    reference = cost_volume_reference(left, right, 5, *weights.values(), *census_size)
    assert ours.dtype == np.float32
    assert ours.shape == (5, 10, 16)
    np.testing.assert_allclose(ours, reference, atol=2e-5, rtol=0)
    # the border columns carry alpha + beta + gamma exactly
    for d in range(5):
        np.testing.assert_allclose(ours[d, :, :d], 1.5, atol=1e-6)
    # sanity: the true disparity wins in the interior
    assert (ours[:, :, 4:].argmin(axis=0) == 2).mean() > 0.9


def test_matching_cost_volume_and_traced_block_match_the_reference(pair):
    """A volume of many disparities, and a block starting at a traced disparity, both equal
    the brute-force reference."""
    left, right = pair
    weights = dict(alpha=0.3, beta=0.5, gamma=0.7, tau_c=0.1, tau_g=0.05)
    kw = dict(tad_weight=0.3, gradient_weight=0.5, census_weight=0.7, tad_truncation=0.1,
              gradient_truncation=0.05)
    ndisp = 13
    reference = cost_volume_reference(left, right, ndisp, *weights.values(), 7, 9)
    features = matching_features(jnp.asarray(left), jnp.asarray(right))
    whole = np.asarray(matching_cost(features, 0, ndisp, **kw))
    np.testing.assert_allclose(whole, reference, atol=2e-5, rtol=0)
    block = jax.jit(lambda first: matching_cost(features, first, 3, **kw))(jnp.int32(9))
    np.testing.assert_allclose(np.asarray(block), reference[9:12], atol=2e-5, rtol=0)


def test_matching_cost_at_gathers_the_volume(pair):
    """Each pixel's cost at its own disparity equals the volume's entry, the border included."""
    left, right = pair
    kw = dict(tad_weight=0.3, gradient_weight=0.5, census_weight=0.7, tad_truncation=0.1,
              gradient_truncation=0.05)
    ndisp = 9
    features = matching_features(jnp.asarray(left), jnp.asarray(right))
    volume = np.asarray(matching_cost(features, 0, ndisp, **kw))
    disparity = np.random.default_rng(3).integers(0, ndisp, size=volume.shape[1:])
    ours = np.asarray(matching_cost_at(features, jnp.asarray(disparity, jnp.int32), **kw))
    expected = np.take_along_axis(volume, disparity[None], axis=0)[0]
    np.testing.assert_allclose(ours, expected, atol=1e-6, rtol=0)
    assert (disparity > np.arange(disparity.shape[1])).any()  # border pixels were drawn


def test_matching_cost_at_rejects_a_wrong_shape(pair):
    features = matching_features(jnp.asarray(pair[0]), jnp.asarray(pair[1]))
    kw = dict(tad_weight=1., gradient_weight=1., census_weight=1., tad_truncation=0.1,
              gradient_truncation=0.1)
    with pytest.raises(ValueError, match="disparity must have shape"):
        matching_cost_at(features, jnp.zeros((3, 3), jnp.int32), **kw)


def test_cost_volume_gray_single_channel(pair):
    left, right = (im @ LUMA.astype(np.float32) for im in pair)
    left, right = left[..., None], right[..., None]
    ours = np.asarray(
        cost_volume(
            jnp.asarray(left),
            jnp.asarray(right),
            ndisp=4,
            tad_weight=1.0,
            gradient_weight=0.5,
            census_weight=2.0,
            tad_truncation=0.08,
            gradient_truncation=0.04,
            census_height=3,
            census_width=3,
        )
    )
    reference = cost_volume_reference(left, right, 4, 1.0, 0.5, 2.0, 0.08, 0.04, 3, 3)
    np.testing.assert_allclose(ours, reference, atol=2e-5, rtol=0)


def test_cost_volume_ndisp_equal_to_width_is_allowed():
    image = jnp.asarray(np.random.default_rng(4).random((6, 7, 3)), jnp.float32)
    c = cost_volume(
        image, image, ndisp=7, tad_weight=1.0, gradient_weight=1.0, census_weight=1.0,
        tad_truncation=0.1, gradient_truncation=0.1, census_height=3, census_width=3,
    )
    assert c.shape == (7, 6, 7)
    np.testing.assert_allclose(np.asarray(c)[6, :, :6], 3.0)
    np.testing.assert_allclose(np.asarray(c)[0], 0.0)


# ---------------------------------------------------------------------------------------------
# input checks

COST_KW = dict(tad_weight=1.0, gradient_weight=1.0, census_weight=1.0, tad_truncation=0.1,
               gradient_truncation=0.1, census_height=3, census_width=3)


def test_cost_volume_rejects_mismatched_shapes():
    a = jnp.zeros((6, 8, 3))
    b = jnp.zeros((6, 9, 3))
    with pytest.raises(ValueError, match="same shape"):
        cost_volume(a, b, ndisp=2, **COST_KW)


def test_cost_volume_rejects_two_channel_images():
    a = jnp.zeros((6, 8, 2))
    with pytest.raises(ValueError, match="channels"):
        cost_volume(a, a, ndisp=2, **COST_KW)


def test_cost_volume_rejects_ndisp_larger_than_width():
    a = jnp.zeros((6, 8, 3))
    with pytest.raises(ValueError, match="ndisp"):
        cost_volume(a, a, ndisp=9, **COST_KW)
    with pytest.raises(ValueError, match="ndisp"):
        cost_volume(a, a, ndisp=0, **COST_KW)


@pytest.mark.parametrize("size", [dict(census_height=4), dict(census_width=6)])
def test_cost_volume_rejects_even_census_size(size):
    a = jnp.zeros((8, 10, 3))
    with pytest.raises(ValueError, match="odd"):
        cost_volume(a, a, ndisp=2, **{**COST_KW, **size})


def test_census_transform_rejects_even_size():
    with pytest.raises(ValueError, match="odd"):
        census_transform(jnp.zeros((5, 5)), height=3, width=4)
