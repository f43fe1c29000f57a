"""Configurations of the last stages: the median over the disparity map and coarse-to-fine.

The graph reads these options (:mod:`sswjax.graph.refine`, :mod:`sswjax.graph.coarse`); the
stage functions are :func:`~sswjax.stages.filters.side_window_median_filter`,
:func:`~sswjax.stages.pyramid.halve_image` and
:func:`~sswjax.stages.upsampling.upsample_disparity`.
"""

from __future__ import annotations

from sswjax.config.fields import ConfigError, is_set, option
from sswjax.config.parts import Part, register

__all__ = ["CoarseToFine", "SideWindowMedian"]


@register("refinement", "side-window-median")
class SideWindowMedian(Part):
    """Side-window median filter over the disparity map, the paper's last step."""

    # The side windows' sorting networks have (r + 1)(2r + 1) inputs: at most 128 (r <= 7).
    radius: int = option(2, static=True, low=1, high=7, help="radius of the side windows")
    iterations: int = option(2, static=True, low=1, high=20, help="passes of the filter")


@register("coarse", "halving")
class CoarseToFine(Part):
    """The method on the pair halved ``levels`` times (ndisp halved too), its map doubled back
    guided by the left image: about 8 ** levels times less volume work (the ``fast`` preset)."""

    levels: int = option(1, static=True, low=1, high=4, help="times the pair is halved")
    median_radius: int = option(1, static=True, low=0, high=7,
                                help="radius of the side-window median after each doubling; "
                                     "0: none")
    median_iterations: int = option(2, static=True, low=1, high=20,
                                    help="passes of that median")
    jump: float = option(3.0, low=0, help="largest spread (fine pixels) of the four coarse "
                         "neighbours that a doubled pixel interpolates; beyond it the nearest "
                         "colour's")

    def validate(self, params) -> None:
        """The median's passes need the median."""
        if self.median_radius == 0 and is_set(self, "median_iterations"):
            raise ConfigError("coarse.median_iterations", "parameter coarse.median_iterations "
                              "acts only with coarse.median_radius > 0")
