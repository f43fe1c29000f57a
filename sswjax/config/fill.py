"""Configurations of the fills of the pixels the checks reject (Eq. 9 and beyond).

Array conventions (whole module): ``fill(disparity, valid, guide=, labels=, num_segments=)``
takes the disparity map float32 ``(H, W)`` in pixels, the validity bool ``(H, W)`` (True where
the checks passed), the left image float32 ``(H, W, C)`` in [0, 1] and the superpixels (int32
``(H, W)`` and their static count, 0 without them); it returns a dense float32 ``(H, W)`` map
equal to ``disparity`` where ``valid``.
"""

from __future__ import annotations

import jax

from sswjax.config.fields import ConfigError, option, stage_config
from sswjax.config.parts import Part, register
from sswjax.stages.fill import SOURCES, vote_fill, weighted_median_fill
from sswjax.stages.planes import plane_refine
from sswjax.stages.background import MEDIANS, fill_invalid

__all__ = ["BackgroundFill", "Fill", "LeftBandFill", "PlaneFill", "VoteFill",
           "WeightedMedianFill"]

_SQUARE_RADIUS = 5
"""The square median's sorting network has (2r + 1)^2 inputs: at most 128 (a 512-input network
took over 20 GB to compile); the separable median's networks have 2r + 1."""


class Fill(Part):
    """Base of the fills. ``uses_segments``: whether it reads the superpixels."""

    uses_segments = False

    def fill(self, disparity: jax.Array, valid: jax.Array, *, guide: jax.Array,
             labels: jax.Array, num_segments: int) -> jax.Array:
        """The dense map (module docstring)."""
        raise NotImplementedError


@stage_config
class _MedianOptions(Fill):
    """The median over the filled pixels that the background rule ends with."""

    median_radius: int = option(2, static=True, low=0, high=15,
                                help="radius of the median over the filled pixels (Eq. 9); 0: "
                                     "none")
    median: str = option("square", static=True, choices=tuple(MEDIANS),
                         help="'square': the exact (2r+1)^2 median (r <= 5); 'separable': the "
                              "median of its column medians, far cheaper for wide windows")

    def validate(self, params) -> None:
        """The square median's radius bound."""
        if self.median == "square" and self.median_radius > _SQUARE_RADIUS:
            raise ConfigError("fill.median_radius", f"parameter fill.median_radius must be in "
                              f"[0, {_SQUARE_RADIUS}] with fill.median 'square', got "
                              f"{self.median_radius}")


def _band_fit():
    """The ``band_fit`` option of the fills that treat the left band."""
    return option(0, static=True, low=0, high=100_000,
                  help="k > 0: the band left of each row's first valid pixel takes a line "
                       "fitted to the next k valid columns; 0: their constant")


@register("fill", "background")
class BackgroundFill(_MedianOptions):
    """The nearer-background valid disparity of the row, then a median over the filled pixels
    (Eq. 9 as we read it)."""

    def fill(self, disparity, valid, *, guide, labels, num_segments):
        """:func:`~sswjax.stages.background.fill_invalid`."""
        return fill_invalid(disparity, valid, radius=self.median_radius, median=self.median)


@register("fill", "left-band")
class LeftBandFill(_MedianOptions):
    """The background fill, but the surface on the right where the pixel has no match at its
    column (x < d), the left border's case."""

    band_fit: int = _band_fit()

    def fill(self, disparity, valid, *, guide, labels, num_segments):
        """:func:`~sswjax.stages.background.fill_invalid` with ``left_band``."""
        return fill_invalid(disparity, valid, radius=self.median_radius, left_band=True,
                            median=self.median, band_fit=self.band_fit)


@register("fill", "vote")
class VoteFill(_MedianOptions):
    """The left-band fill, then a vote among it and the nearest valid disparities left and right
    on the row, by neighbours weighted by intensity likeness."""

    band_fit: int = _band_fit()
    radius: int = option(9, static=True, low=1, high=50, help="radius of the sampled window")
    step: int = option(4, static=True, low=1, high=50, help="sampling step of the window")
    sigma: float = option(0.2, above=0, grid=0.1, help="intensity difference at which a "
                          "neighbour's vote weighs a quarter of an identical one's")
    tolerance: float = option(2.0, low=0, grid=1.0, help="how close (pixels) a neighbour's "
                              "disparity must be to a candidate to vote for it")

    def fill(self, disparity, valid, *, guide, labels, num_segments):
        """:func:`~sswjax.stages.fill.vote_fill`."""
        return vote_fill(disparity, valid, guide=guide, median_radius=self.median_radius,
                         radius=self.radius, step=self.step, sigma=self.sigma,
                         tolerance=self.tolerance, median=self.median, band_fit=self.band_fit)


@register("fill", "wmedian")
class WeightedMedianFill(Fill):
    """The left-band fill, then a weighted median of the neighbours' disparities, weighted by
    the guided filter on the left image (Rhemann et al. 2011, Ma et al. 2013)."""

    radius: int = option(9, static=True, low=1, high=50, help="window radius of the guided "
                         "weights")
    eps: float = option(1e-3, above=0, help="guided-filter regularisation of the weights "
                        "(intensities in [0, 1])")
    quantile: float = option(0.5, above=0, high=1, help="the weighted quantile taken: 0.5 the "
                             "median, less leans to the background")
    source: str = option("filled", static=True, choices=SOURCES,
                         help="what the median counts: every pixel of the background-filled "
                              "map ('filled') or the valid ones")
    band_fit: int = _band_fit()

    def fill(self, disparity, valid, *, guide, labels, num_segments):
        """:func:`~sswjax.stages.fill.weighted_median_fill`."""
        return weighted_median_fill(disparity, valid, radius=self.radius, guide=guide,
                                    eps=self.eps, quantile=self.quantile, source=self.source,
                                    band_fit=self.band_fit)


@register("fill", "plane")
class PlaneFill(_MedianOptions):
    """A robust plane per superpixel through its valid pixels where they support it, else the
    background fill."""

    min_support: float = option(0.25, low=0, high=1, help="share of a superpixel's pixels that "
                                "must be valid inliers for its plane to fill it")
    inlier_scale: float = option(1.0, above=0, help="residual (pixels) up to which a pixel keeps "
                                 "full weight in the robust fit")

    uses_segments = True

    def validate(self, params) -> None:
        """The planes are fitted per superpixel."""
        super().validate(params)
        if params.segments is None:
            raise ConfigError("fill", "fill 'plane' fits a plane per superpixel: it needs "
                              "segments (--set segments=slic)")

    def fill(self, disparity, valid, *, guide, labels, num_segments):
        """The background fill, then :func:`~sswjax.stages.planes.plane_refine`."""
        filled = fill_invalid(disparity, valid, radius=self.median_radius, median=self.median)
        return plane_refine(filled, valid, labels, num_segments=num_segments,
                            min_support=self.min_support, inlier_scale=self.inlier_scale)
