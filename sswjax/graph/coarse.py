"""Coarse-to-fine: the method on the pair halved, its map doubled back guided by the left image
and, optionally, fitted again on the full-resolution cost.

Array conventions: images float32 ``(H, W, C)`` in [0, 1]; the map float32 ``(H, W)`` in fine
pixels; the confidence cues those of :class:`~sswjax.stages.confidence.ConfidenceCues`.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from sswjax.config import Params
from sswjax.graph.padding import padding_as_edge
from sswjax.graph.scopes import Stage, scope
from sswjax.graph.volume import cost_features
from sswjax.stages.baselines import box_filter
from sswjax.stages.confidence import ConfidenceCues
from sswjax.stages.medians import side_window_median_filter
from sswjax.stages.pyramid import halve_image
from sswjax.stages.refit import refit_centres, refit_disparity
from sswjax.stages.upsampling import double_nearest, upsample_disparity

__all__ = ["halved_pair", "match_coarse_to_fine", "refit_on_cost"]


def halved_pair(left: jax.Array, right: jax.Array, ndisp: int, valid_ndisp, *, valid_shape=None):
    """The pair halved (:func:`~sswjax.stages.pyramid.halve_image`) and what the method on it
    takes: ``(small_left, small_right, ndisp, valid_ndisp, valid_shape)`` of the halved pair.

    Fine disparities ``0 .. ndisp - 1`` are coarse ``0 .. (ndisp - 1) / 2``: ``ndisp // 2 + 1``
    of them, within the halved width. ``valid_shape`` (int32 (2,), a padded pair's own size)
    is halved up, a coarse pixel counting as the pair's when any of its fine pixels does, and
    the halved padding holds the halved pair's edge again.
    """
    small_left, small_right = halve_image(left), halve_image(right)
    small_shape = None if valid_shape is None else (valid_shape + 1) // 2
    if small_shape is not None:
        small_left, small_right = (
            jnp.moveaxis(padding_as_edge(jnp.moveaxis(image, -1, 0), small_shape), 0, -1)
            for image in (small_left, small_right))
    small_ndisp = min(ndisp // 2 + 1, small_left.shape[1] - 1)
    small_limit = None if valid_ndisp is None else jnp.minimum(valid_ndisp // 2 + 1, small_ndisp)
    return small_left, small_right, small_ndisp, small_limit, small_shape


def match_coarse_to_fine(left: jax.Array, right: jax.Array, params: Params, ndisp: int,
                         valid_ndisp, match: Callable, *, valid_shape=None
                         ) -> tuple[jax.Array, ConfidenceCues]:
    """``params.coarse`` with ``levels = L``: the method with ``L - 1`` levels on the pair
    halved, its map doubled back guided by the left image
    (:func:`~sswjax.stages.upsampling.upsample_disparity`), then a small side-window median
    and, with ``refit_radius``, the fit on the full-resolution cost (:func:`refit_on_cost`).

    ``match(left, right, params, ndisp, valid_ndisp, valid_shape=) -> (map, cues)`` runs the
    method on the halved pair (:func:`halved_pair`). The confidence cues are the coarse ones,
    each on the fine pixels its coarse pixel covers (disparities and distances doubled).
    """
    coarse = params.coarse
    limit = ndisp if valid_ndisp is None else valid_ndisp
    small_left, small_right, coarse_ndisp, coarse_limit, coarse_shape = halved_pair(
        left, right, ndisp, valid_ndisp, valid_shape=valid_shape)
    inner = params.replace(coarse=coarse.replace(levels=coarse.levels - 1)
                           if coarse.levels > 1 else None)
    disparity, cues, _ = match(small_left, small_right, inner, coarse_ndisp, coarse_limit,
                               valid_shape=coarse_shape)
    shape = left.shape[:2]
    with scope(Stage.UPSAMPLING):
        disparity = upsample_disparity(padding_as_edge(disparity, coarse_shape), left, small_left,
                                       jump=coarse.jump)
        if coarse.median_radius > 0:
            disparity = side_window_median_filter(padding_as_edge(disparity, valid_shape),
                                                  radius=coarse.median_radius,
                                                  iterations=coarse.median_iterations)
        disparity = jnp.clip(disparity, 0, limit - 1)
    if coarse.refit_radius > 0:
        with scope(Stage.REFIT):
            disparity = refit_on_cost(left, right, params, disparity, limit=limit,
                                      valid_shape=valid_shape)
    with scope(Stage.UPSAMPLING):
        doubled = ConfidenceCues(*(double_nearest(cue, shape=shape) for cue in cues))
        cues = doubled._replace(lr_distance=2 * doubled.lr_distance, initial=2 * doubled.initial)
    return disparity, cues


def refit_on_cost(left: jax.Array, right: jax.Array, params: Params, disparity: jax.Array, *,
                  limit, valid_shape=None) -> jax.Array:
    """``disparity`` fitted again on the pair's matching cost (Eq. 5) at this resolution.

    Each pixel's cost at its rounded disparity and the two beside it (one gather of the right
    image's features per plane, :meth:`~sswjax.config.MatchingCost.at`) is averaged over the
    ``(2r + 1)^2`` window of ``params.coarse.refit_radius`` (:func:`box_filter`: each plane
    follows the map, as a band's planes do), then
    :func:`~sswjax.stages.refit.refit_disparity` fits it. ``disparity``: float32 (H, W) in
    [0, limit - 1]; ``limit`` and ``valid_shape`` as for :func:`match_coarse_to_fine`'s caller.
    Returns float32 (H, W).
    """
    features = cost_features(left, right, params, valid_shape=valid_shape)
    centres = refit_centres(disparity, limit=limit)
    # A loop over the three planes: its body reads the pair's features from buffers, where
    # a stack of the planes recomputed the left image's census inside every plane's fusion.
    cost = jax.lax.map(lambda k: params.cost.at(features, jnp.clip(centres + k, 0, limit - 1)),
                       jnp.arange(-1, 2))
    cost = box_filter(padding_as_edge(cost, valid_shape), radius=params.coarse.refit_radius)
    return refit_disparity(disparity, centres, *cost, limit=limit)
