"""The checks of a disparity map (paper Section III-D, Eq. 9): the left-right distance and the
uniqueness test.

Array conventions (whole module): cost volumes float32 ``(D, H, W)`` (slice ``d`` pairs left
``(y, x)`` with right ``(y, x - d)``); disparity maps float32 or int32 ``(H, W)`` in pixels;
validity masks bool ``(H, W)``. What the checks reject is filled by :mod:`sswjax.stages.background`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax._checks import check_rank, check_same_shape


def left_right_distance(left_disparity: jax.Array, right_disparity: jax.Array) -> jax.Array:
    """``|d_L(x) - d_R(x - round(d_L(x)))|``, ``+inf`` where ``x - round(d_L(x)) < 0``.

    Parameters
    ----------
    left_disparity, right_disparity : float32 or int32 (H, W)

    Returns
    -------
    float32 (H, W), pixels

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> left_right_distance(jnp.array([[1, 1, 2, 0]]), jnp.array([[1, 1, 3, 0]])).tolist()
    [[inf, 0.0, 1.0, 0.0]]
    """
    check_rank("left_disparity", left_disparity, 2)
    check_same_shape("left_disparity", left_disparity, "right_disparity", right_disparity)
    width = left_disparity.shape[1]
    columns = jnp.arange(width)[None, :]
    target = columns - jnp.round(left_disparity).astype(jnp.int32)
    matched = jnp.take_along_axis(right_disparity, jnp.clip(target, 0, width - 1), axis=1)
    distance = jnp.abs(left_disparity.astype(jnp.float32) - matched.astype(jnp.float32))
    return jnp.where(target >= 0, distance, jnp.inf)


def uniqueness_violations(disparity: jax.Array, cost: jax.Array, *, gap: int) -> jax.Array:
    """Pixels whose right-image match is claimed more cheaply by a pixel of another surface.

    Left pixels ``p`` and ``q`` of one row claim the same right pixel when
    ``x_p - d_p = x_q - d_q``; one point of the right image cannot be both. Where the claims'
    disparities differ by ``gap`` or more (two surfaces, not the compressed pixels of one
    slanted surface), the claim with the larger matching cost loses. Every pixel claims, valid
    or not. Occluded pixels that took the foreground's disparity pass the left-right check when
    the right view is derived from the left volume (both inherit its fattening), but their cost
    before aggregation, against a right pixel of another surface, is high.

    This is the uniqueness constraint of Marr & Poggio (Science 1976) used as an occlusion
    test; which claim wins is our choice (the cost before aggregation, where fattening has not
    spread the foreground's match), and each claim is compared with its right pixel's winner
    only.

    Parameters
    ----------
    disparity : int32 (H, W)
        Integer disparities of the left view (winner-takes-all).
    cost : float32 (H, W)
        Each pixel's matching cost at its disparity (before aggregation, e.g.
        :func:`sswjax.stages.cost.matching_cost_at`).
    gap : int >= 1, keyword-only
        Smallest disparity difference between claims that are resolved.

    Returns
    -------
    bool (H, W): True where the pixel's claim loses.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.array([[0, 0, 0, 3, 3, 3]])  # x=0 with 0 and x=3 with 3 claim right pixel 0
    >>> uniqueness_violations(d, jnp.array([[0.1, 0., 0., 0.5, 0., 0.]]), gap=2).tolist()
    [[False, False, False, True, False, False]]
    """
    check_rank("disparity", disparity, 2)
    check_same_shape("disparity", disparity, "cost", cost)
    if isinstance(gap, bool) or not isinstance(gap, int) or gap < 1:
        raise ValueError(f"gap must be an integer >= 1, got {gap!r}")
    height, width = disparity.shape
    target = jnp.arange(width)[None, :] - disparity
    # One flat index per (row, right column); claims outside the right image are dropped.
    flat = jnp.where(target >= 0, jnp.arange(height)[:, None] * width + target, height * width)
    cost = cost.astype(jnp.float32)
    best = jnp.full(height * width, jnp.inf, jnp.float32).at[flat].min(cost, mode="drop")
    best_at = best.at[flat].get(mode="fill", fill_value=jnp.inf)
    # The winner's disparity (ties: the largest), read back at each claimant.
    winner = jnp.full(height * width, -1, disparity.dtype).at[
        jnp.where(cost <= best_at, flat, height * width)].max(disparity, mode="drop")
    winner_at = winner.at[flat].get(mode="fill", fill_value=-1)
    return (cost > best_at) & (jnp.abs(winner_at - disparity) >= gap) & (winner_at >= 0)
