"""The jitted graph: the stages of :mod:`sswjax.stages` composed into the SSW method.

Array conventions (whole module): the pure functions take images float32 ``(H, W, C)`` with
C in {1, 3} and values in [0, 1], a :class:`~sswjax.params.Params` pytree and a static
``ndisp``; they return float32 ``(H, W)`` disparities in pixels, dense, in [0, ndisp - 1].
The NumPy front door (validation, conversion, shape buckets) is :mod:`sswjax.api`.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_floating, check_positive_int, check_rank, check_same_shape
from sswjax.params import Params
from sswjax.registry import AGGREGATORS, FILLS, OPTIMIZERS, PREPROCESSORS
from sswjax.stages.aggregation import SegmentTerm
from sswjax.stages.baselines import box_filter
from sswjax.stages.confidence import DEFAULT_MEASURE, ConfidenceCues, confidence
from sswjax.stages.cost import MatchingFeatures, matching_cost, matching_cost_at, matching_features
from sswjax.stages.filters import side_window_median_filter
from sswjax.stages.pyramid import halve_image
from sswjax.stages.refinement import left_right_distance, uniqueness_violations
from sswjax.stages.segments import slic, slic_grid_shape
from sswjax.stages.selection import (Winners, fold_right_view, fold_winners, no_winners,
                                     parabola_refine)
from sswjax.stages.sgm import PathSums, quantise_cost, sum_planes
from sswjax.stages.upsampling import double_nearest, upsample_disparity


STAGES = ("cost", "superpixels", "aggregation", "optimization", "selection", "refinement",
          "upsampling")
"""Named scopes (``jax.named_scope``) of the stages in the compiled graph: profiler traces
attribute each operation to one of them (``benchmarks/speed.py``)."""


def _check_pair(left, right, ndisp: int) -> None:
    check_rank("left", left, 3)
    check_floating("left", left)
    check_same_shape("left", left, "right", right)
    if left.shape[-1] not in (1, 3):
        raise ValueError(f"images must have 1 or 3 channels, got shape {tuple(left.shape)}")
    check_positive_int("ndisp", ndisp)
    if ndisp >= left.shape[1]:
        raise ValueError(f"ndisp must be smaller than the image width {left.shape[1]}, got {ndisp}")


def superpixels(left: jax.Array, params: Params) -> tuple[jax.Array, int]:
    """SLIC labels of the left image and their static count (0 when no segment term is used).

    Parameters
    ----------
    left : float32 (H, W, C)
    params : Params

    Returns
    -------
    (int32 (H, W), int)
    """
    static = params.static
    used = (AGGREGATORS[static.aggregation].uses_segments
            or OPTIMIZERS[static.optimizer].uses_segments
            or (static.lr_check and FILLS[static.fill].uses_segments))
    if static.n_segments == 0 or not used:
        return jnp.zeros(left.shape[:2], jnp.int32), 0
    height, width = left.shape[:2]
    ny, nx = slic_grid_shape(height, width, static.n_segments)
    image = left if left.shape[-1] == 3 else jnp.repeat(left, 3, axis=-1)
    labels = slic(
        image,
        n_segments=static.n_segments,
        compactness=params.dynamic.slic_compactness,
        iterations=static.slic_iterations,
    )
    return labels, ny * nx


def _aggregate_slices(
    features: MatchingFeatures,
    left: jax.Array,
    labels: jax.Array,
    num_segments: int,
    first,
    count: int,
    params: Params,
) -> jax.Array:
    """Eq. (5) and (7) for disparities ``first .. first + count - 1``: cost, then aggregation.

    Every aggregator acts on each disparity slice independently (the guide and superpixels are
    shared), so slices computed in chunks equal those of the whole volume.
    """
    static, dynamic = params.static, params.dynamic
    with jax.named_scope(STAGES[0]):
        cost = matching_cost(
            features,
            first,
            count,
            tad_weight=dynamic.tad_weight,
            gradient_weight=dynamic.gradient_weight,
            census_weight=dynamic.census_weight,
            tad_truncation=dynamic.tad_truncation,
            gradient_truncation=dynamic.gradient_truncation,
        )
    aggregator = AGGREGATORS[static.aggregation]
    with jax.named_scope(STAGES[2]):
        return aggregator.fn(
            cost,
            left,
            radius=static.aggregation_radius if aggregator.radius is None else aggregator.radius,
            iterations=static.aggregation_iterations,
            window_selection=static.window_selection,
            segments=SegmentTerm(labels, num_segments, dynamic.segment_weight),
        )


def _features(left, right, params: Params):
    static = params.static
    with jax.named_scope(STAGES[0]):
        preprocess = PREPROCESSORS[static.preprocess].fn
        seen = (left, right) if preprocess is None else (
            preprocess(left, params=params), preprocess(right, params=params))
        features = matching_features(
            *seen, census_height=static.census_height, census_width=static.census_width
        )
    with jax.named_scope(STAGES[1]):
        labels, num_segments = superpixels(left, params)
    return features, labels, num_segments


def aggregated_cost(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int) -> jax.Array:
    """Eq. (5)-(7): matching cost, superpixels and segment-side-window aggregation.

    The whole volume at once: what the differentiable parameter search and analyses use.

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    params : Params
    ndisp : int, 1 <= ndisp < W

    Returns
    -------
    float32 (ndisp, H, W), lower is better.
    """
    _check_pair(left, right, ndisp)
    features, labels, num_segments = _features(left, right, params)
    return _aggregate_slices(features, left, labels, num_segments, 0, ndisp, params)


def _refine(winners: Winners, params: Params, ndisp, labels=None, num_segments: int = 0, *,
            parabola=None, guide=None, features=None, aggregated_right=None
            ) -> tuple[jax.Array, ConfidenceCues]:
    """Eq. (8)-(9) after the winners are known: parabola, LR check, filling, side-window median.

    ``parabola``: the three costs of the sub-pixel fit, when they come from another volume than
    the winners' (default: the winners' ``before``, ``cost``, ``after``). Returns the dense map
    and the cues of its confidence (:mod:`sswjax.stages.confidence`); callers that keep only
    the map let ``jit`` drop the cues."""
    static = params.static
    with jax.named_scope(STAGES[4]):
        if static.subpixel:
            before, centre, after = parabola or (winners.before, winners.cost, winners.after)
            disparity = parabola_refine(winners.disparity, before, centre, after, ndisp=ndisp)
        else:
            disparity = winners.disparity.astype(jnp.float32)
    initial = disparity
    failed = jnp.zeros(disparity.shape, bool)
    with jax.named_scope(STAGES[5]):
        # The left-right check (refinement.left_right_consistency) on a distance kept for the
        # confidence.
        distance = left_right_distance(winners.disparity, winners.right_disparity)
        if static.lr_check:
            valid = distance <= params.dynamic.lr_tolerance
            if static.uniqueness_gap > 0:
                dynamic = params.dynamic
                claim = matching_cost_at(
                    features, winners.disparity, tad_weight=dynamic.tad_weight,
                    gradient_weight=dynamic.gradient_weight, census_weight=dynamic.census_weight,
                    tad_truncation=dynamic.tad_truncation,
                    gradient_truncation=dynamic.gradient_truncation)
                if static.uniqueness_radius > 0:
                    claim = box_filter(claim, radius=static.uniqueness_radius)
                valid &= ~uniqueness_violations(winners.disparity, claim,
                                                gap=static.uniqueness_gap)
            if static.aggregated_lr_gap > 0 and aggregated_right is not None:
                # The optimiser spreads the foreground over occlusions in both views alike;
                # the aggregated cost's right view has not been spread.
                valid &= left_right_distance(winners.disparity, aggregated_right) \
                    < static.aggregated_lr_gap
            failed = ~valid
            fill = FILLS[static.fill]
            extra = {"guide": guide} if fill.uses_guide else {}
            disparity = fill.fn(disparity, valid, labels=labels,
                                num_segments=num_segments, params=params, **extra)
        if static.refine_radius > 0 and static.refine_iterations > 0:
            disparity = side_window_median_filter(
                disparity, radius=static.refine_radius, iterations=static.refine_iterations
            )
        disparity = jnp.clip(disparity, 0, ndisp - 1)
    cues = ConfidenceCues(winners.cost, winners.second, distance, initial, failed)
    return disparity, cues


def _fold(state: Winners, slices, first, limit) -> Winners:
    with jax.named_scope(STAGES[4]):
        return fold_winners(state, slices, first, limit=limit)


def _with_halo(cost: jax.Array) -> list[jax.Array]:
    """The D planes of a volume between two halo planes (masked to +inf by the fold); a list,
    so no copy of the volume is made."""
    return [cost[0], *(cost[d] for d in range(cost.shape[0])), cost[-1]]


def select_and_refine(cost: jax.Array, params: Params) -> jax.Array:
    """Eq. (8)-(9): WTA (+ parabola), left-right check, filling, side-window median.

    Parameters
    ----------
    cost : float32 (D, H, W)
        Aggregated cost of the left view.
    params : Params

    Returns
    -------
    float32 (H, W), dense, in [0, D - 1].
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    if params.static.uniqueness_gap > 0:
        raise ValueError("uniqueness_gap > 0 needs the images' features: use ssw_disparity, "
                         "or uniqueness_gap=0 with a cost volume")
    ndisp = cost.shape[0]
    winners = _fold(no_winners(cost.shape[1:]), _with_halo(cost), 0, ndisp)
    return _refine(winners, params, ndisp)[0]


