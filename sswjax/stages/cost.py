"""Matching costs of the SSW method (paper Section III-A, Eq. 1-5).

Array conventions (whole module):

- images: float32 ``(H, W, C)`` with C in {1, 3}, intensities in [0, 1]; gray images used by
  the gradient and census terms are float32 ``(H, W)``;
- census codes: uint32 ``(n_words, H, W)``, bit ``k`` of the code set when the k-th neighbour
  (row-major over the window, centre skipped) is darker than the centre;
- cost volumes: float32 ``(D, H, W)``, disparity first; slice ``d`` compares left pixel
  ``(y, x)`` with right pixel ``(y, x - d)``; lower is better.

Each term is normalised to [0, 1] (TAD / tau_c, GM / tau_g, Hamming / number of bits), so the
weights alpha, beta, gamma of Eq. (5) are comparable.

Border rule: where ``x - d < 0`` the right pixel lies outside the image; every term is then set
to its maximum 1, so the combined cost is ``alpha + beta + gamma`` there (no match is possible,
and the value never beats a real match).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_floating, check_positive_int, check_rank, check_same_shape
from sswjax.stages.color import rgb_to_gray

_WORD_BITS = 32


def check_image(name: str, image) -> None:
    check_rank(name, image, 3)
    check_floating(name, image)
    if image.shape[-1] not in (1, 3):
        raise ValueError(f"{name} must have 1 or 3 channels, got shape {tuple(image.shape)}")


def to_gray(image: jax.Array) -> jax.Array:
    """Gray image ``(H, W)`` of an ``(H, W, C)`` image, C in {1, 3} (BT.601 luma for colour)."""
    check_image("image", image)
    return image[..., 0] if image.shape[-1] == 1 else rgb_to_gray(image)


def sobel_gradient_magnitude(gray: jax.Array) -> jax.Array:
    """Sobel gradient magnitude of a gray image (Eq. 3's G), edge-replicated borders.

    The Sobel kernels are scaled by 1/8 so that a unit ramp has gradient 1 per pixel.

    Parameters
    ----------
    gray : float32 (H, W)

    Returns
    -------
    float32 (H, W), >= 0

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> ramp = jnp.tile(jnp.arange(5.0), (4, 1))
    >>> float(sobel_gradient_magnitude(ramp)[2, 2])
    1.0
    """
    check_rank("gray", gray, 2)
    check_floating("gray", gray)
    h, w = gray.shape
    p = jnp.pad(gray, 1, mode="edge")

    def at(dy: int, dx: int) -> jax.Array:
        return p[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]

    gx = (at(-1, 1) + 2 * at(0, 1) + at(1, 1) - at(-1, -1) - 2 * at(0, -1) - at(1, -1)) / 8
    gy = (at(1, -1) + 2 * at(1, 0) + at(1, 1) - at(-1, -1) - 2 * at(-1, 0) - at(-1, 1)) / 8
    return jnp.sqrt(gx * gx + gy * gy)


def census_transform(gray: jax.Array, *, height: int = 7, width: int = 9) -> jax.Array:
    """Census transform (Zabih & Woodfill, ECCV 1994) packed into uint32 words (Eq. 4's xi).

    Bit ``k`` is 1 when the k-th neighbour of the ``height x width`` window (row-major, centre
    skipped) is strictly darker than the centre. Borders are edge-replicated.

    Parameters
    ----------
    gray : float32 (H, W)
    height, width : int, odd
        Window size.

    Returns
    -------
    uint32 (ceil((height * width - 1) / 32), H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> census_transform(jnp.zeros((4, 6)), height=3, width=3).shape
    (1, 4, 6)
    """
    check_rank("gray", gray, 2)
    check_floating("gray", gray)
    for name, size in (("height", height), ("width", width)):
        check_positive_int(name, size)
        if size % 2 == 0:
            raise ValueError(f"census {name} must be odd, got {size}")
    h, w = gray.shape
    ry, rx = height // 2, width // 2
    padded = jnp.pad(gray, ((ry, ry), (rx, rx)), mode="edge")
    offsets = [(dy, dx) for dy in range(height) for dx in range(width) if (dy, dx) != (ry, rx)]
    words = []
    for start in range(0, len(offsets), _WORD_BITS):
        word = jnp.zeros((h, w), jnp.uint32)
        for bit, (dy, dx) in enumerate(offsets[start : start + _WORD_BITS]):
            darker = padded[dy : dy + h, dx : dx + w] < gray
            word = word | (darker.astype(jnp.uint32) << bit)
        words.append(word)
    return jnp.stack(words)


def hamming_distance(codes_a: jax.Array, codes_b: jax.Array) -> jax.Array:
    """Number of differing bits between census codes (Eq. 4's H), summed over words.

    Parameters
    ----------
    codes_a, codes_b : uint32 (n_words, ...)

    Returns
    -------
    int32 (...)
    """
    check_same_shape("codes_a", codes_a, "codes_b", codes_b)
    if codes_a.dtype != jnp.uint32 or codes_b.dtype != jnp.uint32:
        raise TypeError(f"census codes must be uint32, got {codes_a.dtype} and {codes_b.dtype}")
    # Summed word by word: a reduction over the leading (word) axis of a vmapped volume ran
    # as a slow strided reduce on XLA CPU.
    return sum(
        lax.population_count(codes_a[k] ^ codes_b[k]).astype(jnp.int32)
        for k in range(codes_a.shape[0])
    )


class MatchingFeatures(NamedTuple):
    """Per-image features the cost slices compare (computed once per pair).

    Attributes
    ----------
    left, right : float32 (C, H, W)
        Colour channels first.
    gradient_left, gradient_right : float32 (H, W)
        Sobel gradient magnitudes.
    census_left, census_right : uint32 (n_words, H, W)
        Packed census codes.
    n_bits : int
        Census bits (window size - 1).
    """

    left: jax.Array
    right: jax.Array
    gradient_left: jax.Array
    gradient_right: jax.Array
    census_left: jax.Array
    census_right: jax.Array
    n_bits: int


def matching_features(
    left: jax.Array, right: jax.Array, *, census_height: int = 7, census_width: int = 9
) -> MatchingFeatures:
    """Features of a pair for :func:`matching_cost`: colours, Sobel magnitudes, census codes.

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    census_height, census_width : int, odd

    Returns
    -------
    MatchingFeatures
    """
    check_image("left", left)
    check_image("right", right)
    check_same_shape("left", left, "right", right)
    gray_l, gray_r = to_gray(left), to_gray(right)
    return MatchingFeatures(
        left=jnp.moveaxis(left, -1, 0),
        right=jnp.moveaxis(right, -1, 0),
        gradient_left=sobel_gradient_magnitude(gray_l),
        gradient_right=sobel_gradient_magnitude(gray_r),
        census_left=census_transform(gray_l, height=census_height, width=census_width),
        census_right=census_transform(gray_r, height=census_height, width=census_width),
        n_bits=census_height * census_width - 1,
    )


def _pixel_cost(features: MatchingFeatures, colour, gradient, census, *, tad_weight,
                gradient_weight, census_weight, tad_truncation, gradient_truncation) -> jax.Array:
    """Eq. (5) between the left features and right features already moved onto the left
    pixels (``colour`` (C, H, W), ``gradient`` (H, W), ``census`` (n_words, H, W)): float32
    (H, W)."""
    # The channel mean is a sum of per-channel planes: a reduction over the leading channel
    # axis of the vmapped (K, C, H, W) block ran 7x slower on XLA CPU (census words alike).
    channels = features.left.shape[0]
    tad = sum(jnp.abs(features.left[c] - colour[c]) for c in range(channels)) / channels
    gm = jnp.abs(features.gradient_left - gradient)
    ct = hamming_distance(features.census_left, census).astype(jnp.float32)
    return (
        tad_weight * jnp.minimum(tad, tad_truncation) / tad_truncation
        + gradient_weight * jnp.minimum(gm, gradient_truncation) / gradient_truncation
        + census_weight * ct / features.n_bits
    )


def matching_cost_at(
    features: MatchingFeatures,
    disparity: jax.Array,
    *,
    tad_weight,
    gradient_weight,
    census_weight,
    tad_truncation,
    gradient_truncation,
) -> jax.Array:
    """The cost of Eq. (5) of each left pixel at its own disparity: ``C(p, disparity[p])``.

    The same value as ``matching_cost(features, 0, ndisp, ...)[disparity[p], y, x]``, from one
    gather of the right features per pixel instead of a volume.

    Parameters
    ----------
    features : MatchingFeatures
    disparity : int32 (H, W), >= 0
        Integer disparities; where ``x - d < 0`` the cost is the border value
        ``tad_weight + gradient_weight + census_weight``, as in :func:`matching_cost`.
    tad_weight, gradient_weight, census_weight, tad_truncation, gradient_truncation
        As in :func:`cost_volume`.

    Returns
    -------
    float32 (H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> img = jnp.linspace(0, 1, 4 * 16 * 3).reshape(4, 16, 3)
    >>> f = matching_features(img, img)
    >>> w = dict(tad_weight=1., gradient_weight=1., census_weight=1., tad_truncation=0.1,
    ...          gradient_truncation=0.1)
    >>> float(matching_cost_at(f, jnp.zeros((4, 16), jnp.int32), **w).max())
    0.0
    """
    check_rank("disparity", disparity, 2)
    if disparity.shape != features.gradient_left.shape:
        raise ValueError(f"disparity must have shape {features.gradient_left.shape}, got "
                         f"{disparity.shape}")
    height, width = disparity.shape
    source = jnp.arange(width) - disparity
    # One flat gather per feature plane: 5x faster on XLA CPU than take_along_axis's.
    index = (jnp.arange(height)[:, None] * width + jnp.clip(source, 0, width - 1)).reshape(-1)

    def moved(x):
        planes = x.reshape(*x.shape[:-2], height * width)
        return jnp.take(planes, index, axis=-1, mode="clip").reshape(x.shape)

    cost = _pixel_cost(features, moved(features.right), moved(features.gradient_right),
                       moved(features.census_right), tad_weight=tad_weight,
                       gradient_weight=gradient_weight, census_weight=census_weight,
                       tad_truncation=tad_truncation, gradient_truncation=gradient_truncation)
    return jnp.where(source < 0, tad_weight + gradient_weight + census_weight, cost)


def matching_cost(
    features: MatchingFeatures,
    first,
    count: int,
    *,
    tad_weight,
    gradient_weight,
    census_weight,
    tad_truncation,
    gradient_truncation,
) -> jax.Array:
    """Cost slices of Eq. (5) for the consecutive disparities ``first .. first + count - 1``.

    ``jax.vmap`` over the disparities, each slice one dynamic slice of the edge-padded right
    features. (Static slices of one shared window per block were tried: faster alone, but 10 %
    slower end to end once XLA fused the block into its two consumers.)

    Parameters
    ----------
    features : MatchingFeatures
    first : int or int32 scalar, >= 0
        First disparity (traced values are fine).
    count : int
        Number of disparities (static). Disparities ``>= W`` give the border value everywhere.
    tad_weight, gradient_weight, census_weight, tad_truncation, gradient_truncation
        As in :func:`cost_volume`.

    Returns
    -------
    float32 (count, H, W)
    """
    check_positive_int("count", count)
    width = features.left.shape[-1]
    pad = width - 1
    columns = jnp.arange(width)
    # Padded once, outside the vmap: each slice is then one dynamic slice of these.
    padded = [
        jnp.pad(x, [(0, 0)] * (x.ndim - 1) + [(pad, 0)], mode="edge")
        for x in (features.right, features.gradient_right, features.census_right)
    ]

    def shifted(x, d):
        return lax.dynamic_slice_in_dim(x, pad - jnp.minimum(d, pad), width, axis=x.ndim - 1)

    def cost_slice(d):
        cost = _pixel_cost(features, shifted(padded[0], d), shifted(padded[1], d),
                           shifted(padded[2], d), tad_weight=tad_weight,
                           gradient_weight=gradient_weight, census_weight=census_weight,
                           tad_truncation=tad_truncation, gradient_truncation=gradient_truncation)
        return jnp.where(columns < d, tad_weight + gradient_weight + census_weight, cost)

    return jax.vmap(cost_slice)(first + jnp.arange(count)).astype(jnp.float32)


