"""The memory guard: an estimate of one :func:`sswjax.match` call's peak memory, and what is free.

The estimate is a linear model in a few terms of the shapes the jitted graph allocates,
floored by what compiling the graph takes:
``peak = MARGIN * max(COMPILE_FLOOR, sum(COEFFICIENTS[t] * terms[t])) + SLACK``. The
coefficients were fitted (non-negative least squares of relative errors) to the peak resident
memory (``ru_maxrss``) of fresh processes that read a pair and matched it on the CPU, and the
floor is the peak of a tiny pair: ``python benchmarks/memory_model.py`` measures and fits, and
its table is in the README ("Memory guard"). The terms:

``base``
    1: Python, NumPy, JAX and XLA's compiler and runtime.
``image``
    ``H * W * C`` of the whole (bucketed) image: the pair as read, its float32 conversion, the
    device copies and the output map, which strips do not shrink.
``window``
    ``h * W`` of what one call of the graph sees (``h`` = the strip's rows plus its overlap, or
    ``H``): features, census codes, winners, refinement.
``slic``
    ``h * W`` again when SLIC runs (``n_segments > 0`` and a stage uses the superpixels).
``blocks``
    ``h * W * min(K, D)`` with ``K = disparity_chunk``: the blocks of cost slices in flight when
    the paper's selection folds them as they come.
``volume``
    ``h * W * D`` when a whole volume is aggregated at once (``disparity_chunk = 0``).
``sgm``
    ``h * W * D`` with the semi-global optimiser: the aggregated volume stored in uint8 as it is
    built, its transposed copy and the paths' in-place int16 sum (and that sum transposed).
``sgm_wide``
    ``h * W * D`` more when the volume is stored wider (``sgm_dtype`` ``"int16"`` or
    ``"float32"``: the float32 volume written whole, then its two int16 copies).
``sgm8``
    ``h * W * D`` more with 8 paths (the diagonal paths' penalties and carries).

``MARGIN`` and ``SLACK`` make the model conservative: on every measured size the estimate is
above the measured peak (by at most the factor stated in the README). The model describes the
CPU backend with the ``ssw`` aggregator; other aggregators are estimated as ``ssw``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

__all__ = ["MemoryEstimateError", "STRIP_HEIGHTS", "available_bytes", "check_memory",
           "estimate_peak_bytes", "fit_in_memory", "format_gb", "memory_terms"]

STRIP_HEIGHTS = (512, 384, 256, 192, 128, 96, 64, 48, 32, 16)
"""Strip heights (rows) that :func:`fit_in_memory` tries, tallest first."""


class MemoryEstimateError(MemoryError):
    """The estimated peak memory of a call exceeds what is available (or the caller's limit).

    Raised before any work; ``estimate`` and ``limit`` are in bytes, the message (one line)
    says what to change.
    """

    def __init__(self, message: str, *, estimate: int, limit: int):
        super().__init__(message)
        self.estimate = estimate
        self.limit = limit


COEFFICIENTS: dict[str, float] = {
    "base": 4.603e8,
    "image": 13.7,
    "window": 0.0,
    "slic": 231.5,
    "blocks": 30.35,
    "volume": 30.89,
    "sgm": 4.749,
    "sgm_wide": 2.625,
    "sgm8": 0.4593,
}
"""Bytes per unit of each term, fitted by ``benchmarks/memory_model.py``."""

COMPILE_FLOOR: dict[str, float] = {"none": 0.496e9, "sgm": 0.453e9}
"""Peak bytes of a tiny pair (96 x 64 x 16): Python, JAX and compiling the graph, without and
with the semi-global optimiser."""

MARGIN = 1.15
"""Factor over the fitted model: the measured peaks were 0.91 to 1.14 times the model."""

SLACK = 150_000_000
"""Bytes added after the margin: room for run-to-run variation (the same run peaked at 0.45
to 0.48 GB) and for what the calling process holds besides."""

STATED_RATIO = 1.6
"""Estimates are between 1 and this many times the measured peak (README, tests), except
where the compile floor decides: compiling may take less memory for some small shapes than
for the tiny one measured, and the estimate is then a larger multiple of the peak."""


def memory_terms(height: int, width: int, ndisp: int, *, params=None, channels: int = 3,
                 buckets=None) -> dict[str, float]:
    """The model's terms for one call (see the module's docstring), in elements.

    Parameters
    ----------
    height, width, ndisp : int
        The pair's size and disparity count, as given to :func:`sswjax.match`.
    params : Params, optional
        Default: the ``accurate`` preset (:func:`sswjax.params.default_params`).
    channels : int
        1 (gray) or 3 (colour) channels matched.
    buckets : ShapeBuckets, optional
        The terms then use the padded shape.

    Returns
    -------
    dict str -> float, keys those of :data:`COEFFICIENTS`.

    Examples
    --------
    >>> memory_terms(100, 200, 16)["blocks"]
    80000.0
    """
    from sswjax.api import bucket_shape
    from sswjax.params import default_params
    from sswjax.registry import AGGREGATORS, FILLS, OPTIMIZERS

    params = default_params() if params is None else params
    static = params.static
    if buckets is not None:
        height, width, ndisp = bucket_shape(height, width, ndisp, buckets)
    rows = height
    window = static.strip_rows + 2 * static.strip_overlap
    if static.strip_rows > 0 and window < height:
        rows = window
    plane = float(rows * width)
    uses_segments = (AGGREGATORS[static.aggregation].uses_segments
                     or OPTIMIZERS[static.optimizer].uses_segments
                     or (static.lr_check and FILLS[static.fill].uses_segments))
    # Coarse-to-fine: the images and one plane at full size, the volumes on the halved pair.
    matched = plane / 4 ** static.coarse_levels
    ndisp = max(1, math.ceil(ndisp / 2 ** static.coarse_levels))
    whole = static.disparity_chunk == 0 or static.disparity_chunk >= ndisp
    sgm = OPTIMIZERS[static.optimizer].fn is not None
    return {
        "base": 1.0,
        "image": float(height * width * channels),
        "window": plane,
        "slic": matched if static.n_segments > 0 and uses_segments else 0.0,
        "blocks": 0.0 if whole else matched * min(static.disparity_chunk, ndisp),
        "volume": matched * ndisp if whole else 0.0,
        "sgm": matched * ndisp if sgm else 0.0,
        "sgm_wide": matched * ndisp if sgm and static.sgm_dtype != "uint8" else 0.0,
        "sgm8": matched * ndisp if sgm and static.sgm_paths == 8 else 0.0,
    }


def estimate_peak_bytes(height: int, width: int, ndisp: int, *, params=None, channels: int = 3,
                        buckets=None) -> int:
    """Conservative estimate of the peak memory (bytes) of one :func:`sswjax.match` call.

    Includes the process itself (Python, JAX, the compiler): it is what the process's peak
    resident memory would be if it did nothing else.

    Parameters
    ----------
    height, width, ndisp : int
        Image size and disparity count.
    params : Params, optional
        Default: the ``accurate`` preset; ``disparity_chunk``, ``optimizer``, ``sgm_paths``,
        ``strip_rows``/``strip_overlap`` and ``n_segments`` change the estimate.
    channels : int
        Channels matched: 1 (gray) or 3 (colour).
    buckets : ShapeBuckets, optional
        Estimate the padded shape.

    Returns
    -------
    int, bytes

    Examples
    --------
    >>> import sswjax
    >>> small = estimate_peak_bytes(497, 741, 70, params=sswjax.preset("accurate"))
    >>> large = estimate_peak_bytes(1988, 2964, 280, params=sswjax.preset("accurate"))
    >>> large > 10 * small
    True
    """
    for name, value in (("height", height), ("width", width), ("ndisp", ndisp)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    if channels not in (1, 3):
        raise ValueError(f"channels must be 1 or 3, got {channels!r}")
    terms = memory_terms(height, width, ndisp, params=params, channels=channels, buckets=buckets)
    fitted = sum(COEFFICIENTS[name] * value for name, value in terms.items())
    sgm = (params or _default_params()).static.optimizer != "none"
    fitted = max(fitted, COMPILE_FLOOR["sgm" if sgm else "none"])
    return int(MARGIN * fitted + SLACK)


def _default_params():
    from sswjax.params import default_params

    return default_params()


def _cgroup_free(root: Path) -> int | None:
    """Bytes left under this process's cgroup (v2 ``memory.max``, v1 ``limit_in_bytes``)."""
    for limit_file, usage_file in (("memory.max", "memory.current"),
                                   ("memory/memory.limit_in_bytes", "memory/memory.usage_in_bytes")):
        try:
            limit = (root / limit_file).read_text().strip()
            usage = int((root / usage_file).read_text().strip())
        except (OSError, ValueError):
            continue
        if limit.isdigit() and int(limit) < 1 << 60:
            return max(int(limit) - usage, 0)
    return None


