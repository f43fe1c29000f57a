"""Choosing the disparity range: from the depths the user cares about, or from the pair itself.

- :func:`range_for_depths`: depths ``Z_min .. Z_max`` of a rig are the disparities ``d = f B /
  Z - doffs`` (:mod:`sswjax.api.geometry`'s convention ``Z = f B / (d + doffs)``), widened by a
  margin and rounded to a count of disparities that is a multiple of 8.
- :func:`estimate_range`: without a range, a cheap coarse pass over a wide one: the pair
  averaged down by 2 (4 from 1000 columns), matched by :data:`COARSE` (the ``fast`` preset, on
  its halved pair: a quarter or an eighth of the resolution in all) over disparities up to
  half the coarse width (or ``max_ndisp``), and the confident disparities of that map (every
  validity bit clear, confidence at least :data:`CONFIDENT`) give the range: their
  :data:`QUANTILES`, a margin of :data:`MARGIN_PIXELS` coarse pixels plus :data:`MARGIN_FRACTION`
  of the upper end, times the factor, the count rounded up to a multiple of 8. The range starts
  at 0 unless its lower end is at least :data:`RAISE_FROM` of its upper one: a higher start that
  cuts no true disparity still moves single scenes by up to 1.6 points of bad 2.0 (measured by
  ``benchmarks/auto_range.py``), so it is taken only where it at least halves the search.
  :func:`coarse_disparities` and :func:`range_from_coarse` are its two steps.

Both return a :class:`DisparityRange` ``(min_disp, ndisp)``: search ``min_disp .. min_disp +
ndisp - 1`` (the ``min_disp`` and ``ndisp`` of :func:`sswjax.match`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sswjax.api.geometry import Calibration, check_calibration
from sswjax.api.images import checked_images, checked_pair
from sswjax.config import preset
from sswjax.graph import ssw_outputs
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.runtime.executables import bounded
from sswjax.runtime.execute import execute
from sswjax.runtime.memory import plan_for_memory
from sswjax.runtime.plan import ExecutionPlan
from sswjax.stages.confidence import DEFAULT_THRESHOLD, validity_mask

__all__ = [
    "COARSE",
    "CONFIDENT",
    "CoarseDisparities",
    "MARGIN_FRACTION",
    "MARGIN_PIXELS",
    "QUANTILES",
    "RAISE_FROM",
    "DisparityRange",
    "coarse_disparities",
    "estimate_range",
    "range_for_depths",
    "range_from_coarse",
]

STEP = 8
"""Counts of disparities are rounded up to a multiple of this."""
COARSE = "fast"
"""The preset of the coarse pass."""
CONFIDENT = 0.3
"""Confidence from which a coarse disparity counts (besides every validity bit clear)."""
QUANTILES = (0.001, 0.999)
"""Quantiles of the confident coarse disparities taken as the range's ends."""
MARGIN_PIXELS = 3.0
"""Margin on each side in coarse pixels (the coarse map's error and the near surfaces it left
unconfident): 3 cuts true disparities in 2 of the 49 shared scenes where 1.5 cut 5, for
searches 11 % (KITTI) to 33 % (Middlebury 2001) wider (``benchmarks/auto_range.py``,
``docs/camera.md``)."""
MARGIN_FRACTION = 0.05
"""And on the upper end, this fraction of it (for the nearest surfaces it may have missed)."""
RAISE_FROM = 0.5
"""``min_disp`` leaves 0 only when the lower end is at least this fraction of the upper one."""
_BUCKETS = ShapeBuckets(size_step=64, ndisp_step=32)
_OUTPUTS = bounded(ssw_outputs, static_argnames=("ndisp", "chunk", "measure"))
"""The coarse pass's graph (its own executables: :mod:`sswjax.api.match` is not imported, so
that it may call :func:`estimate_range`)."""


class DisparityRange(NamedTuple):
    """A search range: ``min_disp .. min_disp + ndisp - 1``."""

    min_disp: int
    ndisp: int


