"""Configuration of the smoothing of the finished map.

The graph (:mod:`sswjax.graph.match`) calls :meth:`GatedBilateralSmoothing.smooth`, which runs
:func:`~sswjax.stages.smoothing.gated_bilateral_smoothing` (passes of
:func:`~sswjax.stages.smoothing.gated_bilateral_mean` or its separable form,
:func:`~sswjax.stages.smoothing.gated_bilateral_line_mean`).
"""

from __future__ import annotations

import jax.numpy as jnp

from sswjax.config.fields import option
from sswjax.config.parts import Part, register
from sswjax.stages.smoothing import gated_bilateral_smoothing

__all__ = ["GatedBilateralSmoothing"]


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
