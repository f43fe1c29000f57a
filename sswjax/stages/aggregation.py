"""Segment-side-window cost aggregation (paper Section III-B, Eq. 6-7).

Array conventions (whole module): cost volumes are float32 ``(D, H, W)`` (disparity first,
lower is better); the guide is the left image, float32 ``(H, W, C)`` in [0, 1], C in {1, 3};
superpixel labels are int32 ``(H, W)`` in ``[0, num_segments)``.

Interpretation of Eq. (7). The paper filters ``w(p, q) [C(p, d) + S(p)]`` over a side window,
with ``S(p)`` "the SLIC value". A label id added to a cost has no meaning, so we read ``S`` as a
segment-level cost: ``S(p, d)`` = mean of ``C(., d)`` over the superpixel of ``p``. The filter
input is ``C + lambda * S`` (blended before filtering), and ``w(p, q)`` is the uniform weight of
the side-window box filter. The window is chosen independently on every cost slice (default) or
once per pixel on the guide image, shared by all disparities; on trainingQ the per-slice choice
measured better once the segment term is in (``docs/reading-the-paper.md``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax

from sswjax._checks import check_floating, check_rank
from sswjax.stages.filters import side_window_box_filter
from sswjax.stages.segments import segment_mean

WINDOW_SELECTIONS = ("slice", "guide")
"""Where a side window is chosen: on every cost slice (Yin et al.'s S-BOX) or on the guide."""


def segment_cost(cost: jax.Array, labels: jax.Array, *, num_segments: int) -> jax.Array:
    """Segment term ``S(p, d)``: the mean cost over the superpixel of ``p`` (our Eq. 7 reading).

    Parameters
    ----------
    cost : float32 (D, H, W)
    labels : int32 (H, W), values in [0, num_segments)
    num_segments : int

    Returns
    -------
    float32 (D, H, W)
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    return segment_mean(cost, labels, num_segments=num_segments)


class SegmentTerm(NamedTuple):
    """The superpixels of the segment term and its weight.

    Attributes
    ----------
    labels : int32 (H, W), values in [0, num_segments)
    num_segments : int
        Static count of labels.
    weight : float or scalar array
        lambda: the filter sees ``C + lambda * S``.
    """

    labels: jax.Array
    num_segments: int
    weight: Any


def segment_side_window_aggregation(
    cost: jax.Array,
    guide: jax.Array,
    *,
    radius: int,
    iterations: int,
    window_selection: str = "slice",
    segments: SegmentTerm | None = None,
    between=None,
) -> jax.Array:
    """Segment-side-window aggregation: ``SWF(C + lambda * S)`` (Eq. 7 as we read it).

    Parameters
    ----------
    cost : float32 (D, H, W)
        Raw matching cost (Eq. 5).
    guide : float32 (H, W, C)
        Left image, selects the side window of each pixel when ``window_selection="guide"``.
    radius, iterations : int
        Side-window radius and number of filtering passes.
    window_selection : {"guide", "slice"}
    segments : SegmentTerm, optional
        Superpixels and lambda; without them (or with ``num_segments=0``) the term is off.
    between : callable, optional
        Applied to the volume between passes (see :func:`side_window_box_filter`).

    Returns
    -------
    float32 (D, H, W)
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    check_rank("guide", guide, 3)
    if guide.shape[:2] != cost.shape[1:]:
        raise ValueError(f"guide size {guide.shape[:2]} differs from cost size {cost.shape[1:]}")
    if window_selection not in WINDOW_SELECTIONS:
        raise ValueError(f"window_selection must be one of {WINDOW_SELECTIONS}, "
                         f"got {window_selection!r}")
    if segments is not None and segments.num_segments > 0:
        cost = cost + segments.weight * segment_cost(
            cost, segments.labels, num_segments=segments.num_segments)
    return side_window_box_filter(
        cost, radius=radius, iterations=iterations,
        guide=guide if window_selection == "guide" else None, between=between,
    )
