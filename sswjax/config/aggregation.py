"""Configurations of the aggregation of the cost volume: the paper's segment-side-window filter
and the baselines of its Table 1 that replace it.

Array conventions (whole module): ``aggregate(cost, guide, labels=, num_segments=)`` takes a
float32 ``(D, H, W)`` cost volume (lower is better), the left image float32 ``(H, W, C)`` in
[0, 1] and the superpixels (int32 ``(H, W)`` labels and their static count, 0 without them),
and returns a float32 ``(D, H, W)`` volume. Every aggregator acts on each disparity slice alone,
so slices aggregated in blocks equal those of the whole volume.
"""

from __future__ import annotations

import jax

from sswjax.config.fields import ConfigError, Softplus, is_set, option
from sswjax.config.parts import Part, register
from sswjax.stages.aggregation import WINDOW_SELECTIONS, SegmentTerm, segment_side_window_aggregation
from sswjax.stages.baselines import bilateral_filter, box_filter, median_cost_filter
from sswjax.stages.guided import guided_filter, iterated_guided_filter

__all__ = ["Aggregator", "BilateralAggregation", "BoxAggregation", "GuidedAggregation",
           "IteratedGuidedAggregation", "MedianAggregation", "SideWindowAggregation"]


class Aggregator(Part):
    """Base of the aggregators. ``uses_segments``: whether it reads the superpixels."""

    uses_segments = False

    def aggregate(self, cost: jax.Array, guide: jax.Array, *, labels: jax.Array,
                  num_segments: int, edge=None) -> jax.Array:
        """float32 (D, H, W) -> float32 (D, H, W).

        ``edge`` (optional): ``edge(volume, reach)``, what a filter of several passes applies
        between them, ``reach`` its radius (the graph's copy of the edge into a shape bucket's
        padding, :func:`sswjax.graph.padding.padding_as_edge`); single passes do not need it.
        """
        raise NotImplementedError

    def bound_factor(self, segments: bool):
        """What the aggregation multiplies the largest matching cost by (None: nothing; an
        average keeps it)."""
        return None


@register("aggregation", "ssw")
class SideWindowAggregation(Aggregator):
    """Segment-side-window box filter with the superpixel cost term, the paper's method (Eq. 7)."""

    radius: int = option(4, static=True, low=1, high=50, help="side-window radius r (Eq. 7)")
    iterations: int = option(3, static=True, low=0, high=20,
                             help="side-window filtering passes over the volume")
    window_selection: str = option("slice", static=True, choices=WINDOW_SELECTIONS,
                                   help="'slice': each slice picks its windows (Yin et al. "
                                        "2019); 'guide': the left image picks them for all")
    segment_weight: float = option(0.59967893, low=0, search=Softplus(0.0),
                                   help="lambda: the filter sees C + lambda S (Eq. 7 as we read "
                                        "it); with segments only")

    uses_segments = True

    def validate(self, params) -> None:
        """The segment weight acts only with superpixels."""
        if params.segments is None and is_set(self, "segment_weight"):
            raise ConfigError("aggregation.segment_weight", "parameter aggregation.segment_weight "
                              "acts only with superpixels (segments is None)")

    def aggregate(self, cost, guide, *, labels, num_segments, edge=None):
        """:func:`~sswjax.stages.aggregation.segment_side_window_aggregation` (the segment term
        is off without superpixels)."""
        segments = SegmentTerm(labels, num_segments, self.segment_weight)
        return segment_side_window_aggregation(cost, guide, radius=self.radius,
                                               iterations=self.iterations,
                                               window_selection=self.window_selection,
                                               segments=segments, between=edge)

    def bound_factor(self, segments: bool):
        """``1 + lambda`` with the segment term: the filter averages ``C + lambda S``."""
        return 1.0 + abs(self.segment_weight) if segments else None


@register("aggregation", "box")
class BoxAggregation(Aggregator):
    """Square box mean (Scharstein & Szeliski 2002)."""

    radius: int = option(4, static=True, low=1, high=50, help="window radius")

    def aggregate(self, cost, guide, *, labels, num_segments, edge=None):
        """:func:`~sswjax.stages.baselines.box_filter`."""
        return box_filter(cost, radius=self.radius)


@register("aggregation", "bf")
class BilateralAggregation(Aggregator):
    """Bilateral / adaptive support weights (Yoon & Kweon 2006)."""

    radius: int = option(4, static=True, low=1, high=50, help="window radius")

    def aggregate(self, cost, guide, *, labels, num_segments, edge=None):
        """:func:`~sswjax.stages.baselines.bilateral_filter`."""
        return bilateral_filter(cost, guide, radius=self.radius)


@register("aggregation", "gf")
class GuidedAggregation(Aggregator):
    """Colour guided filter, eps 1e-4 (He et al. 2013; Hosni et al. 2013)."""

    radius: int = option(9, static=True, low=1, high=50,
                         help="window radius (9, as in Hosni et al. 2013)")

    def aggregate(self, cost, guide, *, labels, num_segments, edge=None):
        """:func:`~sswjax.stages.baselines.guided_filter`."""
        return guided_filter(cost, guide, radius=self.radius)


@register("aggregation", "igf")
class IteratedGuidedAggregation(Aggregator):
    """Two guided-filter passes."""

    radius: int = option(9, static=True, low=1, high=50, help="window radius")

    def aggregate(self, cost, guide, *, labels, num_segments, edge=None):
        """:func:`~sswjax.stages.baselines.iterated_guided_filter`."""
        return iterated_guided_filter(cost, guide, radius=self.radius)


@register("aggregation", "mf")
class MedianAggregation(Aggregator):
    """Median of each cost slice, 5x5."""

    # The sorting network of a (2r + 1)^2 window: 128 inputs at most (r <= 5) compile.
    radius: int = option(2, static=True, low=1, high=5, help="window radius")

    def aggregate(self, cost, guide, *, labels, num_segments, edge=None):
        """:func:`~sswjax.stages.baselines.median_cost_filter`."""
        return median_cost_filter(cost, radius=self.radius)
