"""Configurations of the last stages: the median over the disparity map, coarse-to-fine and
the smoothing of the finished map.

The graph reads these options (:mod:`sswjax.graph.refine`, :mod:`sswjax.graph.coarse`,
:mod:`sswjax.graph.match`); the stage functions are
:func:`~sswjax.stages.filters.side_window_median_filter`,
:func:`~sswjax.stages.pyramid.halve_image`,
:func:`~sswjax.stages.upsampling.upsample_disparity`, :mod:`sswjax.stages.refit` and
:func:`~sswjax.stages.smoothing.gated_bilateral_smoothing` (passes of
:func:`~sswjax.stages.smoothing.gated_bilateral_mean` or its separable form,
:func:`~sswjax.stages.smoothing.gated_bilateral_line_mean`).
"""

from __future__ import annotations

import jax.numpy as jnp

from sswjax.config.fields import ConfigError, is_set, option
from sswjax.config.parts import Part, register
from sswjax.stages.smoothing import gated_bilateral_smoothing

__all__ = ["CoarseToFine", "GatedBilateralSmoothing", "SideWindowMedian"]


@register("refinement", "side-window-median")
class SideWindowMedian(Part):
    """Side-window median filter over the disparity map, the paper's last step."""

    # The side windows' sorting networks have (r + 1)(2r + 1) inputs: at most 128 (r <= 7).
    radius: int = option(2, static=True, low=1, high=7, help="radius of the side windows")
    iterations: int = option(2, static=True, low=1, high=20, help="passes of the filter")


@register("coarse", "halving")
class CoarseToFine(Part):
    """The method on the pair halved ``levels`` times (ndisp halved too), its map doubled back
    guided by the left image: about 8 ** levels times less volume work (the ``fast`` preset);
    optionally fitted again on the finer level's cost (``refit_radius``)."""

    levels: int = option(1, static=True, low=1, high=4, help="times the pair is halved")
    median_radius: int = option(1, static=True, low=0, high=7,
                                help="radius of the side-window median after each doubling; "
                                     "0: none")
    median_iterations: int = option(2, static=True, low=1, high=20,
                                    help="passes of that median")
    jump: float = option(3.0, low=0, help="largest spread (fine pixels) of the four coarse "
                         "neighbours that a doubled pixel interpolates; beyond it the nearest "
                         "colour's")
    refit_radius: int = option(0, static=True, low=0, high=7, help="r > 0: after each "
                               "doubling, fit each pixel's disparity again on the finer level's "
                               "matching cost at its rounded disparity and the two beside it, "
                               "each averaged over a (2r + 1)^2 window; 0: none")

    def validate(self, params) -> None:
        """The median's passes need the median."""
        if self.median_radius == 0 and is_set(self, "median_iterations"):
            raise ConfigError("coarse.median_iterations", "parameter coarse.median_iterations "
                              "acts only with coarse.median_radius > 0")


@register("smoothing", "gated-bilateral")
class GatedBilateralSmoothing(Part):
    """The finished map averaged over each pixel's neighbours on its own surface: weighted by
    colour, neighbours more than ``gate`` pixels away left out; at full resolution, last. Turns
    the integer steps of a slanted surface back into its ramp (bad 1.0 and 0.5)."""

    # (2r + 1)^2 shifted windows, unrolled: r <= 7 keeps the graph small.
    radius: int = option(3, static=True, low=1, high=7, help="window radius")
    gate: float = option(1.0, above=0, grid=0.5, help="largest disparity difference (pixels) "
                         "of a neighbour that is averaged")
    colour_scale: float = option(0.1, above=0, help="scale of the colour weight (sum of "
                                 "absolute channel differences, intensities in [0, 1])")
    iterations: int = option(1, static=True, low=1, high=4, help="passes of the filter")
    separable: bool = option(False, static=True, help="a row then a column of the window per "
                             "pass instead of the square: 3.5x fewer weights at radius 3, an "
                             "approximation")
    tilted: bool = option(False, static=True, help="measure the gate from the map's local slope "
                          "through the pixel, not from its own disparity: a steep surface keeps "
                          "its far neighbours (the trilateral filter's tilt)")

    def smooth(self, disparity, guide, limit):
        """float32 (H, W) map and (H, W, C) left image -> the smoothed map in [0, limit - 1]."""
        disparity = gated_bilateral_smoothing(disparity, guide, radius=self.radius, gate=self.gate,
                                              colour_scale=self.colour_scale,
                                              iterations=self.iterations,
                                              separable=self.separable, tilted=self.tilted)
        return jnp.clip(disparity, 0, limit - 1)
