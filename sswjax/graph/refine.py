"""After the winners are known: sub-pixel fit, the checks, the fill and the median (Eq. 8-9).

Array conventions (whole module): maps float32 ``(H, W)`` in pixels, validity bool ``(H, W)``;
the winners and the scene of :mod:`sswjax.graph.volume`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax.config import Params
from sswjax.graph.padding import outside_as_border, padding_as_edge
from sswjax.graph.scopes import Stage, scope
from sswjax.graph.volume import Scene, Selected, cost_bound
from sswjax.stages.baselines import box_filter
from sswjax.stages.confidence import ConfidenceCues
from sswjax.stages.medians import side_window_median_filter
from sswjax.stages.checks import left_right_distance, uniqueness_violations
from sswjax.stages.selection import SUBPIXEL_FITS

__all__ = ["refine"]


def _checked(selected: Selected, scene: Scene, params: Params, distance: jax.Array) -> jax.Array:
    """Where the checks of ``params.checks`` accept the winners: bool (H, W)."""
    checks, winners = params.checks, selected.winners
    # The left-right check (stages.reference.left_right_consistency) on a distance kept for
    # the confidence.
    valid = distance <= checks.tolerance
    if checks.uniqueness_gap > 0:
        claim = params.cost.at(scene.features, winners.disparity)
        if checks.uniqueness_radius > 0:
            claim = box_filter(padding_as_edge(claim, scene.valid_shape),
                               radius=checks.uniqueness_radius)
        # A bucket's padding claims no right pixel (at the largest cost it loses every claim).
        claim = outside_as_border(claim, scene.valid_shape, params.cost.bound())
        valid &= ~uniqueness_violations(winners.disparity, claim, gap=checks.uniqueness_gap)
    if checks.aggregated_gap > 0 and selected.aggregated_right is not None:
        # The optimiser spreads the foreground over occlusions in both views alike; the
        # aggregated cost's right view has not been spread.
        valid &= left_right_distance(winners.disparity, selected.aggregated_right) \
            < checks.aggregated_gap
    return valid


def refine(selected: Selected, scene: Scene, params: Params, limit
           ) -> tuple[jax.Array, ConfidenceCues]:
    """Eq. (8)-(9): parabola, the checks, the fill of what they reject, side-window median.

    Parameters
    ----------
    selected : Selected
        The winners (and the costs of their parabola when they come from another volume than
        the winners', and the aggregated cost's right view).
    scene : Scene
    params : Params
    limit : int or int32 scalar
        The search range: the map is clipped to ``[0, limit - 1]``.

    Returns
    -------
    (float32 (H, W), ConfidenceCues)
        The dense map and the cues of its confidence (:mod:`sswjax.stages.confidence`);
        callers that keep only the map let ``jit`` drop the cues.
    """
    # Each map the filters below read is replicated into a shape bucket's padding, as they pad
    # (the other maps are read pixel by pixel).
    def edge(values):
        return padding_as_edge(values, scene.valid_shape)

    winners = selected.winners._replace(disparity=edge(selected.winners.disparity))
    with scope(Stage.SELECTION):
        if params.selection.subpixel:
            before, centre, after = selected.parabola or (winners.before, winners.cost,
                                                          winners.after)
            fit = SUBPIXEL_FITS[params.selection.fit]
            disparity = fit(winners.disparity, before, centre, after, ndisp=limit)
        else:
            disparity = winners.disparity.astype(jnp.float32)
    initial = disparity
    failed = jnp.zeros(disparity.shape, bool)
    with scope(Stage.REFINEMENT):
        distance = left_right_distance(winners.disparity, winners.right_disparity)
        if params.checks is not None:
            valid = edge(_checked(selected._replace(winners=winners), scene, params, distance))
            failed = ~valid
            disparity = params.fill.fill(edge(disparity), valid, guide=scene.left,
                                         labels=scene.labels, num_segments=scene.num_segments)
        median = params.refinement
        if median is not None:
            disparity = side_window_median_filter(edge(disparity), radius=median.radius,
                                                  iterations=median.iterations)
        disparity = jnp.clip(disparity, 0, limit - 1)
    margin = selected.margin
    if margin is None:  # the winners are the aggregated cost's
        margin = (winners.second - winners.cost) / cost_bound(params)
    cues = ConfidenceCues(winners.cost, winners.second, distance, initial, failed, margin)
    return disparity, cues
