"""sswjax: Segment-Side-Window stereo matching in JAX.

Al-Asbahi, Kadmin, Hamzah et al., "Enhanced Local Disparity Map Algorithm Segment-Side Window-based
Cost Aggregation and Refinement", 2025: multi-cost matching (TAD + Sobel gradient + census), SLIC
superpixels and side-window filtering for aggregation, winner-takes-all, left-right check, median
filling and side-window refinement.

>>> import sswjax
>>> disparity = sswjax.match(left, right, ndisp=64)          # doctest: +SKIP

The package in layers, each importing only those before it: ``stages`` (pure functions on
arrays) -> ``config`` (the parameters, per stage) -> ``graph`` (the jitted method) ->
``runtime`` (execution plans: buckets, strips, memory, devices) -> ``api`` (the NumPy front
door) -> ``data`` / ``evaluation`` / ``search`` -> ``cli``. This module only names the public
API.

Python's garbage collector is paused while this module imports JAX and the package (and set
back as it was after): the objects of an import live as long as the process, and the
collections that their allocations set off scanned them again and again, 0.03-0.05 s of the
import (``docs/notes/speed-and-memory.md``, "The collector during the import").
"""

import gc

_COLLECTING = gc.isenabled()
gc.disable()

from sswjax._version import __version__  # noqa: E402  (the imports the pause is for)
from sswjax.api.geometry import Calibration, depth_from_disparity, point_cloud
from sswjax.api.match import Matched, match, match_with_confidence
from sswjax.api.warmup import warm_up
from sswjax.config import (DEFAULT_PRESET, PRESETS, ConfigError, Params, check_params,
                           default_params, load_params, preset, save_params)
from sswjax.data.calibration import read_calibration
from sswjax.data.ply import write_ply
from sswjax.graph import aggregated_cost, ssw_disparity, ssw_outputs
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.runtime.memory import MemoryEstimateError
from sswjax.runtime.plan import ExecutionPlan

# Frozen then unfrozen, every object is in the oldest generation, unscanned: the next young
# collection does not scan the whole import at once. Skipped if the importer froze objects
# (``unfreeze`` would thaw them).
if not gc.get_freeze_count():
    gc.freeze()
    gc.unfreeze()
if _COLLECTING:
    gc.enable()
del _COLLECTING

__all__ = [
    "Calibration",
    "__version__",
    "ConfigError",
    "DEFAULT_PRESET",
    "ExecutionPlan",
    "Matched",
    "MemoryEstimateError",
    "PRESETS",
    "Params",
    "ShapeBuckets",
    "aggregated_cost",
    "check_params",
    "default_params",
    "depth_from_disparity",
    "load_params",
    "match",
    "match_with_confidence",
    "point_cloud",
    "preset",
    "read_calibration",
    "save_params",
    "ssw_disparity",
    "ssw_outputs",
    "warm_up",
    "write_ply",
]
