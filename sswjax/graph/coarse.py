"""Coarse-to-fine: the method on the pair halved, its map doubled back guided by the left image.

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
from sswjax.stages.confidence import ConfidenceCues
from sswjax.stages.medians import side_window_median_filter
from sswjax.stages.pyramid import halve_image
from sswjax.stages.upsampling import double_nearest, upsample_disparity

__all__ = ["match_coarse_to_fine"]


def match_coarse_to_fine(left: jax.Array, right: jax.Array, params: Params, ndisp: int,
                         valid_ndisp, match: Callable, *, valid_shape=None
                         ) -> tuple[jax.Array, ConfidenceCues]:
    """``params.coarse`` with ``levels = L``: the method with ``L - 1`` levels on the pair
    halved, its map doubled back guided by the left image
    (:func:`~sswjax.stages.upsampling.upsample_disparity`), then a small side-window median.

    ``match(left, right, params, ndisp, valid_ndisp, valid_shape=) -> (map, cues)`` runs the
    method on the halved pair; ``valid_shape`` (int32 (2,), a padded pair's own size) is
    halved up, a coarse pixel counting as the pair's when any of its fine pixels does. The confidence cues are the coarse ones, each on the fine pixels its coarse
    pixel covers (disparities and distances doubled).
    """
    coarse = params.coarse
    limit = ndisp if valid_ndisp is None else valid_ndisp
    small_left, small_right = halve_image(left), halve_image(right)
    coarse_shape = None if valid_shape is None else (valid_shape + 1) // 2
    if coarse_shape is not None:
        # A bucket's padding halved is not the halved pair's edge: copied again from it.
        small_left, small_right = (
            jnp.moveaxis(padding_as_edge(jnp.moveaxis(image, -1, 0), coarse_shape), 0, -1)
            for image in (small_left, small_right))
    # Fine disparities 0 .. ndisp - 1 are coarse 0 .. (ndisp - 1) / 2: ndisp // 2 + 1 of them,
    # within the halved width.
    coarse_ndisp = min(ndisp // 2 + 1, small_left.shape[1] - 1)
    coarse_limit = None if valid_ndisp is None else jnp.minimum(valid_ndisp // 2 + 1, coarse_ndisp)
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
        doubled = ConfidenceCues(*(double_nearest(cue, shape=shape) for cue in cues))
        cues = doubled._replace(lr_distance=2 * doubled.lr_distance, initial=2 * doubled.initial)
    return disparity, cues
