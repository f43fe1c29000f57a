"""Baseline cost-aggregation filters: box (BOX), bilateral (BF), guided (GF), iterated guided
(iGF) and median (MF), the aggregators the SSW paper compares its segment-side-window
aggregation against.

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
:data:`sswjax.registry.AGGREGATORS`.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from sswjax._checks import check_floating, check_map, check_positive_int, check_rank
from sswjax.stages.filters import edge_pad, median_filter

__all__ = [
    "bilateral_filter",
    "box_filter",
    "guided_filter",
    "iterated_guided_filter",
    "median_cost_filter",
]


# ---------------------------------------------------------------------------------------------
# Entry checks and shared helpers.


def _check_guide(guide, x, *, channels: tuple[int, ...] | None = None) -> None:
    """Guide: floating (H, W, C) or (H, W), spatial size of ``x``, optionally C in ``channels``."""
    check_rank("guide", guide, (2, 3))
    check_floating("guide", guide)
    if tuple(guide.shape[:2]) != tuple(x.shape[-2:]):
        raise ValueError(
            f"guide size {tuple(guide.shape[:2])} differs from x size {tuple(x.shape[-2:])}"
        )
    num_channels = guide.shape[2] if guide.ndim == 3 else 1
    if channels is not None and num_channels not in channels:
        want = " or ".join(str(c) for c in channels)
        raise ValueError(f"guide must have {want} channels, got shape {tuple(guide.shape)}")


def _check_positive(name: str, value) -> None:
    """Reject non-positive Python numbers; traced or array values pass unchecked."""
    if isinstance(value, (int, float)) and not isinstance(value, bool) and not value > 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")


def _channels_first(guide: jax.Array) -> jax.Array:
    """(H, W, C) or (H, W) -> float32 (C, H, W)."""
    g = guide if guide.ndim == 3 else guide[..., None]
    return jnp.moveaxis(g.astype(jnp.float32), -1, 0)


def _window_sum_1d(padded: jax.Array, radius: int, axis: int) -> jax.Array:
    """Sums over ``[i - r, i + r]`` along ``axis`` of an array padded by ``r`` at both ends.

    A 1-D ``lax.reduce_window`` sum: the same ``2r + 1`` terms as summing shifted slices (no
    running-sum cancellation), but XLA materialises a reduction once where it re-fuses a sum of
    slices into every consumer: in the colour guided filter each window mean feeds four
    consumers, and shifted slices made it ~3x slower.
    """
    window = [1] * padded.ndim
    window[axis] = 2 * radius + 1
    zero = jnp.array(0.0, padded.dtype)
    strides = (1,) * padded.ndim
    return jax.lax.reduce_window(padded, zero, jax.lax.add, tuple(window), strides, "VALID")


def _box_mean(x: jax.Array, radius: int) -> jax.Array:
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
    return _box_mean(x.astype(jnp.float32), radius)


# ---------------------------------------------------------------------------------------------
# Guided filter.


# Orthonormal opponent colour basis: intensity (R+G+B)/sqrt(3) and two chroma differences.
_OPPONENT_BASIS = jnp.array(
    [
        [3**-0.5, 3**-0.5, 3**-0.5],
        [2**-0.5, -(2**-0.5), 0.0],
        [6**-0.5, 6**-0.5, -2 * 6**-0.5],
    ],
    jnp.float32,
)


def _inverse_regularised_covariance(g: jax.Array, mean_g: jax.Array, radius: int, eps):
    """Per-pixel ``(Sigma + eps U)^-1`` of the guide, as a C x C nested list of (H, W) maps.

    C = 1: ``1 / (var + eps)``. C = 3: adjugate over determinant of the symmetric 3 x 3 matrix,
    then one Newton-Schulz step ``X <- X + X (U - M X)``. Where the window's colours lie near
    a line (an edge between two colours) ``M`` is ill-conditioned (cond up to ~tr(Sigma) / eps)
    and the determinant cancels, so the adjugate inverse has float32 errors growing like
    cond^2 u; the refined inverse's grow like cond u, the level already set by the float32
    window moments.
    """
    num_channels = g.shape[0]
    m = {}  # M = Sigma + eps U, symmetric: m[i, j] is m[j, i]
    for i in range(num_channels):
        for j in range(i, num_channels):
            m[i, j] = _box_mean(g[i] * g[j], radius) - mean_g[i] * mean_g[j]
            if i == j:
                m[i, j] = m[i, j] + eps
            m[j, i] = m[i, j]
    if num_channels == 1:
        return [[1.0 / m[0, 0]]]
    # Adjugate (transposed cofactors) of the symmetric M, itself symmetric.
    adj = {
        (0, 0): m[1, 1] * m[2, 2] - m[1, 2] * m[1, 2],
        (0, 1): m[0, 2] * m[1, 2] - m[0, 1] * m[2, 2],
        (0, 2): m[0, 1] * m[1, 2] - m[0, 2] * m[1, 1],
        (1, 1): m[0, 0] * m[2, 2] - m[0, 2] * m[0, 2],
        (1, 2): m[0, 1] * m[0, 2] - m[0, 0] * m[1, 2],
        (2, 2): m[0, 0] * m[1, 1] - m[0, 1] * m[0, 1],
    }
    for i, j in list(adj):
        adj[j, i] = adj[i, j]
    inv_det = 1.0 / (m[0, 0] * adj[0, 0] + m[0, 1] * adj[0, 1] + m[0, 2] * adj[0, 2])
    inverse = [[adj[i, j] * inv_det for j in range(3)] for i in range(3)]
    residual = [
        [float(i == j) - sum(m[i, k] * inverse[k][j] for k in range(3)) for j in range(3)]
        for i in range(3)
    ]
    return [
        [inverse[i][j] + sum(inverse[i][k] * residual[k][j] for k in range(3)) for j in range(3)]
        for i in range(3)
    ]


def _guided_filter_fn(guide: jax.Array, radius: int, eps) -> Callable[[jax.Array], jax.Array]:
    """Precompute the guide statistics once; return ``apply(p)`` filtering (..., H, W) inputs."""
    g = _channels_first(guide)
    # Two changes of guide coordinates that leave q exactly unchanged (in exact arithmetic)
    # but shrink float32 cancellation in the window moments and the 3 x 3 inverse:
    # an orthonormal change of colour basis (Sigma -> Q Sigma Q^T, eps U unchanged, a -> Q a,
    # so a^T I is unchanged) to the opponent basis, where intensity edges (the common
    # near-singular Sigma) are axis-aligned; and centring every channel (b absorbs shifts).
    if g.shape[0] == 3:
        g = jnp.einsum("ij,jhw->ihw", _OPPONENT_BASIS, g)
    g = g - g.mean(axis=(1, 2), keepdims=True)
    channels = range(g.shape[0])
    mean_g = _box_mean(g, radius)  # (C, H, W)
    inverse = _inverse_regularised_covariance(g, mean_g, radius, eps)

    def apply(p: jax.Array) -> jax.Array:
        mean_p = _box_mean(p, radius)
        cov = [_box_mean(g[c] * p, radius) - mean_g[c] * mean_p for c in channels]
        a = [sum(inverse[c][k] * cov[k] for k in channels) for c in channels]
        b = mean_p - sum(a[c] * mean_g[c] for c in channels)
        return sum(_box_mean(a[c], radius) * g[c] for c in channels) + _box_mean(b, radius)

    return apply


def guided_filter(x: jax.Array, guide: jax.Array, *, radius: int = 9, eps=1e-4) -> jax.Array:
    """Guided filter of every slice of ``x`` with one guide image (GF aggregation).

    He, Sun & Tang, "Guided Image Filtering", TPAMI 2013: in each window ``w_k`` the output is
    an affine function of the guide, ``q_i = a_k^T I_i + b_k``, fitted to the input ``p`` by
    ridge regression; ``q`` averages the coefficients of all windows covering ``i``:
    ``q_i = mean(a)_i^T I_i + mean(b)_i``. With a colour guide (Eq. 19-21 of the paper)
    ``a_k = (Sigma_k + eps U)^-1 (mean(I p)_k - mu_k mean(p)_k)`` with ``Sigma_k`` the 3 x 3
    covariance of the guide in ``w_k``, inverted per pixel via adjugate / determinant; with a
    gray guide ``a_k = cov(I, p)_k / (var(I)_k + eps)``. In both, ``b_k = mean(p)_k - a_k^T mu_k``.
    Filtering every disparity slice of a cost volume with the left image as guide is the
    cost-volume filtering of Hosni, Rhemann, Bleyer, Rother & Gelautz, "Fast Cost-Volume
    Filtering for Visual Correspondence and Beyond", TPAMI 2013.

    Borders: the paper normalises the box sums by the number of in-image pixels; we use
    edge-replicated borders (our choice, consistent with the rest of the package), so results
    differ from the paper's within ``radius`` of the image border.

    Precision: float32 throughout. To keep the ill-conditioned colour systems (windows across
    an edge between two colours, cond up to ~tr(Sigma) / eps) accurate, the guide is moved to
    an orthonormal opponent colour basis and centred (both leave the output unchanged in exact
    arithmetic) and the adjugate inverse gets one Newton-Schulz refinement step.

    Parameters
    ----------
    x : float32 (..., H, W)
        Input p: a cost volume (D, H, W) or any batch of maps.
    guide : float32 (H, W, C) or (H, W), C in {1, 3}, values in [0, 1]
        Guide image I (the left image); C = 3 selects the colour guided filter.
    radius : int >= 1
        Window radius r (windows of (2r+1)^2 pixels).
    eps : float > 0 (or traced scalar)
        Regularisation; edges with guide variance well above ``eps`` are preserved.

    Returns
    -------
    float32, shape of ``x``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> guide = jnp.zeros((6, 8, 3)).at[:, 4:].set(1.0)   # vertical colour edge
    >>> cost = jnp.zeros((2, 6, 8)).at[:, :, 4:].set(1.0)  # cost with the same edge
    >>> q = guided_filter(cost, guide, radius=2, eps=1e-4)
    >>> [round(float(v), 3) for v in q[0, 3]]   # the step survives
    [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]
    """
    check_map("x", x, radius)
    _check_guide(guide, x, channels=(1, 3))
    _check_positive("eps", eps)
    return _guided_filter_fn(guide, radius, eps)(x.astype(jnp.float32))


def iterated_guided_filter(
    x: jax.Array, guide: jax.Array, *, radius: int = 9, eps=1e-4, iterations: int = 2
) -> jax.Array:
    """Guided filter applied ``iterations`` times to the cost, the guide fixed (iGF aggregation).

    The SSW paper names an "iGF" baseline without defining it. We read it as iterative guided
    filtering of the cost volume: ``q_0 = x``, ``q_{t+1} = GF_I(q_t)`` with the same left image
    ``I`` as guide in every pass (He, Sun & Tang, "Guided Image Filtering", TPAMI 2013; cost
    volume filtering as in Hosni et al., TPAMI 2013). The guide is not updated (unlike the
    joint side-window filtering of :func:`sswjax.stages.filters.side_window_box_filter`), and its
    statistics are computed once and shared by all passes. ``iterations=1`` is
    :func:`guided_filter`.

    Parameters
    ----------
    x : float32 (..., H, W)
    guide : float32 (H, W, C) or (H, W), C in {1, 3}, values in [0, 1]
    radius : int >= 1
    eps : float > 0 (or traced scalar)
    iterations : int >= 1

    Returns
    -------
    float32, shape of ``x``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> guide = jnp.zeros((6, 8)).at[:, 4:].set(1.0)
    >>> cost = jnp.zeros((6, 8)).at[:, 4:].set(1.0).at[2, 1].set(0.5)   # step + a blip
    >>> q = iterated_guided_filter(cost, guide, radius=1, eps=1e-3, iterations=3)
    >>> [round(float(v), 2) for v in q[2]]   # blip spread out, edge kept
    [0.03, 0.03, 0.03, 0.02, 1.0, 1.0, 1.0, 1.0]
    """
    check_map("x", x, radius)
    _check_guide(guide, x, channels=(1, 3))
    _check_positive("eps", eps)
    check_positive_int("iterations", iterations)
    apply = _guided_filter_fn(guide, radius, eps)
    q = x.astype(jnp.float32)
    for _ in range(iterations):
        q = apply(q)
    return q


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
    _check_guide(guide, x)
    _check_positive("sigma_space", sigma_space)
    _check_positive("sigma_color", sigma_color)
    r = radius
    height, width = x.shape[-2:]
    g = _channels_first(guide)
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
    to the box mean. Exact, through :func:`sswjax.stages.filters.median_filter` (sorting network,
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