_OUT_OF_RANGE_COST = 1e4


def _aggregated_volume(features, left, labels, num_segments, ndisp, params, store=None
                       ) -> jax.Array:
    """The whole aggregated volume (ndisp, H, W), built ``disparity_chunk`` slices at a time (a
    ``lax.scan`` whose outputs are the blocks) or at once when it is 0: float32, or as
    ``store`` (an elementwise function of the float32 cost) stores each block."""
    chunk = params.static.disparity_chunk
    store = (lambda block: block) if store is None else store
    if chunk == 0 or chunk >= ndisp:
        return store(_aggregate_slices(features, left, labels, num_segments, 0, ndisp, params))

    def step(carry, first):
        return carry, store(_aggregate_slices(features, left, labels, num_segments, first,
                                              chunk, params))

    _, blocks = jax.lax.scan(step, None, jnp.arange(0, ndisp, chunk))
    return blocks.reshape((-1, *blocks.shape[2:]))[:ndisp]


def _right_view(volume: jax.Array, limit, chunk: int) -> jax.Array:
    """The right view's winners (int32 (H, W)) of a volume (D, H, W) of any real or integer
    dtype as stored, read ``chunk`` planes per step of a ``lax.scan`` (0: all at once);
    disparities ``>= limit`` excluded. A pass of its own over the stored volume: folded inside
    the aggregation's scan it cost 4x more (XLA's fusions of the block's consumers)."""
    ndisp, height, width = volume.shape
    chunk = ndisp if chunk == 0 or chunk >= ndisp else chunk

    def step(state, first):
        # The last block starts early rather than past the end (no padded copy of the
        # volume): planes it folds again cannot win, as a tie keeps the winner.
        first = jnp.minimum(first, ndisp - chunk)
        block = lax.dynamic_slice_in_dim(volume, first, chunk, axis=0)
        # float32 planes: uint8 ones measured slower on XLA CPU (+40 against +20 ms per call).
        planes = [jnp.where(first + k < jnp.minimum(limit, ndisp),
                            block[k].astype(jnp.float32), jnp.inf) for k in range(chunk)]
        return fold_right_view(*state, planes, first), None

    start = no_winners((height, width))
    (disparity, _), _ = lax.scan(step, (start.right_disparity, start.right_cost),
                                 jnp.arange(0, ndisp, chunk))
    return disparity


