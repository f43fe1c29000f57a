"""The cost volume of one call: built in blocks of disparities, optimised, folded into winners.

Array conventions (whole module): images float32 ``(H, W, C)``, C in {1, 3}, values in [0, 1];
cost volumes ``(D, H, W)``, lower is better, float32 or as the optimiser stores them (uint8 or
int16 levels); ``limit`` is the search range ``0 .. limit - 1`` within the volume (the static
``ndisp``, or a traced int32 scalar when the volume is padded); ``chunk = K > 0`` builds and
folds the volume K disparities per step of a ``lax.scan``, ``0`` all at once (the same values).

:func:`optimised_volume` is the one place the optimised volume is made: inference folds it
(:func:`select_optimised`) and the parameter search relaxes its winner-takes-all
(:mod:`sswjax.search.objective`).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from sswjax.config import Params
from sswjax.graph.padding import (edge_cost_slices, edge_filler, outside_as_border,
                                  padding_as_edge)
from sswjax.graph.scopes import Stage, scope
from sswjax.stages.cost import MatchingFeatures
from sswjax.stages.selection import Winners, fold_right_view, fold_winners, no_winners
from sswjax.stages.quantisation import PathSums, quantise_cost, sum_planes

__all__ = ["OUT_OF_RANGE_COST", "Scene", "Selected", "aggregate_slices", "aggregated_volume",
           "cost_bound", "cost_features", "cost_margin", "fold_volume", "optimised_volume",
           "prepare_scene", "right_view", "select_optimised", "stored_scale", "streamed_winners",
           "superpixels"]

OUT_OF_RANGE_COST = 1e4
"""Cost of the disparities beyond a traced range, as the optimiser sees them: high but finite
(+inf would turn the recursion's differences into NaN)."""


class Scene(NamedTuple):
    """What the stages of one call share.

    Attributes
    ----------
    left : float32 (H, W, C)
        The left image as given: the guide of the aggregation, the optimiser and the fills.
    features : MatchingFeatures
        The per-image terms of the matching cost (of the pre-processed pair).
    labels : int32 (H, W)
        Superpixels of the left image (zeros without them).
    num_segments : int
        Their static count, 0 without superpixels.
    valid_shape : int32 (2,) or None
        The pair's own height and width when it is padded to a shape bucket (None: not
        padded; :mod:`sswjax.graph.padding`).
    """

    left: jax.Array
    features: MatchingFeatures
    labels: jax.Array
    num_segments: int
    valid_shape: jax.Array | None = None


class Selected(NamedTuple):
    """The winners and what the refinement reads beside them.

    Attributes
    ----------
    winners : Winners
        Of both views (:func:`~sswjax.stages.selection.fold_winners`).
    parabola : (float32 (H, W),) * 3 or None
        The costs of the sub-pixel fit when they come from another volume than the winners'.
    aggregated_right : int32 (H, W) or None
        The right view's winners of the aggregated cost before the optimiser.
    carried : Seeds or None
        The optimiser's path states for the neighbouring windows, when it was given seeds.
    margin : float32 (H, W) or None
        The ``margin`` confidence cue (:mod:`sswjax.stages.confidence`) when the winners come
        from another volume than the aggregated cost (:func:`cost_margin`); None: the winners'
        own ``(second - cost) / cost_bound``.
    """

    winners: Winners
    parabola: tuple | None = None
    aggregated_right: jax.Array | None = None
    carried: object = None
    margin: jax.Array | None = None


def superpixels(left: jax.Array, params: Params) -> tuple[jax.Array, int]:
    """SLIC labels of the left image and their static count: int32 (H, W), int (0 and zeros
    when ``params.segments`` is None)."""
    if params.segments is None:
        return jnp.zeros(left.shape[:2], jnp.int32), 0
    return params.segments.labels(left)


def prepare_scene(left: jax.Array, right: jax.Array, params: Params, *, valid_shape=None
                  ) -> Scene:
    """Pre-processing, the cost's features and the superpixels of a pair; ``valid_shape``
    (int32 (2,), optional) the pair's own height and width when it is padded."""
    features = cost_features(left, right, params, valid_shape=valid_shape)
    with scope(Stage.SUPERPIXELS):
        labels, num_segments = superpixels(left, params)
    return Scene(left, features, labels, num_segments, valid_shape)


def cost_features(left: jax.Array, right: jax.Array, params: Params, *, valid_shape=None
                  ) -> MatchingFeatures:
    """The pre-processing and the cost's features of a pair (``valid_shape`` as for
    :func:`prepare_scene`)."""
    with scope(Stage.COST):
        preprocess = params.preprocess
        seen = (left, right) if preprocess is None else (preprocess.apply(left),
                                                         preprocess.apply(right))
        features = params.cost.features(*seen)
        if valid_shape is not None:
            # The census and gradient windows of the padded rows reach back into the pair:
            # the edge's features instead, so that those rows cost what the last row does.
            features = features._replace(**{
                name: padding_as_edge(value, valid_shape)
                for name, value in features._asdict().items() if isinstance(value, jax.Array)})
    return features


def aggregate_slices(scene: Scene, params: Params, first, count: int) -> jax.Array:
    """Eq. (5) and (7) for disparities ``first .. first + count - 1``: the cost, then its
    aggregation, float32 (count, H, W)."""
    with scope(Stage.COST):
        cost = edge_cost_slices(params.cost.slices, scene.features, first, count,
                                scene.valid_shape, params.cost.bound())
    with scope(Stage.AGGREGATION):
        aggregated = params.aggregation.aggregate(cost, scene.left, labels=scene.labels,
                                                  num_segments=scene.num_segments,
                                                  edge=edge_filler(scene.valid_shape))
    return outside_as_border(aggregated, scene.valid_shape, params.cost.bound())


def aggregated_volume(scene: Scene, params: Params, *, ndisp: int, chunk: int, store=None
                      ) -> jax.Array:
    """The whole aggregated volume (ndisp, H, W), ``chunk`` slices per step of a ``lax.scan``
    whose outputs are the blocks (0: at once): float32, or as ``store`` (an elementwise
    function of the float32 cost) stores each block."""
    store = (lambda block: block) if store is None else store
    if chunk == 0 or chunk >= ndisp:
        return store(aggregate_slices(scene, params, 0, ndisp))

    def step(carry, first):
        return carry, store(aggregate_slices(scene, params, first, chunk))

    _, blocks = jax.lax.scan(step, None, jnp.arange(0, ndisp, chunk))
    return blocks.reshape((-1, *blocks.shape[2:]))[:ndisp]


def cost_bound(params: Params):
    """The largest aggregated cost of a matching pixel: each term of Eq. 5 is in [0, 1], so
    the weights' sum, times what the aggregation multiplies it by (``1 + lambda`` with the
    segment term of Eq. 7). A filter that is not an average, such as the guided one, may
    overshoot it slightly: the quantisation clips there."""
    bound = params.cost.bound()
    factor = params.aggregation.bound_factor(params.segments is not None)
    return bound if factor is None else bound * factor


def optimised_volume(scene: Scene, params: Params, *, ndisp: int, valid_ndisp=None,
                     chunk: int, seeds=None) -> tuple[jax.Array, PathSums | jax.Array]:
    """The aggregated volume as the optimiser stores it and the optimiser's result.

    Parameters
    ----------
    scene : Scene
    params : Params
        With an optimizer.
    ndisp : int
        Planes of the volume (static).
    valid_ndisp : int32 scalar, optional
        Traced range: planes at and beyond it take :data:`OUT_OF_RANGE_COST` (stored), so the
        paths never pass through them.
    chunk : int
        Disparities per block of the aggregation (0: at once).
    seeds : Seeds, optional
        The paths along the rows carried in from the windows above and below
        (:mod:`sswjax.stages.paths`), for an optimiser that ``carries_paths``.

    Returns
    -------
    (cost, optimised)
        The stored volume (ndisp, H, W) (float32, or uint8 / int16 levels), masked to the
        range; the optimised volume, float32 (ndisp, H, W) or
        :class:`~sswjax.stages.sgm.PathSums`.
    """
    optimizer = params.optimizer
    bound = cost_bound(params)
    # The optimiser may take the cost quantised: each block is stored so as it is built.
    quant = optimizer.storage(bound)
    store = None if quant is None else functools.partial(quantise_cost, quant=quant)
    cost = aggregated_volume(scene, params, ndisp=ndisp, chunk=chunk, store=store)
    if valid_ndisp is not None:
        high = jnp.float32(OUT_OF_RANGE_COST)
        cost = jnp.where(jnp.arange(ndisp)[:, None, None] < valid_ndisp, cost,
                         high if store is None else store(high))
    with scope(Stage.OPTIMIZATION):
        labels = scene.labels if scene.num_segments else None
        optimised = optimizer.optimise(cost, scene.left, labels=labels, cost_bound=bound,
                                       seeds=seeds)
    return cost, optimised


def select_optimised(scene: Scene, params: Params, *, ndisp: int, valid_ndisp=None,
                     chunk: int, seeds=None) -> Selected:
    """The winners of the optimised volume and, as the checks ask, the right view of the
    aggregated one; the parabola's costs from the aggregated volume when the optimiser asks;
    the paths' states for the neighbouring windows with ``seeds``; the confidence's margin
    from the aggregated volume (:func:`cost_margin`)."""
    limit = ndisp if valid_ndisp is None else valid_ndisp
    cost, optimised = optimised_volume(scene, params, ndisp=ndisp, valid_ndisp=valid_ndisp,
                                       chunk=chunk, seeds=seeds)
    aggregated_right = None
    if params.checks is not None and params.checks.aggregated_gap > 0:
        # Disparities at and beyond the range are excluded by the view itself, so it reads
        # the masked volume as it would the unmasked one.
        aggregated_right = right_view(cost, limit, chunk)
    winners = fold_volume(optimised, limit, chunk)
    parabola = (costs_around(cost, winners.disparity)
                if params.optimizer.subpixel_on_input else None)
    carried = optimised.carried if isinstance(optimised, PathSums) else None
    # The confidence's margin, from the aggregated cost: the paths' penalties alone make the
    # sums' minimum stand out. Only graphs that return the confidence keep this fold.
    margin = cost_margin(cost, params, limit=limit, chunk=chunk)
    return Selected(winners, parabola, aggregated_right, carried, margin)


def stored_scale(params: Params):
    """Levels per cost unit of the aggregated volume as the optimiser of ``params`` stores it
    (:meth:`~sswjax.config.Optimizer.storage`): a float32 scalar, or None for float32."""
    quant = params.optimizer.storage(cost_bound(params))
    if quant is None:
        return None
    return quant.scale if quant.levels is None else quant.levels / quant.cap


def cost_margin(cost: jax.Array, params: Params, *, limit, chunk: int) -> jax.Array:
    """The ``margin`` confidence cue of the stored aggregated volume ``cost`` (D, H, W) of
    :func:`optimised_volume`: ``(c2 - c1) / cost_bound`` of its own winner-takes-all, in its
    stored levels (:mod:`sswjax.stages.confidence`). float32 (H, W), ``+inf`` without a
    runner-up."""
    winners = fold_volume(PathSums(cost, stored_scale(params)), limit, chunk)
    return (winners.second - winners.cost) / cost_bound(params)


def _fold(state: Winners, slices, first, limit) -> Winners:
    with scope(Stage.SELECTION):
        return fold_winners(state, slices, first, limit=limit)


def with_halo(cost: jax.Array) -> list[jax.Array]:
    """The D planes of a volume between two halo planes (masked to +inf by the fold); a list,
    so no copy of the volume is made."""
    return [cost[0], *(cost[d] for d in range(cost.shape[0])), cost[-1]]


def right_view(volume: jax.Array, limit, chunk: int) -> jax.Array:
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


def costs_around(cost: jax.Array, disparity: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Costs of ``cost`` (D, H, W) at ``disparity - 1``, ``disparity``, ``disparity + 1``
    (int32 (H, W)); +inf outside the volume, as in the fold."""
    ndisp = cost.shape[0]

    def at(offset):
        index = disparity + offset
        value = jnp.take_along_axis(cost, jnp.clip(index, 0, ndisp - 1)[None], axis=0)[0]
        return jnp.where((index >= 0) & (index < ndisp), value, jnp.inf)

    return at(-1), at(0), at(1)


def fold_volume(cost, limit, chunk: int) -> Winners:
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


def streamed_winners(scene: Scene, params: Params, *, ndisp: int, limit, chunk: int) -> Winners:
    """The winners of both views of the aggregated cost without an optimiser: the volume is
    never stored whole (``chunk`` > 0), or folded at once (``chunk`` 0)."""
    if chunk == 0 or chunk >= ndisp:
        cost = aggregate_slices(scene, params, 0, ndisp)
        return _fold(no_winners(cost.shape[1:]), with_halo(cost), 0, limit)

    # Each step aggregates a block of K slices and folds the block of the previous step, which
    # the loop carries: every slice is computed once, and the fold reads a materialised block
    # (XLA would otherwise recompute the last filtering pass inside each of its consumers).
    # The first step folds an empty block (disparities -K .. -1, all +inf).
    height, width = scene.left.shape[:2]
    inf_plane = jnp.full((height, width), jnp.inf, jnp.float32)
    firsts = jnp.arange(0, ndisp, chunk)

    def fold(state, block, before, after, first):
        planes = [before, *(block[k] for k in range(chunk)), after]
        return _fold(state, planes, first, limit)

    def step(carry, first):
        state, previous, before = carry
        # The last block may run past ndisp: those slices are computed but masked by the fold.
        block = aggregate_slices(scene, params, first, chunk)
        state = fold(state, previous, before, block[0], first - chunk)
        return (state, block, previous[-1]), None

    empty = jnp.full((chunk, height, width), jnp.inf, jnp.float32)
    start = (no_winners((height, width)), empty, inf_plane)
    (winners, last, before), _ = jax.lax.scan(step, start, firsts)
    return fold(winners, last, before, inf_plane, firsts[-1])
