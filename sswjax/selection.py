"""Disparity selection (paper Section III-C, Eq. 8): winner-takes-all and its refinements.

Array conventions (whole module): aggregated cost volumes are float32 ``(D, H, W)``, lower is
better; disparity maps are float32 ``(H, W)`` in pixels (integer-valued from WTA).
"""

from __future__ import annotations

from typing import NamedTuple

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


class Winners(NamedTuple):
    """Running winner-takes-all state of both views over disparity slices.

    Left view, float32/int32 ``(H, W)``: ``disparity`` (int32) and ``cost`` of the best slice
    so far, ``before``/``after`` the costs at ``disparity -/+ 1`` (for the parabola). Right
    view, ``C_R(x, d) = C(x + d, d)``: ``right_disparity`` (int32) and ``right_cost``, stored
    *skewed* as ``(H, W + P)`` arrays (P = number of disparities to fold): after ``n`` slices,
    column ``x'`` holds right pixel ``x' - (n - 1)``. Advancing one disparity is then a
    one-column shift, so every update is element-wise and XLA fuses the whole fold into one
    pass; :func:`right_winners` undoes the skew.
    """

    disparity: jax.Array
    cost: jax.Array
    before: jax.Array
    after: jax.Array
    right_disparity: jax.Array
    right_cost: jax.Array


def no_winners(shape: tuple[int, int], *, ndisp: int) -> Winners:
    """The state before any slice (costs ``+inf``, disparities 0) for ``ndisp`` slices to come."""
    height, width = shape
    zeros, inf = jnp.zeros(shape, jnp.int32), jnp.full(shape, jnp.inf, jnp.float32)
    skewed = (height, width + ndisp)
    return Winners(zeros, inf, inf, inf, jnp.zeros(skewed, jnp.int32),
                   jnp.full(skewed, jnp.inf, jnp.float32))


def right_winners(state: Winners) -> tuple[jax.Array, jax.Array]:
    """The right view's ``(disparity int32 (H, W), cost float32 (H, W))`` once all P slices
    announced to :func:`no_winners` are folded."""
    width = state.disparity.shape[1]
    offset = state.right_cost.shape[1] - width - 1
    return (state.right_disparity[:, offset : offset + width],
            state.right_cost[:, offset : offset + width])


def fold_winners(state: Winners, slices: jax.Array, first, *, limit, origin: int = 0) -> Winners:
    """Fold cost slices for disparities ``first - 1 .. first + K`` into the running winners.

    Eq. (8) for both views at once: an unrolled chain of element-wise minimums over the K core
    slices, which XLA fuses into one pass, where ``argmin`` over the disparity axis (a
    reduction over a major axis) measured 6x slower on CPU. Ties keep the smaller disparity, as
    ``argmin`` does. ``slices[0]`` and ``slices[-1]`` are a halo, used only for
    ``before``/``after``. Slices must be folded in increasing disparity order, each once, for
    the right view's skew (see :class:`Winners`).

    Parameters
    ----------
    state : Winners
    slices : float32 (K + 2, H, W)
        Cost of the left view at disparities ``first - 1 .. first + K``.
    first : int or int32 scalar
        Disparity of ``slices[1]`` (traced values are fine).
    limit : int or int32 scalar
        Disparities outside ``[0, limit)`` count as ``+inf``.
    origin : int
        The disparity of the first slice ever folded into this state (static; negative when
        the caller starts with empty, out-of-range slices).

    Returns
    -------
    Winners

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> c = jnp.stack([jnp.full((1, 3), v) for v in (3.0, 1.0, 2.0)])
    >>> w = fold_winners(no_winners((1, 3), ndisp=3), jnp.concatenate([c[:1], c, c[-1:]]), 0, limit=3)
    >>> w.disparity.tolist(), float(w.before[0, 0]), float(w.after[0, 0])
    ([[1, 1, 1]], 3.0, 2.0)
    """
    check_rank("slices", slices, 3)
    check_floating("slices", slices)
    count = slices.shape[0] - 2
    if count < 1:
        raise ValueError(f"need at least 3 slices (one core slice and two halo), got {count + 2}")
    extra = state.right_cost.shape[1] - slices.shape[2]
    if not 0 <= -origin <= extra:
        raise ValueError(f"origin must be in [{-extra}, 0], got {origin}")
    planes = [
        jnp.where((first - 1 + k >= 0) & (first - 1 + k < limit), slices[k], jnp.inf)
        for k in range(count + 2)
    ]
    s = state
    for k in range(1, count + 1):
        d, cost = first + k - 1, planes[k]
        better = cost < s.cost
        # Right view, skewed: shift the state one column; the n-th folded slice (d = origin + n)
        # puts right pixel x_r's candidate C(x_r + d, d) at column x' = x_r + n.
        right_cost = jnp.pad(s.right_cost[:, :-1], ((0, 0), (1, 0)), constant_values=jnp.inf)
        right_disparity = jnp.pad(s.right_disparity[:, :-1], ((0, 0), (1, 0)))
        candidate = jnp.pad(cost, ((0, 0), (-origin, extra + origin)), constant_values=jnp.inf)
        right_better = candidate < right_cost
        s = Winners(
            disparity=jnp.where(better, d, s.disparity).astype(jnp.int32),
            cost=jnp.where(better, cost, s.cost),
            before=jnp.where(better, planes[k - 1], s.before),
            after=jnp.where(better, planes[k + 1], s.after),
            right_disparity=jnp.where(right_better, d, right_disparity).astype(jnp.int32),
            right_cost=jnp.where(right_better, candidate, right_cost),
        )
    return s


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
