"""Configuration of the selection: winner-takes-all and its sub-pixel fit (Eq. 8).

The graph (:mod:`sswjax.graph.refine`) reads these options; the stage functions are those of
:mod:`sswjax.stages.selection`.
"""

from __future__ import annotations

from sswjax.config.fields import option
from sswjax.config.parts import Part, register
from sswjax.stages.selection import SUBPIXEL_FITS

__all__ = ["WinnerTakesAll"]


@register("selection", "wta")
class WinnerTakesAll(Part):
    """Winner-takes-all over the (optimised) volume, with a sub-pixel fit around the minimum:
    Eq. 8's parabola, or two lines of opposite slopes (``fit``)."""

    subpixel: bool = option(True, static=True,
                            help="fit a curve through the costs around the winner (Eq. 8 "
                                 "refined)")
    fit: str = option("parabola", static=True, choices=tuple(SUBPIXEL_FITS),
                      help="the curve of the sub-pixel fit: a parabola (Eq. 8) or two lines "
                           "of opposite slopes (equiangular)")
