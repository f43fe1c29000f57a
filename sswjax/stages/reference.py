"""Reference implementations that the tests check the live stages against, and only the tests.

Each computes in one direct step what the graph computes in folds and blocks: the whole cost
volume (:func:`cost_volume`, where the graph builds blocks with
:func:`~sswjax.stages.cost.matching_cost`), the winner-takes-all and its parabola on a whole
volume (where the graph folds running minima, :func:`~sswjax.stages.selection.fold_winners`),
the right view's cost volume and the left-right check as a mask (where the graph keeps the
distance, :func:`~sswjax.stages.checks.left_right_distance`). Nothing in the package calls
them.

Array conventions (whole module): cost volumes float32 ``(D, H, W)``, lower is better;
disparities ``(H, W)`` in pixels, int32 (winners) or float32; images float32 ``(H, W, C)`` in
[0, 1].
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_floating, check_positive_int, check_rank
from sswjax.stages.cost import check_image, matching_cost, matching_features
from sswjax.stages.checks import left_right_distance
from sswjax.stages.selection import parabola_refine

__all__ = ["cost_volume", "left_right_consistency", "right_cost_volume", "subpixel_parabola",
           "winner_takes_all"]


def winner_takes_all(cost: jax.Array) -> jax.Array:
    """Eq. (8): ``argmin_d cost[d, y, x]`` (the smallest d on ties).

    Parameters
    ----------
    cost : float32 (D, H, W)

    Returns
    -------
    int32 (H, W), in [0, D)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> c = jnp.stack([jnp.full((2, 2), 3.0), jnp.ones((2, 2)), jnp.full((2, 2), 2.0)])
    >>> winner_takes_all(c).tolist()
    [[1, 1], [1, 1]]
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    return jnp.argmin(cost, axis=0).astype(jnp.int32)


def subpixel_parabola(cost: jax.Array, disparity: jax.Array) -> jax.Array:
    """Sub-pixel disparity by a parabola through the costs at ``d-1, d, d+1``.

    ``d + (c[d-1] - c[d+1]) / (2 (c[d-1] - 2 c[d] + c[d+1]))``, the offset clipped to
    [-0.5, 0.5]; at the ends of the range or for a flat/concave fit the offset is 0.

    Parameters
    ----------
    cost : float32 (D, H, W)
    disparity : int32 (H, W), the WTA winners

    Returns
    -------
    float32 (H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.arange(5.0)[:, None, None]
    >>> c = (d - 2.25) ** 2 * jnp.ones((5, 1, 1))        # minimum at 2.25
    >>> float(subpixel_parabola(c, winner_takes_all(c))[0, 0])
    2.25
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    check_rank("disparity", disparity, 2)
    ndisp = cost.shape[0]

    def at(offset):
        index = jnp.clip(disparity + offset, 0, ndisp - 1)[None]
        return jnp.take_along_axis(cost, index, axis=0)[0]

    return parabola_refine(disparity, at(-1), at(0), at(1), ndisp=ndisp)


def cost_volume(
    left: jax.Array,
    right: jax.Array,
    *,
    ndisp: int,
    tad_weight,
    gradient_weight,
    census_weight,
    tad_truncation,
    gradient_truncation,
    census_height: int = 7,
    census_width: int = 9,
) -> jax.Array:
    """Combined matching cost ``C(p, d)`` of Eq. (5) for d = 0 .. ndisp-1.

    ``C = alpha * min(TAD, tau_c) / tau_c + beta * min(GM, tau_g) / tau_g + gamma * CT / n_bits``
    where TAD (Eq. 2) is the channel mean of ``|I_L(p) - I_R(p - d)|``, GM (Eq. 3) the absolute
    difference of Sobel gradient magnitudes, truncated too (an untruncated GM lets outliers
    dominate), and CT (Eq. 4) the Hamming distance of census codes (:func:`matching_features`
    then :func:`matching_cost`).

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    ndisp : int
        Number of disparities, 1 <= ndisp <= W.
    tad_weight, gradient_weight, census_weight : float or scalar array
        alpha, beta, gamma.
    tad_truncation, gradient_truncation : float or scalar array, > 0
        tau_c and tau_g, in intensity units.
    census_height, census_width : int, odd
        Census window.

    Returns
    -------
    float32 (ndisp, H, W), values in [0, alpha + beta + gamma]

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> img = jnp.linspace(0, 1, 4 * 16 * 3).reshape(4, 16, 3)
    >>> c = cost_volume(img, img, ndisp=3, tad_weight=1., gradient_weight=1., census_weight=1.,
    ...                 tad_truncation=0.1, gradient_truncation=0.1)
    >>> c.shape, float(c[0].max())
    ((3, 4, 16), 0.0)
    """
    check_image("left", left)
    check_positive_int("ndisp", ndisp)
    if ndisp > left.shape[1]:
        raise ValueError(f"ndisp must be <= image width {left.shape[1]}, got {ndisp}")
    features = matching_features(left, right, census_height=census_height, census_width=census_width)
    return matching_cost(
        features,
        0,
        ndisp,
        tad_weight=tad_weight,
        gradient_weight=gradient_weight,
        census_weight=census_weight,
        tad_truncation=tad_truncation,
        gradient_truncation=gradient_truncation,
    )


def right_cost_volume(cost: jax.Array, *, disparities: jax.Array | None = None) -> jax.Array:
    """The right view's cost volume from the left one: ``C_R[d, y, x] = C_L[d, y, x + d]``.

    Where ``x + d >= W`` no left pixel matches and the cost is ``+inf``.

    Parameters
    ----------
    cost : float32 (K, H, W)
        Left-view cost slices.
    disparities : int32 (K,), optional
        The disparity of each slice (traced values are fine); default ``arange(K)``.

    Returns
    -------
    float32 (K, H, W)
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    count, _, width = cost.shape
    if disparities is None:
        disparities = jnp.arange(count)
    check_rank("disparities", disparities, 1)
    padded = jnp.pad(cost, ((0, 0), (0, 0), (0, width)), constant_values=jnp.inf)

    def shift_left(slice_, d):
        return lax.dynamic_slice_in_dim(slice_, jnp.clip(d, 0, width), width, axis=1)

    return jax.vmap(shift_left)(padded, disparities)


def left_right_consistency(
    left_disparity: jax.Array, right_disparity: jax.Array, *, tolerance
) -> jax.Array:
    """Left-right check: ``|d_L(x) - d_R(x - round(d_L(x)))| <= tolerance`` and ``x - d_L >= 0``.

    Parameters
    ----------
    left_disparity, right_disparity : float32 or int32 (H, W)
    tolerance : float >= 0, pixels

    Returns
    -------
    bool (H, W), True where the left disparity is confirmed.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> dl = jnp.array([[0, 1, 1, 1]])
    >>> dr = jnp.array([[1, 1, 3, 0]])
    >>> left_right_consistency(dl, dr, tolerance=0).tolist()
    [[False, True, True, False]]
    """
    return left_right_distance(left_disparity, right_disparity) <= tolerance
