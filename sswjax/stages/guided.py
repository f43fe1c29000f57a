"""The guided filter (He, Sun & Tang, "Guided Image Filtering", TPAMI 2013) and its iterated
form: the GF and iGF baselines of the paper's Table 1, and the weights of the weighted-median
fill (:mod:`sswjax.stages.fill`).

Array conventions (whole module): filtered arrays are float32 ``(..., H, W)``, leading axes a
batch sharing the guide's statistics; guides are the left image, float32 ``(H, W, C)`` (C in
{1, 3}) or ``(H, W)`` in [0, 1]; borders edge-replicated, as in :mod:`sswjax.stages.baselines`.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from sswjax._checks import check_guide, check_map, check_positive, check_positive_int
from sswjax.stages.baselines import box_mean
from sswjax.stages.filters import channels_first

__all__ = ["guided_filter", "guided_filter_fn", "iterated_guided_filter"]


# Orthonormal opponent colour basis: intensity (R+G+B)/sqrt(3) and two chroma differences. A
# NumPy constant: a JAX array here would start the backend when the package is imported.
_OPPONENT_BASIS = np.array(
    [
        [3**-0.5, 3**-0.5, 3**-0.5],
        [2**-0.5, -(2**-0.5), 0.0],
        [6**-0.5, 6**-0.5, -2 * 6**-0.5],
    ],
    np.float32,
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
            m[i, j] = box_mean(g[i] * g[j], radius) - mean_g[i] * mean_g[j]
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


def guided_filter_fn(guide: jax.Array, radius: int, eps) -> Callable[[jax.Array], jax.Array]:
    """Precompute the guide statistics once; return ``apply(p)`` filtering (..., H, W) inputs."""
    g = channels_first(guide.astype(jnp.float32))
    # Two changes of guide coordinates that leave q exactly unchanged (in exact arithmetic)
    # but shrink float32 cancellation in the window moments and the 3 x 3 inverse:
    # an orthonormal change of colour basis (Sigma -> Q Sigma Q^T, eps U unchanged, a -> Q a,
    # so a^T I is unchanged) to the opponent basis, where intensity edges (the common
    # near-singular Sigma) are axis-aligned; and centring every channel (b absorbs shifts).
    if g.shape[0] == 3:
        g = jnp.einsum("ij,jhw->ihw", _OPPONENT_BASIS, g)
    g = g - g.mean(axis=(1, 2), keepdims=True)
    channels = range(g.shape[0])
    mean_g = box_mean(g, radius)  # (C, H, W)
    inverse = _inverse_regularised_covariance(g, mean_g, radius, eps)

    def apply(p: jax.Array) -> jax.Array:
        mean_p = box_mean(p, radius)
        cov = [box_mean(g[c] * p, radius) - mean_g[c] * mean_p for c in channels]
        a = [sum(inverse[c][k] * cov[k] for k in channels) for c in channels]
        b = mean_p - sum(a[c] * mean_g[c] for c in channels)
        return sum(box_mean(a[c], radius) * g[c] for c in channels) + box_mean(b, radius)

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
    check_guide(guide, x, channels=(1, 3))
    check_positive("eps", eps)
    return guided_filter_fn(guide, radius, eps)(x.astype(jnp.float32))


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
    check_guide(guide, x, channels=(1, 3))
    check_positive("eps", eps)
    check_positive_int("iterations", iterations)
    apply = guided_filter_fn(guide, radius, eps)
    q = x.astype(jnp.float32)
    for _ in range(iterations):
        q = apply(q)
    return q
