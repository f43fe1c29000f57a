"""Configuration of the tests that reject a pixel's disparity: the left-right check (Eq. 9),
the uniqueness of each right pixel's claim and the right view of the aggregated cost.

The graph (:mod:`sswjax.graph.refine`) reads these options; the stage functions are those of
:mod:`sswjax.stages.checks`.
"""

from __future__ import annotations

from sswjax.config.fields import ConfigError, is_set, option
from sswjax.config.parts import Part, register

__all__ = ["LeftRightCheck"]


@register("checks", "lr")
class LeftRightCheck(Part):
    """Left-right consistency check (Eq. 9), optionally with two occlusion tests: uniqueness of
    each right pixel's claim, and the right view of the cost before optimisation."""

    tolerance: float = option(0.0, low=0, grid=0.5, help="largest left / right disagreement "
                              "accepted, in pixels")
    uniqueness_gap: int = option(0, static=True, low=0, high=100_000, grid=1,
                                 help="g > 0: also reject a pixel whose right pixel is claimed "
                                      "by a disparity g or more apart at a lower cost before "
                                      "aggregation; 0: off")
    uniqueness_radius: int = option(2, static=True, low=0, high=50,
                                    help="the claims' costs are means over (2r+1)^2 pixels; 0: "
                                         "the pixel's own cost")
    aggregated_gap: int = option(0, static=True, low=0, high=100_000, grid=1,
                                 help="g > 0 (with an optimizer): also reject where the right "
                                      "view of the aggregated cost before the optimiser "
                                      "disagrees by g or more; 0: off")

    def validate(self, params) -> None:
        """The uniqueness radius needs the test on; the aggregated view an optimiser."""
        if self.uniqueness_gap == 0 and is_set(self, "uniqueness_radius"):
            raise ConfigError("checks.uniqueness_radius", "parameter checks.uniqueness_radius "
                              "acts only with checks.uniqueness_gap > 0")
        if self.aggregated_gap > 0 and params.optimizer is None:
            raise ConfigError("checks.aggregated_gap", "parameter checks.aggregated_gap needs an "
                              "optimizer: without one the aggregated cost is the one selected")