def available_bytes(*, meminfo: str | os.PathLike = "/proc/meminfo",
                    cgroup: str | os.PathLike = "/sys/fs/cgroup") -> int | None:
    """Memory a new allocation can get: ``MemAvailable`` and, if lower, the cgroup's free room.

    Parameters
    ----------
    meminfo, cgroup : path
        Where to read them (for tests).

    Returns
    -------
    int bytes, or None when neither can be read (not Linux).

    Examples
    --------
    >>> available_bytes() > 0                       # doctest: +SKIP
    True
    """
    free = None
    try:
        for line in Path(meminfo).read_text().splitlines():
            if line.startswith("MemAvailable:"):
                free = int(line.split()[1]) * 1024
                break
    except (OSError, ValueError, IndexError):
        pass
    limited = _cgroup_free(Path(cgroup))
    if limited is not None:
        free = limited if free is None else min(free, limited)
    return free


def format_gb(value: float) -> str:
    """Bytes as GB with two decimals.

    >>> format_gb(1.5e9)
    '1.50 GB'
    """
    return f"{value / 1e9:.2f} GB"


def check_memory(height: int, width: int, ndisp: int, *, params=None, channels: int = 3,
                 buckets=None, limit: float | None = None) -> int:
    """Raise :class:`MemoryEstimateError` if one call would not fit; return the estimate.

    Parameters
    ----------
    height, width, ndisp, params, channels, buckets
        As :func:`estimate_peak_bytes`.
    limit : float, optional
        Bytes allowed (``--max-memory``); the available memory (:func:`available_bytes`)
        applies as well. Without either (not Linux, no limit) nothing is checked.

    Returns
    -------
    int, the estimate in bytes.

    Examples
    --------
    >>> check_memory(100, 200, 16, limit=1e6)
    Traceback (most recent call last):
    ...
    sswjax.memory.MemoryEstimateError: ...
    """
    from sswjax.params import default_params

    params = default_params() if params is None else params
    estimate = estimate_peak_bytes(height, width, ndisp, params=params, channels=channels,
                                   buckets=buckets)
    bound, what = _bound(limit)
    if bound is None or estimate <= bound:
        return estimate
    raise _refusal(height, width, ndisp, estimate, bound, what,
                   _tallest_strips(height, width, ndisp, params, channels, buckets, bound),
                   channels=channels, buckets=buckets)