def _costs_around(cost: jax.Array, disparity: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Costs of ``cost`` (D, H, W) at ``disparity - 1``, ``disparity``, ``disparity + 1``
    (int32 (H, W)); +inf outside the volume, as in the fold."""
    ndisp = cost.shape[0]

    def at(offset):
        index = disparity + offset
        value = jnp.take_along_axis(cost, jnp.clip(index, 0, ndisp - 1)[None], axis=0)[0]
        return jnp.where((index >= 0) & (index < ndisp), value, jnp.inf)

    return at(-1), at(0), at(1)


def _fold_volume(cost, limit, chunk: int) -> Winners:
    """The winners of both views over a whole volume, float32 (D, H, W) or the
    :class:`~sswjax.stages.sgm.PathSums` of the paths (converted plane by plane as it is read),
    ``chunk`` planes per step of a ``lax.scan`` (0: all planes in one unrolled fold). Each step
    gathers its planes with their halo; indices outside the volume are clipped, and the fold
    masks their disparities."""
    sums = cost if isinstance(cost, PathSums) else PathSums(cost, None)
    ndisp, size = sums.sums.shape[0], sums.sums.shape[1:]
    if chunk == 0 or chunk >= ndisp:
        planes = sum_planes(sums, [0, *range(ndisp), ndisp - 1])
        return _fold(no_winners(size), planes, 0, limit)

    def step(state, first):
        planes = sum_planes(sums, jnp.clip(first - 1 + jnp.arange(chunk + 2), 0, ndisp - 1))
        return _fold(state, planes, first, limit), None

    winners, _ = jax.lax.scan(step, no_winners(size), jnp.arange(0, ndisp, chunk))
    return winners


@functools.partial(jax.jit, static_argnames=("ndisp",))
def ssw_disparity(
    left: jax.Array, right: jax.Array, params: Params, *, ndisp: int, valid_ndisp=None
) -> jax.Array:
    """The whole SSW method as one jitted pure function.

    ``params.static`` is pytree metadata, so changing it (or the image size, or ``ndisp``)
    recompiles; ``params.dynamic`` is traced. ``jax.vmap`` batches it over pairs of one size:
    ``jax.vmap(lambda l, r: ssw_disparity(l, r, params, ndisp=n))(lefts, rights)``.

    With ``params.static.disparity_chunk = K > 0`` (the default) the disparities are processed
    K at a time (``lax.scan`` with a running minimum for both views), so memory holds a few
    ``(K, H, W)`` blocks instead of ``(ndisp, H, W)`` volumes; the result is the same as with
    ``K = 0`` (the whole volume at once).

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    params : Params
    ndisp : int, 1 <= ndisp < W
        Size of the disparity volume (static: a new value recompiles).
    valid_ndisp : int32 scalar, optional
        Traced search range ``0 .. valid_ndisp - 1`` within the volume (default ``ndisp``):
        shape bucketing runs a padded ``ndisp`` and passes the true one here.

    Returns
    -------
    float32 (H, W), dense disparities of the left view in pixels, in [0, valid_ndisp - 1].
    """
    return _match(left, right, params, ndisp, valid_ndisp)[0]


class SSWOutputs(NamedTuple):
    """What :func:`ssw_outputs` returns, all ``(H, W)``: the dense disparity (float32, as
    :func:`ssw_disparity`), its confidence (float32 in [0, 1], higher = more reliable) and the
    pixels the left-right check (with the uniqueness and aggregated-view tests when on)
    rejected and filled (bool)."""

    disparity: jax.Array
    confidence: jax.Array
    lr_failed: jax.Array


@functools.partial(jax.jit, static_argnames=("ndisp", "measure"))
def ssw_outputs(
    left: jax.Array, right: jax.Array, params: Params, *, ndisp: int, valid_ndisp=None,
    measure: str = DEFAULT_MEASURE,
) -> SSWOutputs:
    """:func:`ssw_disparity` with the confidence of each pixel, in one jitted graph.

    The same graph as :func:`ssw_disparity` (which keeps only the map; ``jit`` drops the rest)
    plus the confidence measure of :mod:`sswjax.stages.confidence` on the cues it gathers.

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    params : Params
    ndisp : int, 1 <= ndisp < W
    valid_ndisp : int32 scalar, optional
        As for :func:`ssw_disparity`.
    measure : str
        A key of :data:`sswjax.stages.confidence.MEASURES` (static).

    Returns
    -------
    SSWOutputs
        float32 (H, W) disparity, float32 (H, W) confidence, bool (H, W) lr_failed.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> image = jnp.linspace(0, 1, 40 * 48).reshape(40, 48, 1) ** 2
    >>> out = ssw_outputs(image, image, Params().replace(n_segments=8), ndisp=8)
    >>> out.confidence.shape, str(out.confidence.dtype)
    ((40, 48), 'float32')
    """
    disparity, cues = ssw_cues(left, right, params, ndisp=ndisp, valid_ndisp=valid_ndisp)
    return SSWOutputs(disparity, confidence(cues, disparity, measure=measure), cues.lr_failed)


@functools.partial(jax.jit, static_argnames=("ndisp",))
def ssw_cues(
    left: jax.Array, right: jax.Array, params: Params, *, ndisp: int, valid_ndisp=None
) -> tuple[jax.Array, ConfidenceCues]:
    """The dense disparity of :func:`ssw_disparity` and the raw cues of its confidence.

    For analyses that compare confidence measures on one run (``benchmarks/sparsification.py``).

    Returns
    -------
    (float32 (H, W), ConfidenceCues)
    """
    return _match(left, right, params, ndisp, valid_ndisp)


def _match(left, right, params: Params, ndisp: int, valid_ndisp) -> tuple[jax.Array, ConfidenceCues]:
    """The body of :func:`ssw_disparity`: the map and its confidence cues."""
    _check_pair(left, right, ndisp)
    if params.static.coarse_levels > 0:
        return _match_coarse_to_fine(left, right, params, ndisp, valid_ndisp)
    limit = ndisp if valid_ndisp is None else valid_ndisp
    features, labels, num_segments = _features(left, right, params)
    chunk = params.static.disparity_chunk
    optimizer = OPTIMIZERS[params.static.optimizer]
    if optimizer.fn is not None:
        # The optimiser may take the cost quantised: each block is stored so as it is built.
        quant = None if optimizer.storage is None else optimizer.storage(params)
        store = None if quant is None else functools.partial(quantise_cost, quant=quant)
        cost = _aggregated_volume(features, left, labels, num_segments, ndisp, params, store)
        aggregated_right = None
        if params.static.lr_check and params.static.aggregated_lr_gap > 0:
            aggregated_right = _right_view(cost, limit, chunk)
        if valid_ndisp is not None:
            # Disparities beyond the traced range take a high finite cost: the paths must not
            # pass through them, and +inf would turn the recursion's differences into NaN.
            high = jnp.float32(_OUT_OF_RANGE_COST)
            cost = jnp.where(jnp.arange(ndisp)[:, None, None] < limit, cost,
                             high if store is None else store(high))
        with jax.named_scope(STAGES[3]):
            optimised = optimizer.fn(cost, left, labels=labels if num_segments else None,
                                     params=params)
        winners = _fold_volume(optimised, limit, chunk)
        parabola = _costs_around(cost, winners.disparity) if optimizer.subpixel_on_input else None
        return _refine(winners, params, limit, labels, num_segments, parabola=parabola, guide=left,
                       features=features, aggregated_right=aggregated_right)
    if chunk == 0 or chunk >= ndisp:
        cost = _aggregate_slices(features, left, labels, num_segments, 0, ndisp, params)
        winners = _fold(no_winners(cost.shape[1:]), _with_halo(cost), 0, limit)
        return _refine(winners, params, limit, labels, num_segments, guide=left,
                       features=features)

    # Each step aggregates a block of K slices and folds the block of the previous step, which
    # the loop carries: every slice is computed once, and the fold reads a materialised block
    # (XLA would otherwise recompute the last filtering pass inside each of its consumers).
    # The first step folds an empty block (disparities -K .. -1, all +inf).
    height, width = left.shape[:2]
    inf_plane = jnp.full((height, width), jnp.inf, jnp.float32)
    firsts = jnp.arange(0, ndisp, chunk)

    def fold(state, block, before, after, first):
        planes = [before, *(block[k] for k in range(chunk)), after]
        return _fold(state, planes, first, limit)

    def step(carry, first):
        state, previous, before = carry
        # The last block may run past ndisp: those slices are computed but masked by the fold.
        block = _aggregate_slices(features, left, labels, num_segments, first, chunk, params)
        state = fold(state, previous, before, block[0], first - chunk)
        return (state, block, previous[-1]), None

    empty = jnp.full((chunk, height, width), jnp.inf, jnp.float32)
    start = (no_winners((height, width)), empty, inf_plane)
    (winners, last, before), _ = jax.lax.scan(step, start, firsts)
    winners = fold(winners, last, before, inf_plane, firsts[-1])
    return _refine(winners, params, limit, labels, num_segments, guide=left, features=features)


def _match_coarse_to_fine(left, right, params: Params, ndisp: int,
                          valid_ndisp) -> tuple[jax.Array, ConfidenceCues]:
    """``coarse_levels = L > 0``: the method with ``L - 1`` levels on the pair halved, its map
    doubled back guided by the left image (:mod:`sswjax.stages.upsampling`), then a small
    side-window median. The confidence cues are the coarse ones, each on the fine pixels its
    coarse pixel covers (disparities and distances doubled)."""
    static = params.static
    limit = ndisp if valid_ndisp is None else valid_ndisp
    small_left, small_right = halve_image(left), halve_image(right)
    # Fine disparities 0 .. ndisp - 1 are coarse 0 .. (ndisp - 1) / 2: ndisp // 2 + 1 of them,
    # within the halved width.
    coarse_ndisp = min(ndisp // 2 + 1, small_left.shape[1] - 1)
    coarse_limit = None if valid_ndisp is None else jnp.minimum(valid_ndisp // 2 + 1, coarse_ndisp)
    inner = params.replace(coarse_levels=static.coarse_levels - 1)
    coarse, cues = _match(small_left, small_right, inner, coarse_ndisp, coarse_limit)
    shape = left.shape[:2]
    with jax.named_scope(STAGES[6]):
        disparity = upsample_disparity(coarse, left, small_left, jump=params.dynamic.upsample_jump)
        if static.upsample_radius > 0 and static.refine_iterations > 0:
            disparity = side_window_median_filter(
                disparity, radius=static.upsample_radius, iterations=static.refine_iterations)
        disparity = jnp.clip(disparity, 0, limit - 1)
        doubled = ConfidenceCues(*(double_nearest(cue, shape=shape) for cue in cues))
        cues = doubled._replace(lr_distance=2 * doubled.lr_distance, initial=2 * doubled.initial)
    return disparity, cues
