"""Configuration of the full-resolution band: the search of a few disparities around the map
of the stages before it (tSGM, Rothermel et al. 2012).

The graph (:mod:`sswjax.graph.band`) reads these options; the stage functions are those of
:mod:`sswjax.stages.bands` and the band recursion of
:func:`~sswjax.stages.sgm.semi_global_sums` (``starts``).
"""

from __future__ import annotations

from sswjax.config.fields import ConfigError, option
from sswjax.config.parts import Part, register

__all__ = ["DisparityBand"]


@register("band", "around-map")
class DisparityBand(Part):
    """At full resolution, only ``width`` disparities around each pixel's disparity from the
    stages before (the coarse pass's doubled map, or the full-range map): the cost, its
    aggregation, the semi-global paths in absolute disparities, the selection, the checks and
    the fill run again over that band."""

    # Band volumes are unrolled plane by plane (the cost's gathers, the fold): at most 32.
    width: int = option(7, static=True, low=2, high=32, help="disparities each pixel searches, "
                        "centred on its estimate (K)")
    spread_radius: int = option(0, static=True, low=0, high=8, help="r > 0: centre each "
                                "band on the range of the estimates in the pixel's "
                                "(2r + 1)^2 window where that range fits in the band "
                                "(both sides of a depth edge); 0: on the pixel's own estimate")
    segment_range: bool = option(False, static=True, help="centre each band on the range of "
                                 "the estimates in the pixel's superpixel where that range fits "
                                 "in the band (needs segments); else as spread_radius says")
    aggregate: bool = option(True, static=True, help="aggregate the band's cost with the "
                             "aggregation stage, plane by plane (each plane follows the "
                             "estimate); False: the paths read the matching cost")
    paths: bool = option(True, static=True, help="run the optimizer's semi-global paths over "
                         "the band; False: each pixel's winner is the band's lowest cost "
                         "(aggregated or not), the coarse pass keeping its paths")

    @property
    def uses_segments(self) -> bool:
        """Whether it reads the superpixels (``segment_range``)."""
        return self.segment_range

    def validate(self, params) -> None:
        """The optimiser must run over per-pixel bands; a segment range needs superpixels."""
        if self.segment_range and params.segments is None:
            raise ConfigError("band.segment_range", "band.segment_range takes each band's "
                              "range over its superpixel: it needs segments (--set segments=slic)")
        if params.optimizer is not None and not params.optimizer.searches_bands:
            raise ConfigError("band", f"band: the optimizer {params.optimizer.kind!r} does not "
                              "run over per-pixel disparity bands (use 'sgm' or none)")