def _rounded(low: float, high: float, width: int) -> DisparityRange:
    """The range of integers covering ``low .. high`` in an image ``width`` wide, the count a
    multiple of :data:`STEP` (at most ``width - 1``)."""
    first = math.floor(low)
    count = -(-(math.ceil(high) - first + 1) // STEP) * STEP
    return DisparityRange(first, max(1, min(count, width - 1)))


def range_for_depths(calib: Calibration, depth_min: float, depth_max: float, *, width: int,
                     margin: float = 2.0) -> DisparityRange:
    """The disparities of the depths ``depth_min .. depth_max`` of a rectified rig.

    Parameters
    ----------
    calib : Calibration
        Focal length, baseline (the depths' unit) and ``doffs``.
    depth_min, depth_max : float
        ``0 < depth_min < depth_max``; ``depth_max`` may be ``inf`` (disparity ``-doffs``).
    width : int
        The rectified images' width: the count stays below it.
    margin : float
        Pixels added on each side (calibration and sub-pixel errors), default 2; the lower
        end is not taken below ``-doffs`` (points behind infinity) when the margin would.

    Returns
    -------
    DisparityRange
        ``ndisp`` a multiple of 8 (or ``width - 1``).

    Raises
    ------
    ValueError
        On depths that are not ``0 < min < max`` or a range no pixel of ``width`` can match.

    Examples
    --------
    >>> range_for_depths(Calibration(focal=700, baseline=0.12), 2.0, 10.0, width=640)
    DisparityRange(min_disp=6, ndisp=40)
    """
    calib = check_calibration(calib)
    for name, value in (("depth_min", depth_min), ("depth_max", depth_max)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or \
                math.isnan(value):
            raise ValueError(f"{name} must be a number, got {value!r}")
    if not 0 < depth_min < depth_max:
        raise ValueError(f"the depth range must be 0 < ZMIN < ZMAX, got {depth_min:g} .. "
                         f"{depth_max:g}")
    if not math.isfinite(depth_min):
        raise ValueError("ZMIN must be finite")
    scale = calib.focal * calib.baseline
    high = scale / depth_min - calib.doffs + margin
    low = max(scale / depth_max - calib.doffs - margin, min(-calib.doffs, high - margin))
    found = _rounded(low, high, width)
    if found.min_disp > width - 1:
        raise ValueError(f"depths from {depth_min:g} are disparities from {low:.0f} px: beyond an "
                         f"image {width} pixels wide")
    return found


def _downscale(image: np.ndarray, factor: int) -> np.ndarray:
    """Block means of ``factor x factor`` pixels: float32 ``(H // f, W // f, C)``."""
    if factor == 1:
        return image
    height, width = (image.shape[0] // factor) * factor, (image.shape[1] // factor) * factor
    blocks = image[:height, :width].reshape(height // factor, factor, width // factor, factor, -1)
    return blocks.mean(axis=(1, 3), dtype=np.float32)


def coarse_factor(width: int) -> int:
    """How much :func:`estimate_range` shrinks a pair ``width`` wide: 4 from 1000 columns, 2
    from 160, else 1."""
    return 4 if width >= 1000 else 2 if width >= 160 else 1


class CoarseDisparities(NamedTuple):
    """What :func:`coarse_disparities` found: the confident disparities of the coarse map.

    Attributes
    ----------
    values : numpy.ndarray float32 (N,)
        The confident coarse disparities, in coarse pixels.
    factor : int
        The coarse map's scale: a coarse pixel is ``factor`` pixels of the pair.
    limit : int
        The largest disparity looked for, in pixels of the pair.
    width : int
        The pair's width.
    """

    values: np.ndarray
    factor: int
    limit: int
    width: int


def coarse_disparities(left, right, *, max_ndisp: int | None = None) -> CoarseDisparities:
    """The coarse pass of :func:`estimate_range` (module docstring) and its confident disparities.

    Parameters and errors as :func:`estimate_range`.
    """
    left, right = checked_images(left, right, preset(COARSE))  # too small: said as such
    width = left.shape[1]
    limit = width // 2 if max_ndisp is None else int(max_ndisp)
    if not 1 <= limit < width:
        raise ValueError(f"max_ndisp must be in [1, {width - 1}] for this width, got {max_ndisp}")
    factor = coarse_factor(width)
    small = [_downscale(image, factor) for image in (left, right)]
    coarse_ndisp = max(2, min(-(-limit // factor) + 1, small[0].shape[1] - 1))
    params = preset(COARSE)
    small = checked_pair(*small, coarse_ndisp, params)
    height, coarse_width, channels = small[0].shape
    plan = plan_for_memory(height, coarse_width, coarse_ndisp, params=params,
                           plan=ExecutionPlan(buckets=_BUCKETS), channels=channels)
    maps = execute(_OUTPUTS, *small, params=params, ndisp=coarse_ndisp, plan=plan)
    validity = np.asarray(validity_mask(maps.disparity, maps.confidence, maps.lr_failed,
                                        threshold=DEFAULT_THRESHOLD))
    confident = (validity == 0) & (np.asarray(maps.confidence) >= CONFIDENT)
    values = np.asarray(maps.disparity, dtype=np.float32)[confident]
    return CoarseDisparities(values, factor, limit, width)


def range_from_coarse(coarse: CoarseDisparities, *, margin_pixels: float = MARGIN_PIXELS,
                      margin_fraction: float = MARGIN_FRACTION,
                      raise_from: float = RAISE_FROM) -> DisparityRange:
    """The range the confident coarse disparities give (module docstring).

    Parameters
    ----------
    coarse : CoarseDisparities
    margin_pixels, margin_fraction : float
        The margins, default :data:`MARGIN_PIXELS` and :data:`MARGIN_FRACTION`.
    raise_from : float
        ``min_disp`` leaves 0 only when the lower end is at least this fraction of the upper
        one (default :data:`RAISE_FROM`; 0: always, ``inf``: never).

    Returns
    -------
    DisparityRange
        As :func:`estimate_range`.
    """
    if coarse.values.size < 16:
        return _rounded(0, coarse.limit, coarse.width)
    low, high = np.quantile(coarse.values, QUANTILES)
    high = min((high + margin_pixels) * (1 + margin_fraction) * coarse.factor, coarse.limit)
    low = max(0.0, low - margin_pixels) * coarse.factor
    if low < raise_from * high:
        low = 0.0
    return _rounded(low, high, coarse.width)


def estimate_range(left, right, *, max_ndisp: int | None = None) -> DisparityRange:
    """Estimate the disparity range of a rectified pair from a coarse pass (module docstring).

    Parameters
    ----------
    left, right : array_like (H, W) or (H, W, 1|3|4), uint8, uint16 or float in [0, 1]
        The rectified pair, as for :func:`sswjax.match`.
    max_ndisp : int, optional
        The largest disparity looked for (default: half the width).

    Returns
    -------
    DisparityRange
        ``min_disp >= 0`` (0 unless that at least halves the search) and ``ndisp`` a multiple
        of 8, at most ``max_ndisp`` (rounded) and below the width. Without confident coarse
        disparities: ``0`` and the whole range looked at.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> right = rng.random((96, 192, 3), dtype=np.float32)
    >>> estimate_range(np.roll(right, 20, axis=1), right)    # doctest: +SKIP
    DisparityRange(min_disp=16, ndisp=8)
    """
    return range_from_coarse(coarse_disparities(left, right, max_ndisp=max_ndisp))
