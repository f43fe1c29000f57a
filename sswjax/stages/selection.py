"""Disparity selection (paper Section III-C, Eq. 8): winner-takes-all and its refinements.

Array conventions (whole module): aggregated cost volumes are float32 ``(D, H, W)``, lower is
better; disparity maps are float32 ``(H, W)`` in pixels (integer-valued from WTA).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_floating, check_rank


class Winners(NamedTuple):
    """Running winner-takes-all state of both views over disparity slices (all arrays (H, W)).

    ``disparity``/``cost``: the left view's best disparity (int32) and its cost; ``before`` and
    ``after``: the costs at ``disparity - 1`` and ``+ 1`` (for the parabola); ``right_disparity``
    and ``right_cost``: the same minimum for the right view, ``C_R(x, d) = C(x + d, d)``;
    ``second``: the smallest cost of the left view at a disparity not adjacent to the winner
    (``|d - disparity| > 1``), the runner-up of the confidence measures
    (:mod:`sswjax.stages.confidence`).
    """

    disparity: jax.Array
    cost: jax.Array
    before: jax.Array
    after: jax.Array
    right_disparity: jax.Array
    right_cost: jax.Array
    second: jax.Array


def no_winners(shape: tuple[int, int]) -> Winners:
    """The state before any slice: every cost ``+inf``, every disparity 0."""
    zeros, inf = jnp.zeros(shape, jnp.int32), jnp.full(shape, jnp.inf, jnp.float32)
    return Winners(zeros, inf, inf, inf, zeros, inf, inf)


def fold_winners(state: Winners, slices, first, *, limit) -> Winners:
    """Fold cost slices for disparities ``first - 1 .. first + K`` into the running winners.

    Eq. (8) for both views at once, as unrolled chains of element-wise minimums over the K core
    slices, which XLA fuses into single passes (``argmin`` over the disparity axis, a reduction
    over a major axis, measured 6x slower on CPU); the right view by :func:`fold_right_view`.
    Ties keep the smaller disparity, as ``argmin`` does.
    ``slices[0]`` and ``slices[-1]`` are a halo, used only for ``before``/``after``.

    The runner-up ``second`` needs the slices in increasing disparity over successive calls
    (as every caller folds them): then a disparity adjacent to the winner can only be the one
    just above it, and when a new winner ``d`` takes over, the smallest cost away from it is the
    old winner's, or, if the old winner was ``d - 1``, the smaller of the old runner-up and the
    old ``before`` (the cost at ``d - 2``). It is exact and costs two selects per slice.

    Parameters
    ----------
    state : Winners
    slices : float32 (K + 2, H, W), or a sequence of K + 2 float32 (H, W) planes
        Cost of the left view at disparities ``first - 1 .. first + K`` (a sequence spares the
        caller a concatenation).
    first : int or int32 scalar
        Disparity of ``slices[1]`` (traced values are fine).
    limit : int or int32 scalar
        Disparities outside ``[0, limit)`` count as ``+inf``.

    Returns
    -------
    Winners

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> c = jnp.stack([jnp.full((1, 3), v) for v in (3.0, 1.0, 2.0)])
    >>> w = fold_winners(no_winners((1, 3)), jnp.concatenate([c[:1], c, c[-1:]]), 0, limit=3)
    >>> w.disparity.tolist(), float(w.before[0, 0]), float(w.after[0, 0])
    ([[1, 1, 1]], 3.0, 2.0)
    """
    planes = [slices[k] for k in range(len(slices))]
    for plane in planes:
        check_rank("slice", plane, 2)
        check_floating("slice", plane)
    count = len(planes) - 2
    if count < 1:
        raise ValueError(f"need at least 3 slices (one core slice and two halo), got {count + 2}")
    if any(plane.shape != state.cost.shape for plane in planes):
        raise ValueError(f"slices must all be {state.cost.shape} like the state, got "
                         f"{sorted({tuple(plane.shape) for plane in planes})}")
    height, width = planes[0].shape
    planes = [
        jnp.where((first - 1 + k >= 0) & (first - 1 + k < limit), plane, jnp.inf)
        for k, plane in enumerate(planes)
    ]
    s = state
    for k in range(1, count + 1):
        cost = planes[k]
        better = cost < s.cost
        adjacent = first + k - 1 == s.disparity + 1
        runner_up = jnp.where(adjacent, jnp.minimum(s.second, s.before), s.cost)
        s = s._replace(
            second=jnp.where(better, runner_up,
                             jnp.where(adjacent, s.second, jnp.minimum(s.second, cost))),
            disparity=jnp.where(better, first + k - 1, s.disparity).astype(jnp.int32),
            cost=jnp.where(better, cost, s.cost),
            before=jnp.where(better, planes[k - 1], s.before),
            after=jnp.where(better, planes[k + 1], s.after),
        )
    right_disparity, right_cost = fold_right_view(s.right_disparity, s.right_cost,
                                                  planes[1:-1], first)
    return s._replace(right_disparity=right_disparity, right_cost=right_cost)


def fold_right_view(disparity: jax.Array, cost: jax.Array, planes, first
                    ) -> tuple[jax.Array, jax.Array]:
    """Fold left-view cost slices ``first .. first + K - 1`` into the right view's running
    winner-takes-all, ``C_R(x_r, d) = C(x_r + d, d)``.

    The block's minimum is taken in block coordinates ``u = x_r + first`` with static shifts,
    then moved to right-image coordinates with one dynamic shift (one per block, not per
    slice). Ties keep the smaller disparity.

    Parameters
    ----------
    disparity : int32 (H, W)
        The right view's best disparity so far (:func:`no_winners` gives the start).
    cost : (H, W), the planes' dtype
        Its cost (``+inf``, or an integer dtype's largest value, before any slice).
    planes : sequence of K (H, W) arrays of one real or integer dtype
        Left-view cost at disparities ``first .. first + K - 1``, the worst value (``+inf``,
        an integer dtype's largest) where a disparity must not count; a disparity that only
        ties with the worst value may then win over none, as the smaller one.
    first : int or int32 scalar
        Disparity of ``planes[0]`` (traced values are fine).

    Returns
    -------
    (int32 (H, W), (H, W) of the planes' dtype): the updated disparity and cost.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> left = [jnp.array([[5., 0., 5., 5.]]), jnp.array([[5., 5., 0., 5.]])]  # d = 0, 1
    >>> d, c = fold_right_view(jnp.zeros((1, 4), jnp.int32), jnp.full((1, 4), jnp.inf), left, 0)
    >>> d.tolist()  # right x = 1 matches left x = 1 (d = 0) and left x = 2 (d = 1): tie -> 0
    [[0, 0, 0, 0]]
    """
    height, width = planes[0].shape
    dtype = planes[0].dtype
    # The worst cost of the dtype: +inf, or an integer volume's largest value.
    worst = jnp.inf if jnp.issubdtype(dtype, jnp.floating) else jnp.iinfo(dtype).max
    block_cost = jnp.full((height, width), worst, dtype)
    block_index = jnp.zeros((height, width), jnp.int32)
    for k, plane in enumerate(planes):
        # C(u + k, first + k) at u = x_r + first.
        # (A block wider than the image leaves no column of its last planes.)
        shifted = jnp.pad(plane[:, k:], ((0, 0), (0, min(k, width))), constant_values=worst)
        better = shifted < block_cost
        block_cost = jnp.where(better, shifted, block_cost)
        block_index = jnp.where(better, k, block_index)
    # To right-image coordinates: x_r = u - first, so read column x_r + first.
    start = jnp.clip(first, 0, width)
    moved = lax.dynamic_slice_in_dim(
        jnp.pad(block_cost, ((0, 0), (0, width)), constant_values=worst), start, width, axis=1)
    index = lax.dynamic_slice_in_dim(jnp.pad(block_index, ((0, 0), (0, width))), start, width,
                                     axis=1)
    better = moved < cost
    return (jnp.where(better, first + index, disparity).astype(jnp.int32),
            jnp.where(better, moved, cost))


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


def equiangular_refine(disparity, before, centre, after, *, ndisp: int) -> jax.Array:
    """Sub-pixel disparity from two lines of opposite slopes through the three costs.

    Equiangular line fitting (Shimizu and Okutomi, "Sub-pixel estimation error cancellation on
    area-based matching", IJCV 2005, Eq. 9): the steeper of the two sides gives the slope, and
    the offset is ``(before - after) / (2 (max(before, after) - centre))``. It suits costs that
    grow like ``|d - d*|`` near their minimum (absolute differences, Hamming distances, and the
    semi-global sums whose ``P1`` penalty is linear), on which the parabola of
    :func:`parabola_refine` pulls the offsets towards 0. Arguments and result as there: the
    int32 (H, W) winners, the float32 (H, W) costs at ``d - 1``, ``d`` and ``d + 1``, the
    range's size (winners at its ends are not moved); float32 (H, W).
    """
    check_rank("disparity", disparity, 2)
    rise = jnp.maximum(before, after) - centre
    inside = (disparity > 0) & (disparity < ndisp - 1) & (rise > 0)
    offset = jnp.where(inside, (before - after) / (2 * jnp.where(inside, rise, 1.0)), 0.0)
    return disparity.astype(jnp.float32) + jnp.clip(offset, -0.5, 0.5)


SUBPIXEL_FITS = {"parabola": parabola_refine, "equiangular": equiangular_refine}


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
