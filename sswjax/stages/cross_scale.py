"""Semi-global optimisation across scales: the paths at half resolution, added back to the
full-resolution cost (cross-scale aggregation, Zhang et al., "Cross-Scale Cost Aggregation for
Stereo Matching", CVPR 2014, with SGM as the coarse scale's aggregator).

Array conventions (whole module): cost volumes float32 ``(D, H, W)``, lower is better; the
guide is the left image, float32 ``(H, W, C)`` in [0, 1].
"""

from __future__ import annotations

import jax

from sswjax._checks import check_floating, check_rank
from sswjax.stages.pyramid import double_volume, halve_image, halve_volume
from sswjax.stages.sgm import semi_global

__all__ = ["half_resolution_semi_global"]


def half_resolution_semi_global(
    cost: jax.Array,
    guide: jax.Array,
    *,
    p1,
    p2,
    sigma=0.05,
    paths: int = 4,
    detail_weight=1.0,
    cost_bound=None,
    cost_levels=None,
) -> jax.Array:
    """Semi-global optimisation at half resolution, added back to the full-resolution cost.

    The volume is halved in space and disparity (:func:`sswjax.stages.pyramid.halve_volume`),
    optimised by :func:`semi_global` with the halved guide, doubled back, and the
    full-resolution cost weighted by ``detail_weight`` is added: the coarse paths carry the
    evidence across weakly textured areas for an eighth of the work, and the fine cost decides
    between the two disparities and the four pixels that each coarse cell stands for. This is
    cross-scale aggregation in the sense of Zhang et al. (CVPR 2014), with SGM as the coarse
    scale's aggregator. A coarse disparity step is two fine ones, so ``p1`` acts on steps of 2.

    Parameters
    ----------
    cost : float32 (D, H, W)
    guide : float32 (H, W, C)
    p1, p2, sigma, paths, cost_bound, cost_levels
        As in :func:`semi_global_sums` (halving averages, so the bound holds at half resolution).
    detail_weight : float or scalar array, >= 0
        Weight of the full-resolution cost in the sum.

    Returns
    -------
    float32 (D, H, W), lower is better.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> cost = jnp.ones((6, 8, 10)).at[3].set(0.0)
    >>> out = half_resolution_semi_global(cost, jnp.zeros((8, 10, 1)), p1=0.1, p2=0.5)
    >>> out.shape, int(out.argmin(axis=0).min()), int(out.argmin(axis=0).max())
    ((6, 8, 10), 3, 3)
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    coarse = semi_global(halve_volume(cost), halve_image(guide), p1=p1, p2=p2, sigma=sigma,
                         paths=paths, cost_bound=cost_bound, cost_levels=cost_levels)
    return detail_weight * cost + double_volume(coarse, shape=cost.shape)
