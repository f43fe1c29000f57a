"""Configuration of the refinement: the side-window median over the disparity map.

The graph (:mod:`sswjax.graph.refine`) reads these options; the stage function is
:func:`~sswjax.stages.filters.side_window_median_filter`.
"""

from __future__ import annotations

from sswjax.config.fields import option
from sswjax.config.parts import Part, register

__all__ = ["SideWindowMedian"]


@register("refinement", "side-window-median")
class SideWindowMedian(Part):
    """Side-window median filter over the disparity map, the paper's last step."""

    # The side windows' sorting networks have (r + 1)(2r + 1) inputs: at most 128 (r <= 7).
    radius: int = option(2, static=True, low=1, high=7, help="radius of the side windows")
    iterations: int = option(2, static=True, low=1, high=20, help="passes of the filter")
