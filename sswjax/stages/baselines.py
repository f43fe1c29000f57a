"""Baseline cost-aggregation filters: box (BOX), bilateral (BF) and median (MF), with guided (GF)
and iterated guided (iGF) in :mod:`sswjax.stages.guided`: the aggregators the SSW paper compares
its segment-side-window aggregation against.

Array conventions (whole module): filtered arrays (cost volumes, cost slices) are float32
``(..., H, W)``; the filters act on the last two axes and treat leading axes (disparities) as a
batch: every slice is filtered with the same guide-derived weights, so a cost volume
``(D, H, W)`` is filtered in one vectorised pass. Guides are the left image, float32
``(H, W, C)`` (or ``(H, W)`` for gray) with values in [0, 1]. Every window is the square
``(2 r + 1) x (2 r + 1)`` centred on the pixel; borders are edge-replicated (each window sum
pads its own input by ``r``), as in :mod:`sswjax.stages.filters`. Outputs are float32 with the shape
of the filtered input.

All functions are pure and ``jax.jit``-able with ``radius`` (and ``iterations``) static; the
other numeric options (``eps``, ``sigma_space``, ``sigma_color``) may be traced scalars. No
``(D, H, W, window)`` tensor is built: box means are separable 1-D window sums, and the
bilateral filter loops over window offsets, accumulating.

Each is a drop-in replacement of the SSW aggregation step through its entry in
:mod:`sswjax.config.aggregation`.
"""

from __future__ import annotations


import jax
import jax.numpy as jnp
import numpy as np

from sswjax._checks import check_guide, check_map, check_positive
from sswjax.stages.filters import channels_first, edge_pad
from sswjax.stages.medians import median_filter

__all__ = ["bilateral_filter", "box_filter", "box_mean", "median_cost_filter"]


# ---------------------------------------------------------------------------------------------
# Entry checks and shared helpers.


def _window_sum_1d(padded: jax.Array, radius: int, axis: int) -> jax.Array:
    """Sums over ``[i - r, i + r]`` along ``axis`` of an array padded by ``r`` at both ends.

    A 1-D ``lax.reduce_window`` sum: the same ``2r + 1`` terms as summing shifted slices (no
    running-sum cancellation), but XLA materialises a reduction once where it re-fuses a sum of
    slices into every consumer: in the colour guided filter each window mean feeds four
    consumers, and shifted slices made it ~3x slower.
    """
    window = [1] * padded.ndim
    window[axis] = 2 * radius + 1
    zero = np.zeros((), padded.dtype)  # concrete: the sum JAX differentiates (a traced init is not)
    strides = (1,) * padded.ndim
    return jax.lax.reduce_window(padded, zero, jax.lax.add, tuple(window), strides, "VALID")


def box_mean(x: jax.Array, radius: int) -> jax.Array:
    """Unchecked box mean of float32 (..., H, W), edge-replicated borders."""
    padded = edge_pad(x, radius)
    rows = _window_sum_1d(padded, radius, x.ndim - 2)
    return _window_sum_1d(rows, radius, x.ndim - 1) / float((2 * radius + 1) ** 2)


# ---------------------------------------------------------------------------------------------
# Box filter.


def box_filter(x: jax.Array, *, radius: int) -> jax.Array:
    """Mean over the ``(2r+1) x (2r+1)`` window of every pixel (BOX aggregation).

    The fixed square-window aggregation of local stereo (Scharstein & Szeliski, "A Taxonomy and
    Evaluation of Dense Two-Frame Stereo Correspondence Algorithms", IJCV 2002). Separable:
    a vertical then a horizontal 1-D sum of ``2r + 1`` samples of the edge-padded input.

    Parameters
    ----------
    x : float32 (..., H, W)
        Cost volume (D, H, W), a single slice, or any batch of maps.
    radius : int >= 1

    Returns
    -------
    float32, shape of ``x``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> x = jnp.zeros((3, 5)).at[1, 2].set(9.0)
    >>> box_filter(x, radius=1)[1].tolist()
    [0.0, 1.0, 1.0, 1.0, 0.0]
    """
    check_map("x", x, radius)
    return box_mean(x.astype(jnp.float32), radius)


# ---------------------------------------------------------------------------------------------
# Bilateral (adaptive support-weight) filter.


