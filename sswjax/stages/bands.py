"""Narrow disparity bands around an estimate: the full-resolution search of a coarse-to-fine
matcher (Rothermel et al., "SURE: Photogrammetric surface reconstruction from imagery", LC3D
2012, the tSGM; Hirschmuller et al., "Memory efficient semi-global matching", ISPRS Annals
2012, the eSGM).

Instead of all ``D`` disparities, each pixel searches ``K`` consecutive ones around its own
estimate. JAX needs static shapes, so the band is a volume ``(K, H, W)`` with a per-pixel first
disparity: plane ``k`` of pixel ``p`` holds disparity ``start(p) + k``. The semi-global paths
over a band (:func:`sswjax.stages.sgm.semi_global_sums` with ``starts``) compare a pixel with
its predecessor in absolute disparities, so each step realigns the predecessor's band to the
pixel's own (:func:`align_band`), as the tSGM's per-pixel ranges do inside its recursion.

Array conventions (whole module): band volumes ``(K, H, W)``, float32 costs (lower is better)
or their stored integer levels; starts int32 ``(H, W)``, ``>= 0``; disparity estimates float32
``(H, W)`` in pixels; lines of a path ``(K, N)`` with starts ``(N,)``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_integer, check_positive_int, check_rank, check_same_shape
from sswjax.stages.cost import MatchingFeatures, matching_cost_at
from sswjax.stages.filters import edge_pad
from sswjax.stages.quantisation import dequantise
from sswjax.stages.selection import Winners, fold_winners, no_winners

__all__ = ["align_band", "band_cost", "band_deltas", "band_right_view", "band_starts", "band_winners"]


def band_starts(estimate: jax.Array, *, width: int, limit, spread_radius: int = 0,
                labels: jax.Array | None = None, num_segments: int = 0) -> jax.Array:
    """First disparity of each pixel's band: ``width`` disparities centred on the rounded
    estimate, moved inside ``[0, limit)`` where they would leave it.

    With ``spread_radius = r > 0`` the band is centred instead on the middle of the rounded
    estimates' range ``[lo, hi]`` over the ``(2r + 1)^2`` window of the pixel wherever that
    range fits in the band (``hi - lo < width``): near a depth edge of a coarse map the
    estimate can sit on either side of the edge, and a band holding both sides lets the
    full-resolution pass choose (the tSGM's per-pixel ranges from the neighbourhood's minimum
    and maximum, Rothermel et al. 2012, padded to a fixed width). Where the range is wider,
    the band stays on the pixel's own estimate.

    With ``labels`` (superpixels) the range is taken over the pixel's superpixel instead,
    wherever it fits in the band (else the window's range or the pixel's own estimate, as
    above): a superpixel follows the image's edges, so its range is the support the segment
    gives the band (the tSGM's per-pixel range taken per segment; the paper's superpixels,
    Eq. 6, used for the search range rather than the cost).

    Parameters
    ----------
    estimate : float32 (H, W)
        Disparities in pixels.
    width : int >= 1
        ``K``, the band's disparities (odd bands are centred; even ones have one more above).
    limit : int or int32 scalar
        The search range ``0 .. limit - 1``; with ``limit < width`` every band starts at 0.
    spread_radius : int >= 0
        ``r``; 0 centres every band on its own estimate. Borders are edge-replicated.
    labels : int32 (H, W), optional
        Superpixel labels in ``[0, num_segments)``.
    num_segments : int
        Their static count (with ``labels``).

    Returns
    -------
    int32 (H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> band_starts(jnp.array([[0.2, 4.6, 9.0]]), width=3, limit=10).tolist()
    [[0, 4, 7]]
    >>> edge = jnp.array([[2.0, 2.0, 6.0, 6.0]])       # a step of 4 under a band of 7
    >>> band_starts(edge, width=7, limit=20).tolist(), band_starts(
    ...     edge, width=7, limit=20, spread_radius=1).tolist()
    ([[0, 0, 3, 3]], [[0, 1, 1, 3]])
    >>> band_starts(edge, width=7, limit=20, labels=jnp.zeros((1, 4), jnp.int32),
    ...             num_segments=1).tolist()          # one superpixel over both sides
    [[1, 1, 1, 1]]
    """
    check_rank("estimate", estimate, 2)
    check_positive_int("width", width)
    check_positive_int("spread_radius", spread_radius, minimum=0)
    rounded = jnp.round(estimate).astype(jnp.int32)
    start = rounded - (width - 1) // 2
    if spread_radius > 0:
        window = (2 * spread_radius + 1,) * 2
        padded = edge_pad(rounded, spread_radius)
        low = lax.reduce_window(padded, jnp.iinfo(jnp.int32).max, lax.min, window, (1, 1),
                                "VALID")
        high = lax.reduce_window(padded, jnp.iinfo(jnp.int32).min, lax.max, window, (1, 1),
                                 "VALID")
        start = _centred_on_range(start, low, high, width)
    if labels is not None:
        check_same_shape("labels", labels, "estimate", estimate)
        flat = labels.reshape(-1)
        low = jax.ops.segment_min(rounded.reshape(-1), flat, num_segments=num_segments)
        high = jax.ops.segment_max(rounded.reshape(-1), flat, num_segments=num_segments)
        start = _centred_on_range(start, low[labels], high[labels], width)
    return jnp.maximum(jnp.minimum(start, limit - width), 0).astype(jnp.int32)


def _centred_on_range(start, low, high, width: int):
    """``start``, or where ``[low, high]`` fits in the band the start that centres it:
    ``(width - 1 - (high - low)) // 2`` to spare below the range, the rest above."""
    return jnp.where(high - low < width, low - (width - 1 - (high - low)) // 2, start)


def band_cost(features: MatchingFeatures, starts: jax.Array, *, width: int, **terms) -> jax.Array:
    """The matching cost of Eq. (5) over each pixel's band: ``out[k, y, x] = C(p, start(p) + k)``.

    One gather of the right image's features per plane
    (:func:`~sswjax.stages.cost.matching_cost_at`), so the cost of the full volume is never
    computed; the border rule of :mod:`sswjax.stages.cost` holds (``x - d < 0`` costs the
    weights' sum).

    Parameters
    ----------
    features : MatchingFeatures
    starts : int32 (H, W)
    width : int >= 1
    **terms
        The weights and truncations of :func:`~sswjax.stages.cost.matching_cost_at`.

    Returns
    -------
    float32 (width, H, W)
    """
    check_rank("starts", starts, 2)
    check_integer("starts", starts)
    check_positive_int("width", width)
    return jnp.stack([matching_cost_at(features, starts + k, **terms) for k in range(width)])


def align_band(previous: jax.Array, delta: jax.Array, fill: jax.Array) -> jax.Array:
    """A predecessor's band in the disparities of the pixel's own band and its two neighbours.

    ``out[j, n] = previous[j - 1 + delta[n], n]`` for ``j = 0 .. K + 1`` (disparities
    ``start(p) - 1 .. start(p) + K``) where the predecessor's band holds that disparity,
    ``fill[n]`` where it does not.

    Parameters
    ----------
    previous : (K, N), any dtype
        The predecessor's values, plane ``k`` at its disparity ``start(p - r) + k``.
    delta : int32 (N,)
        ``start(p) - start(p - r)``.
    fill : (N,), ``previous``'s dtype

    Returns
    -------
    (K + 2, N), ``previous``'s dtype

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> prev = jnp.array([[0], [1], [2]])             # disparities 5, 6, 7
    >>> align_band(prev, jnp.array([1]), jnp.array([9])).ravel().tolist()   # 5 .. 9
    [0, 1, 2, 9, 9]
    """
    width, size = previous.shape
    index = jnp.arange(-1, width + 1)[:, None] + delta[None, :]
    inside = (index >= 0) & (index < width)
    # One flat gather from the planes with the fill as an extra plane: 6x faster on XLA CPU
    # than take_along_axis and a select, inside the paths' loop.
    source = jnp.concatenate([previous, fill[None].astype(previous.dtype)]).reshape(-1)
    flat = jnp.where(inside, index, width) * size + jnp.arange(size)[None, :]
    return jnp.take(source, flat, mode="clip")


def band_deltas(starts: jax.Array, shift: int, forward: bool) -> jax.Array:
    """``start(p) - start(p - r)`` of every pixel of a path along axis 0, whose predecessor is
    on the line before (``forward``) or after, ``shift`` columns back along axis 1 (0
    straight, +-1 diagonal); 0 where the path starts (the first line, and the column a
    diagonal enters by).

    Parameters
    ----------
    starts : int32 (S, N)
    shift : int
    forward : bool

    Returns
    -------
    int32 (S, N)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> band_deltas(jnp.array([[0, 0], [2, 5]]), 1, True).tolist()   # (1, 1) from (0, 0)
    [[0, 0], [0, 5]]
    """
    check_rank("starts", starts, 2)
    check_integer("starts", starts)
    lines, size = starts.shape
    before = (jnp.concatenate([starts[:1], starts[:-1]]) if forward
              else jnp.concatenate([starts[1:], starts[-1:]]))
    columns = jnp.clip(jnp.arange(size) - shift, 0, size - 1)
    entered = (jnp.arange(size) - shift < 0) | (jnp.arange(size) - shift >= size)
    delta = jnp.where(entered[None, :], 0, starts - before[:, columns])
    return delta.at[0 if forward else lines - 1].set(0)


def band_right_view(volume: jax.Array, starts: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The right view's winner-takes-all over the bands of the left view: for each right pixel
    the disparity of the cheapest left pixel whose band reaches it, ``C_R(x_r, d) = C(x_r + d,
    d)`` over the disparities ``d`` that pixel ``x_r + d`` searched. Ties keep the smaller
    disparity, as :func:`~sswjax.stages.selection.fold_right_view` does; a right pixel no band
    reaches gets the largest int32 and the worst cost (the left-right check never reads it:
    every left pixel's winner reaches its own match).

    A scatter of the claims' minimum: for an integer volume of at most 16 bits (the stored
    levels, the int16 sums of the paths) one scatter of the cost and the disparity packed into
    an int32, else two (the cost, then the smallest disparity that reached it).

    Parameters
    ----------
    volume : (K, H, W), float32, or integer of at most 16 bits
    starts : int32 (H, W)
        Disparities below 65536.

    Returns
    -------
    (int32 (H, W), (H, W) float32, or int32 for an integer volume)
        The right view's winners and their costs.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> cost = jnp.array([[[1., 0., 5.]], [[0., 3., 0.]]])     # K = 2, one row
    >>> # x = 2 searched d = 1, 2 and claims right pixel 0 at cost 0; nobody reaches pixel 2
    >>> band_right_view(cost, jnp.array([[0, 0, 1]]))[0].tolist()
    [[2, 0, 2147483647]]
    """
    check_rank("volume", volume, 3)
    check_same_shape("volume plane", volume[0], "starts", starts)
    width_k, height, width = volume.shape
    disparity = starts[None] + jnp.arange(width_k, dtype=jnp.int32)[:, None, None]
    target = jnp.arange(width)[None, None, :] - disparity
    size = height * width
    flat = jnp.where(target >= 0, jnp.arange(height)[None, :, None] * width + target, size)
    none = jnp.iinfo(jnp.int32).max
    if jnp.issubdtype(volume.dtype, jnp.integer) and jnp.iinfo(volume.dtype).bits <= 16:
        # (cost << 16) | d orders the claims by cost, then disparity.
        key = (volume.astype(jnp.int32) << 16) | disparity
        best = jnp.full(size, none, jnp.int32).at[flat].min(key, mode="drop")
        found = best != none
        return (jnp.where(found, best & 0xFFFF, none).reshape(height, width),
                jnp.where(found, best >> 16, none).reshape(height, width))
    cost = volume.astype(jnp.float32)
    best = jnp.full(size, jnp.inf, jnp.float32).at[flat].min(cost, mode="drop")
    best_at = best.at[flat].get(mode="fill", fill_value=jnp.inf)
    winner = jnp.full(size, none, jnp.int32).at[
        jnp.where(cost <= best_at, flat, size)].min(disparity, mode="drop")
    return winner.reshape(height, width), best.reshape(height, width)


def band_winners(volume: jax.Array, starts: jax.Array, *, scale=None) -> Winners:
    """Winner-takes-all over each pixel's band, in absolute disparities, for both views.

    The left view's fold of :func:`~sswjax.stages.selection.fold_winners` over the band's
    planes (converted to cost units, ``dequantise(plane, scale)``); ``disparity`` is then
    ``start + k``, and where the winner lies on the band's edge the missing neighbour's cost
    is the winner's own (the parabola of Eq. 8 leaves it where it is, as at the ends of a full
    range). The right view is :func:`band_right_view` of the volume as stored.

    Parameters
    ----------
    volume : (K, H, W)
        The band's (optimised) cost, plane ``k`` at disparity ``start + k``: float32, or the
        int16 sums of the paths with their ``scale``.
    starts : int32 (H, W)
    scale : float32 scalar, optional
        Steps per cost unit of an integer volume (:class:`~sswjax.stages.quantisation.PathSums`).

    Returns
    -------
    Winners
        ``second`` is the runner-up within the band; costs in cost units.
    """
    check_rank("volume", volume, 3)
    width = volume.shape[0]
    planes = [dequantise(volume[k], scale) for k in range(width)]
    state = fold_winners(no_winners(starts.shape), [planes[0], *planes, planes[-1]], 0,
                         limit=width)
    band = state.disparity
    right_disparity, right_cost = band_right_view(volume, starts)
    return state._replace(
        disparity=starts + band,
        before=jnp.where(band == 0, state.cost, state.before),
        after=jnp.where(band == width - 1, state.cost, state.after),
        right_disparity=right_disparity, right_cost=dequantise(right_cost, scale))
