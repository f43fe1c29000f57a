"""The sub-pixel fit of a doubled map again, on the full-resolution matching cost.

A map doubled back from the halved pair (:mod:`sswjax.stages.upsampling`) carries the coarse
fit's sub-pixel error twice over and the doubling's interpolation on top: ``fast`` was far
behind the full-resolution method below 2 px (``docs/notes/precision.md``). The hierarchical matchers
(Hirschmuller et al.'s eSGM, ISPRS Annals 2012; the tSGM of Rothermel et al., LC3D 2012) search
a few disparities around the coarse estimate at the finer level. Here the search keeps only
its last step: each pixel's disparity is fitted again (the equiangular lines of Shimizu and
Okutomi, IJCV 2005, Eq. 9, in place of Eq. 8's parabola) on the fine cost at its rounded
disparity and the two beside it, aggregated over a window in which each plane follows the map
(as the band's planes do, :mod:`sswjax.stages.bands`).

Array conventions (whole module): maps float32 ``(H, W)`` in pixels; centres int32 ``(H, W)``;
the costs at each pixel's ``centre - 1``, ``centre`` and ``centre + 1`` three float32
``(H, W)`` planes, lower is better; ``limit`` the search range ``0 .. limit - 1`` (an int, or
a traced int32 scalar under shape buckets).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax._checks import check_floating, check_integer, check_rank, check_same_shape
from sswjax.stages.selection import equiangular_refine

__all__ = ["refit_centres", "refit_disparity"]


def refit_centres(disparity: jax.Array, *, limit) -> jax.Array:
    """The disparity each pixel is fitted around: its map's value rounded, inside the range.

    Parameters
    ----------
    disparity : float32 (H, W)
    limit : int or int32 scalar >= 1

    Returns
    -------
    int32 (H, W) in ``[0, limit - 1]``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> refit_centres(jnp.array([[0.4, 2.6, 9.7]]), limit=9).tolist()
    [[0, 3, 8]]
    """
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    return jnp.clip(jnp.round(disparity), 0, limit - 1).astype(jnp.int32)


def refit_disparity(disparity: jax.Array, centres: jax.Array, before: jax.Array,
                    centre: jax.Array, after: jax.Array, *, limit) -> jax.Array:
    """Each pixel's sub-pixel disparity fitted on the three costs around its centre.

    Where the three costs have a minimum at the centre or slope down to one side, the two lines
    of :func:`~sswjax.stages.selection.equiangular_refine` through them give
    ``centre + offset``, the offset within half a pixel. Where they define no such fit (the
    centre is the highest of the three, or all three are equal) and at the range's ends (the
    centre 0 or ``limit - 1``, whose outer neighbour is outside it), the map's own value stays:
    the fit has nothing to say there, and rounding would only lose the map's sub-pixel part.

    Parameters
    ----------
    disparity : float32 (H, W)
        The map being fitted again.
    centres : int32 (H, W)
        :func:`refit_centres` of ``disparity``.
    before, centre, after : float32 (H, W)
        The cost at ``centres - 1``, ``centres`` and ``centres + 1``.
    limit : int or int32 scalar >= 1

    Returns
    -------
    float32 (H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.array([[4.25, 4.25]])
    >>> cost = jnp.array([[[1.0, 1.0]], [[0.0, 2.0]], [[2.0, 1.0]]])  # a V; a peak
    >>> refit_disparity(d, refit_centres(d, limit=9), *cost, limit=9).tolist()
    [[3.75, 4.25]]
    """
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    check_integer("centres", centres)
    check_same_shape("disparity", disparity, "centres", centres)
    for name, plane in (("before", before), ("centre", centre), ("after", after)):
        check_same_shape("disparity", disparity, name, plane)
    fitted = (centres > 0) & (centres < limit - 1) & (jnp.maximum(before, after) > centre)
    return jnp.where(fitted, equiangular_refine(centres, before, centre, after, ndisp=limit),
                     disparity)
