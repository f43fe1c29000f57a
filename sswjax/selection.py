"""Disparity selection (paper Section III-C, Eq. 8): winner-takes-all and its refinements.

Array conventions (whole module): aggregated cost volumes are float32 ``(D, H, W)``, lower is
better; disparity maps are float32 ``(H, W)`` in pixels (integer-valued from WTA).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax._checks import check_floating, check_rank


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


def parabola_refine(disparity, before, centre, after, *, ndisp: int) -> jax.Array:
    """Sub-pixel disparity from the costs at ``d - 1``, ``d`` and ``d + 1`` of each winner ``d``.

    The rule of :func:`subpixel_parabola`, for callers that tracked the three costs themselves
    (the chunked pipeline).

    Parameters
    ----------
    disparity : int32 (H, W)
    before, centre, after : float32 (H, W)
    ndisp : int
        Size of the disparity range (winners at 0 and ndisp - 1 are not moved).

    Returns
    -------
    float32 (H, W)
    """
    check_rank("disparity", disparity, 2)
    curvature = before - 2 * centre + after
    inside = (disparity > 0) & (disparity < ndisp - 1) & (curvature > 0)
    offset = jnp.where(inside, (before - after) / (2 * jnp.where(inside, curvature, 1.0)), 0.0)
    return disparity.astype(jnp.float32) + jnp.clip(offset, -0.5, 0.5)


def soft_argmin(cost: jax.Array, *, temperature) -> jax.Array:
    """Differentiable WTA: ``sum_d d * softmax(-cost / temperature)[d]`` (Kendall et al. 2017).

    Parameters
    ----------
    cost : float32 (D, H, W)
    temperature : float > 0
        Tends to WTA as it tends to 0.

    Returns
    -------
    float32 (H, W)
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    weights = jax.nn.softmax(-cost / temperature, axis=0)
    d = jnp.arange(cost.shape[0], dtype=cost.dtype)[:, None, None]
    return (weights * d).sum(axis=0)
