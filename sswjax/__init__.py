"""sswjax: Segment-Side-Window stereo matching in JAX.

Al-Asbahi, Kadmin, Hamzah et al., "Enhanced Local Disparity Map Algorithm Segment-Side Window-based
Cost Aggregation and Refinement", 2025: multi-cost matching (TAD + Sobel gradient + census), SLIC
superpixels and side-window filtering for aggregation, winner-takes-all, left-right check, median
filling and side-window refinement.

>>> import sswjax
>>> disparity = sswjax.match(left, right, ndisp=64)          # doctest: +SKIP
"""

from sswjax.params import (DynamicParams, Params, StaticParams, default_params, load_params, preset,
                           save_params)
from sswjax.registry import DEFAULT_PRESET, PRESETS
from sswjax.geometry import Calibration, depth_from_disparity, point_cloud, read_calibration, write_ply
from sswjax.api import Matched, ShapeBuckets, match, match_with_confidence
from sswjax.pipeline import aggregated_cost, select_and_refine, ssw_disparity, ssw_outputs

__all__ = [
    "Calibration",
    "DEFAULT_PRESET",
    "DynamicParams",
    "Matched",
    "PRESETS",
    "Params",
    "ShapeBuckets",
    "StaticParams",
    "aggregated_cost",
    "default_params",
    "depth_from_disparity",
    "load_params",
    "match",
    "match_with_confidence",
    "point_cloud",
    "preset",
    "read_calibration",
    "save_params",
    "select_and_refine",
    "ssw_disparity",
    "ssw_outputs",
    "write_ply",
]
__version__ = "0.1.0"