def fit_in_memory(height: int, width: int, ndisp: int, *, params=None, channels: int = 3,
                  buckets=None, limit: float | None = None):
    """The parameters with which one call fits in memory: strips chosen when they must be.

    With ``params.static.strip_rows == 0`` (the whole image) and an estimate above the bound,
    the pair is matched in the tallest strips of :data:`STRIP_HEIGHTS` that fit (the overlap
    capped at the strip's height); with explicit strips, or when the whole image fits, the
    parameters come back unchanged. Nothing fits: :class:`MemoryEstimateError`, as
    :func:`check_memory` raises it.

    Parameters
    ----------
    height, width, ndisp, params, channels, buckets, limit
        As :func:`check_memory`.

    Returns
    -------
    Params

    Examples
    --------
    >>> import sswjax
    >>> fitted = fit_in_memory(1988, 2964, 280, params=sswjax.preset("accurate"), limit=6e9)
    >>> 0 < fitted.static.strip_rows < 1988
    True
    """
    from sswjax.params import default_params

    params = default_params() if params is None else params
    estimate = estimate_peak_bytes(height, width, ndisp, params=params, channels=channels,
                                   buckets=buckets)
    bound, what = _bound(limit)
    if bound is None or estimate <= bound:
        return params
    strips = _tallest_strips(height, width, ndisp, params, channels, buckets, bound)
    if strips is not None and not params.static.strip_rows:
        return strips
    raise _refusal(height, width, ndisp, estimate, bound, what, strips, channels=channels,
                   buckets=buckets)


def _bound(limit):
    """The tighter of ``limit`` and the available memory, and which it is (None if neither)."""
    free = available_bytes()
    bounds = [(b, what) for b, what in ((limit, "the limit"), (free, "the available memory"))
              if b is not None]
    return min(bounds) if bounds else (None, None)


def _tallest_strips(height, width, ndisp, params, channels, buckets, bound):
    """``params`` with the tallest strips of :data:`STRIP_HEIGHTS` (lower than the current
    ones, if any, and than the image) whose estimate fits under ``bound``; None if none."""
    static = params.static
    for rows in STRIP_HEIGHTS:
        if rows >= height or (static.strip_rows and rows >= static.strip_rows):
            continue
        trial = params.replace(strip_rows=rows, strip_overlap=min(static.strip_overlap, rows))
        if estimate_peak_bytes(height, width, ndisp, params=trial, channels=channels,
                               buckets=buckets) <= bound:
            return trial
    return None


def _refusal(height, width, ndisp, estimate, bound, what, strips, *, channels, buckets
             ) -> MemoryEstimateError:
    """The one-line refusal, with what to change: ``strips`` (the tallest that fit, from
    :func:`_tallest_strips`), else a smaller ndisp or image."""
    if strips is None:
        advice = ("a smaller ndisp or image (even strips of 16 rows do not fit), or a larger "
                  "--max-memory")
    else:
        rows = strips.static.strip_rows
        fitted = estimate_peak_bytes(height, width, ndisp, params=strips, channels=channels,
                                     buckets=buckets)
        advice = (f"match in strips with --params holding \"strip_rows\": {rows} "
                  f"(Params.strip_rows={rows}, about {format_gb(fitted)}), or a smaller ndisp or "
                  "image")
    return MemoryEstimateError(
        f"a {width}x{height} pair with ndisp {ndisp} needs about {format_gb(estimate)}, more than "
        f"{what} ({format_gb(bound)}): {advice}", estimate=estimate, limit=int(bound))