def bilateral_filter(
    x: jax.Array,
    guide: jax.Array,
    *,
    radius: int = 4,
    sigma_space=4.5,
    sigma_color=0.03,
) -> jax.Array:
    """Joint bilateral filter of every slice of ``x`` with one guide image (BF aggregation).

    Adaptive support weights of Yoon & Kweon, "Adaptive Support-Weight Approach for
    Correspondence Search", TPAMI 2006, one-sided (weights from the left image only):

        q(p) = sum_q w(p, q) x(q) / sum_q w(p, q),
        w(p, q) = exp(-|p - q|^2 / (2 sigma_space^2) - ||I_p - I_q||^2 / (2 sigma_color^2)),

    over the ``(2r+1) x (2r+1)`` window of ``p``, ``||.||`` Euclidean over the guide channels.
    Computed by looping over the window offsets and accumulating the weighted sum and the
    weight sum (no window axis is materialised). Edge-replicated pixels outside the image take
    the guide and cost of the nearest border pixel.

    Parameters
    ----------
    x : float32 (..., H, W)
        Cost volume (D, H, W) or any batch of maps.
    guide : float32 (H, W, C) or (H, W), values in [0, 1]
    radius : int >= 1
        Window radius (default 4: a 9 x 9 window).
    sigma_space : float > 0 (or traced scalar)
        Spatial Gaussian scale, pixels.
    sigma_color : float > 0 (or traced scalar)
        Colour Gaussian scale, in guide units ([0, 1] intensities).

    Returns
    -------
    float32, shape of ``x``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> guide = jnp.zeros((5, 6, 3)).at[:, 3:].set(1.0)   # colour edge
    >>> cost = jnp.zeros((5, 6)).at[:, 3:].set(1.0)
    >>> q = bilateral_filter(cost, guide, radius=2)
    >>> [round(float(v), 3) for v in q[2]]   # no mixing across the edge
    [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
    """
    check_map("x", x, radius)
    check_guide(guide, x)
    check_positive("sigma_space", sigma_space)
    check_positive("sigma_color", sigma_color)
    r = radius
    height, width = x.shape[-2:]
    g = channels_first(guide.astype(jnp.float32))
    g_padded = edge_pad(g, r)
    x_padded = edge_pad(x.astype(jnp.float32), r)
    space_scale = -0.5 / jnp.square(jnp.asarray(sigma_space, jnp.float32))
    color_scale = -0.5 / jnp.square(jnp.asarray(sigma_color, jnp.float32))
    numerator = jnp.zeros(x.shape, jnp.float32)
    denominator = jnp.zeros((height, width), jnp.float32)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            rows = slice(r + dy, r + dy + height)
            cols = slice(r + dx, r + dx + width)
            neighbour = g_padded[:, rows, cols]
            # Channel sum as explicit adds: an XLA reduce over the channel axis ran 30x slower.
            color_distance = sum(jnp.square(g[c] - neighbour[c]) for c in range(g.shape[0]))
            weight = jnp.exp(space_scale * float(dy * dy + dx * dx) + color_scale * color_distance)
            numerator = numerator + weight * x_padded[..., rows, cols]
            denominator = denominator + weight
    # The centre weight is exp(0) = 1, so the denominator is >= 1.
    return numerator / denominator


# ---------------------------------------------------------------------------------------------
# Median filter.


def median_cost_filter(x: jax.Array, *, radius: int = 2) -> jax.Array:
    """Median of every cost slice over the ``(2r+1) x (2r+1)`` window (MF aggregation).

    The running median (Tukey, "Exploratory Data Analysis", 1977) applied to each disparity
    slice independently, as the MF baseline of the SSW paper; a robust, unguided alternative
    to the box mean. Exact, through :func:`sswjax.stages.medians.median_filter` (sorting network,
    edge-replicated borders).

    Parameters
    ----------
    x : float32 (..., H, W)
    radius : int >= 1

    Returns
    -------
    float32, shape of ``x``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> x = jnp.ones((2, 5, 5)).at[:, 2, 2].set(50.0)   # an outlier on each slice
    >>> float(median_cost_filter(x, radius=1)[1, 2, 2])
    1.0
    """
    check_map("x", x, radius)
    return median_filter(x.astype(jnp.float32), radius=radius)
