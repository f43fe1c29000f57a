"""Configuration of coarse-to-fine: the method on the pair halved, the map doubled back.

The graph (:mod:`sswjax.graph.coarse`) reads these options; the stage functions are
:func:`~sswjax.stages.pyramid.halve_image`, :func:`~sswjax.stages.upsampling.upsample_disparity`
and :mod:`sswjax.stages.refit`.
"""

from __future__ import annotations

from sswjax.config.fields import ConfigError, is_set, option
from sswjax.config.parts import Part, register

__all__ = ["CoarseToFine"]


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
