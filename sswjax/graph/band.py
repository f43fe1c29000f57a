"""The full-resolution band: the method again over a few disparities around a map.

Array conventions (whole module): images float32 ``(H, W, C)`` in [0, 1]; maps float32
``(H, W)`` in pixels; band volumes ``(K, H, W)`` with int32 ``(H, W)`` starts
(:mod:`sswjax.stages.bands`); ``limit`` the search range ``0 .. limit - 1`` (the static
``ndisp`` or a traced int32 scalar).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax.config import Params
from sswjax.graph.refine import refine
from sswjax.graph.padding import edge_filler, outside_as_border, padding_as_edge
from sswjax.graph.scopes import Stage, scope
from sswjax.graph.volume import (OUT_OF_RANGE_COST, Scene, Selected, cost_bound, prepare_scene,
                                 stored_scale)
from sswjax.stages.bands import band_right_view, band_starts, band_winners
from sswjax.stages.buffers import written_once
from sswjax.stages.confidence import ConfidenceCues
from sswjax.stages.quantisation import PathSums, quantise_cost

__all__ = ["match_band", "select_band"]


def select_band(scene: Scene, params: Params, estimate: jax.Array, *, ndisp: int, limit
                ) -> Selected:
    """The winners over each pixel's band around ``estimate``, in absolute disparities.

    The band holds ``min(params.band.width, ndisp)`` disparities centred on the estimate and
    kept inside the range; disparities at or beyond a traced ``limit`` cost
    :data:`~sswjax.graph.volume.OUT_OF_RANGE_COST`. Its cost (Eq. 5) is aggregated plane by
    plane, each plane following the estimate (``band.aggregate``), then optimised by the
    semi-global paths in absolute disparities (unless ``band.paths`` is False); the right view
    and the aggregated cost's right view for the occlusion test are folded over the bands.
    """
    band = params.band
    optimizer = params.optimizer if band.paths else None
    width = min(band.width, ndisp)
    # Written once: each reader of the band (the cost's gathers, the paths' alignment, both
    # right views) would otherwise recompute the estimate (the coarse map's upsampling) for
    # every plane of the band.
    segments = ({"labels": scene.labels, "num_segments": scene.num_segments}
                if band.segment_range else {})
    starts = written_once(band_starts(estimate, width=width, limit=limit,
                                       spread_radius=band.spread_radius, **segments))
    with scope(Stage.COST):
        cost = padding_as_edge(params.cost.band(scene.features, starts, width),
                               scene.valid_shape)
    if band.aggregate:
        with scope(Stage.AGGREGATION):
            cost = params.aggregation.aggregate(cost, scene.left, labels=scene.labels,
                                                num_segments=scene.num_segments,
                                                edge=edge_filler(scene.valid_shape))
    cost = outside_as_border(cost, scene.valid_shape, params.cost.bound())
    outside = starts[None] + jnp.arange(width)[:, None, None] >= limit
    cost = jnp.where(outside, jnp.float32(OUT_OF_RANGE_COST), cost)
    bound = cost_bound(params)
    quant = None if optimizer is None else optimizer.storage(bound)
    # Written once: XLA would otherwise fuse the aggregation into each of its readers.
    stored = written_once(cost if quant is None else quantise_cost(cost, quant))
    aggregated_right = None
    if params.checks is not None and params.checks.aggregated_gap > 0:
        aggregated_right = band_right_view(stored, starts)[0]
    optimised = PathSums(cost, None)
    if optimizer is not None:
        with scope(Stage.OPTIMIZATION):
            labels = scene.labels if scene.num_segments else None
            optimised = optimizer.optimise(stored, scene.left, labels=labels, cost_bound=bound,
                                           starts=starts)
        if not isinstance(optimised, PathSums):
            optimised = PathSums(optimised, None)
    with scope(Stage.SELECTION):
        winners = band_winners(optimised.sums, starts, scale=optimised.scale)
    margin = None
    if optimizer is not None:
        # The confidence's margin from the band's aggregated cost, not the paths' sums.
        aggregated = band_winners(stored, starts, scale=stored_scale(params))
        margin = (aggregated.second - aggregated.cost) / bound
    return Selected(winners, None, aggregated_right, margin=margin)


def match_band(left: jax.Array, right: jax.Array, params: Params, estimate: jax.Array, *,
               ndisp: int, limit, scene: Scene | None = None, valid_shape=None
               ) -> tuple[jax.Array, ConfidenceCues]:
    """``params.band``: the winners over the band around ``estimate`` (:func:`select_band`),
    then the refinement of :func:`~sswjax.graph.refine.refine` (parabola, checks, fill,
    median) at full resolution. ``scene``: the pair's, when the pass before prepared it at
    this resolution (else prepared here, ``valid_shape`` as for
    :func:`~sswjax.graph.volume.prepare_scene`).

    Returns
    -------
    (float32 (H, W), ConfidenceCues)
    """
    with scope(Stage.BAND):
        if scene is None:
            scene = prepare_scene(left, right, params, valid_shape=valid_shape)
        selected = select_band(scene, params, estimate, ndisp=ndisp, limit=limit)
        return refine(selected, scene, params, limit)

