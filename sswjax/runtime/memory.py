"""The memory guard: an estimate of one :func:`sswjax.match` call's peak memory, and what is free.

The estimate is a linear model in a few terms of the shapes the jitted graph allocates,
floored by what compiling the graph takes:
``peak = MARGIN * max(COMPILE_FLOOR, sum(COEFFICIENTS[t] * terms[t])) + SLACK``. The
coefficients were fitted (non-negative least squares of relative errors) to the peak resident
memory (``ru_maxrss``) of fresh processes that read a pair and matched it on the CPU, and the
floor is the peak of a tiny pair: ``python benchmarks/memory.py fit`` measures and fits, and
its table is in ``docs/notes/speed-and-memory.md``. The terms:

``base``
    1: Python, NumPy, JAX and XLA's compiler and runtime.
``image``
    ``H * W * C`` of the whole (bucketed) image: the pair as read, its float32 conversion, the
    device copies and the output map, which tiles do not shrink (a worker that matches one
    tile of a cluster run holds only its window: :func:`worker_peak_bytes`).
``window``
    ``h * w`` of what one call of the graph sees (the window of a tile or strip, its collar
    included, or the whole image): features, census codes, winners, refinement.
``slic``
    ``h * w`` again when SLIC runs (``params.segments`` is set).
``blocks``
    ``h * W * min(K, D)``, ``K = plan.disparity_chunk``: the cost blocks the paper's fold holds.
``volume``
    ``h * W * D`` when a whole volume is aggregated at once (``plan.disparity_chunk = 0``).
``sgm``
    ``h * W * D`` with the semi-global optimiser: the aggregated volume stored in uint8 as it is
    built, its transposed copy and the paths' in-place int16 sum (and that sum transposed).
``sgm_wide``
    ``h * W * D`` more when the volume is stored wider (``optimizer.dtype`` ``"int16"`` or
    ``"float32"``: the float32 volume written whole, then its two int16 copies).
``sgm8``
    ``h * W * D`` more with 8 paths (the diagonal paths' penalties and carries).
``sgm_whole``
    ``h * W * D`` more with the optimiser when the volume is aggregated whole (no blocks).
``band``
    1 with a band: its graph's compilation; its ``h * w * K`` adds to ``volume`` and ``sgm``.

``h x w``, ``K`` and the bucketed shape come from the :class:`~sswjax.runtime.plan.ExecutionPlan`,
the rest from the parameters. The vertical alignment's first pass, a call before the method's,
is estimated like any other call; an aligned call's estimate is the larger of the two.
``MARGIN`` and ``SLACK`` make the model conservative: on every measured size the estimate is
above the measured peak (by at most :data:`STATED_RATIO`). The model describes the CPU backend
and the ``ssw`` aggregator (other aggregators: as ``ssw``).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from sswjax.config import Params, default_params
from sswjax.graph import carries_paths
from sswjax.runtime.buckets import bucket_shape
from sswjax.runtime.plan import ExecutionPlan, plan_tiling, pyramid_align, tiling_words
from sswjax.runtime.refusal import MemoryEstimateError
from sswjax.runtime.tiles import tilings_by_work, window_shape

__all__ = ["STRIP_HEIGHTS", "MemoryEstimateError", "available_bytes", "check_memory",
           "estimate_peak_bytes", "format_gb", "memory_terms", "plan_for_memory",
           "worker_peak_bytes"]

STRIP_HEIGHTS = (512, 384, 256, 192, 128, 96, 64, 48, 32, 16)
"""Strip heights (rows) that :func:`plan_for_memory` tries, besides the square tiles of
:data:`~sswjax.runtime.tiles.TILE_SIZES`."""


COEFFICIENTS: dict[str, float] = {
    "base": 4.619e8,
    "image": 21.54,
    "window": 176.4,
    "slic": 121.0,
    "blocks": 8.623,
    "volume": 21.06,
    "sgm": 5.013,
    "sgm_wide": 2.827,
    "sgm8": 4.444,
    "sgm_whole": 30.08,
    "band": 1.491e8,
}
"""Bytes per unit of each term, fitted by ``benchmarks/memory.py fit`` (2026-12-07, the
presets aligned)."""

COMPILE_FLOOR: dict[str, float] = {"none": 0.447e9, "sgm": 0.569e9}
"""Peak bytes of a tiny pair (96 x 64 x 16): Python, JAX and compiling, without / with SGM."""

MARGIN = 1.18
"""Factor over the fitted model: the measured peaks were 0.84 to 1.18 times the model."""

SLACK = 150_000_000
"""Bytes added after the margin: run-to-run variation, and what the caller holds besides."""

STATED_RATIO = 1.75
"""Estimates are between 1 and this many times the measured peak (1.22 to 1.73 on the fit's
sizes, ``docs/notes/speed-and-memory.md``), more where the compile floor decides (small shapes)."""


def memory_terms(height: int, width: int, ndisp: int, *, params: Params | None = None,
                 plan: ExecutionPlan | None = None, channels: int = 3) -> dict[str, float]:
    """The model's terms for one call of the method (the module's docstring), in elements: a
    dict str -> float, keys those of :data:`COEFFICIENTS`.

    ``height, width, ndisp`` (int): the pair's size and disparity count, as given to
    :func:`sswjax.match`; ``params`` default the ``accurate`` preset; ``plan`` (default
    ``ExecutionPlan()``): tiles or strips, buckets (the terms then use the padded shape) and
    disparity blocks; ``channels``: 1 (gray) or 3 (colour) channels matched.

    Examples
    --------
    >>> memory_terms(100, 200, 16)["blocks"]
    80000.0
    """
    params = default_params() if params is None else params
    plan = ExecutionPlan() if plan is None else plan
    if plan.buckets is not None:
        height, width, ndisp = bucket_shape(height, width, ndisp, plan.buckets)
    rows, cols = window_shape(height, width, plan_tiling(plan, ndisp, align=pyramid_align(params)))
    plane = float(rows * cols)
    levels = 0 if params.coarse is None else params.coarse.levels
    # Coarse-to-fine: the images and one plane at full size, the volumes on the halved pair.
    matched = plane / 4 ** levels
    ndisp = max(1, math.ceil(ndisp / 2 ** levels))
    chunk = plan.disparity_chunk
    whole = chunk == 0 or chunk >= ndisp
    optimizer = params.optimizer
    sgm = optimizer is not None
    band = 0.0 if params.band is None else plane * min(params.band.width, ndisp * 2 ** levels)
    return {
        "base": 1.0,
        "image": float(height * width * channels),
        "window": plane,
        "slic": matched if params.segments is not None else 0.0,
        "blocks": 0.0 if whole else matched * min(chunk, ndisp),
        "volume": (matched * ndisp if whole else 0.0) + band,
        "sgm": matched * ndisp + band if sgm else 0.0,
        "sgm_wide": matched * ndisp if sgm and optimizer.dtype != "uint8" else 0.0,
        "sgm8": matched * ndisp if sgm and optimizer.paths == 8 else 0.0,
        "sgm_whole": matched * ndisp if sgm and whole else 0.0,
        "band": 0.0 if params.band is None else 1.0,
    }


def estimate_peak_bytes(height: int, width: int, ndisp: int, *, params: Params | None = None,
                        plan: ExecutionPlan | None = None, channels: int = 3) -> int:
    """Conservative estimate of the peak memory (bytes) of one :func:`sswjax.match` call.

    Includes the process itself (Python, JAX, the compiler): it is what the process's peak
    resident memory would be if it did nothing else.

    Parameters as :func:`memory_terms`: the optimiser (its paths and storage),
    coarse-to-fine, the superpixels, tiles or strips, buckets and disparity blocks change the
    estimate. Returns int bytes.

    Examples
    --------
    >>> from sswjax.config import preset
    >>> small = estimate_peak_bytes(497, 741, 70, params=preset("accurate"))
    >>> large = estimate_peak_bytes(1988, 2964, 280, params=preset("accurate"))
    >>> large > 8 * small   # the constant term (the process) aside
    True
    """
    for name, value in (("height", height), ("width", width), ("ndisp", ndisp)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    if channels not in (1, 3):
        raise ValueError(f"channels must be 1 or 3, got {channels!r}")
    params = default_params() if params is None else params
    plan = ExecutionPlan() if plan is None else plan
    terms = memory_terms(height, width, ndisp, params=params, plan=plan, channels=channels)
    fitted = sum(COEFFICIENTS[name] * value for name, value in terms.items())
    fitted = max(fitted, COMPILE_FLOOR["none" if params.optimizer is None else "sgm"])
    return max(int(MARGIN * fitted + SLACK),
               _first_pass_bytes(height, width, ndisp, params=params, plan=plan, channels=channels))


def _first_pass_bytes(height, width, ndisp, *, params, plan, channels) -> int:
    """The estimate of the alignment's call (:func:`sswjax.graph.align_right`): its first pass
    on the (bucketed) pair halved ``levels`` times, whole, and the whole pair it holds and
    moves; 0 without it or on a pair too small to be measured (no first pass runs)."""
    alignment = params.alignment
    if alignment is None or not alignment.measurable((height, width)):
        return 0
    if plan.buckets is not None:
        height, width, ndisp = bucket_shape(height, width, ndisp, plan.buckets)
    whole = height * width * channels
    for _ in range(alignment.levels):
        height, width = (height + 1) // 2, (width + 1) // 2
        ndisp = min(ndisp // 2 + 1, width - 1)
    held = int(MARGIN * COEFFICIENTS["image"] * (whole - height * width * channels))
    whole_plan = plan._replace(strip_rows=0, tile=0, buckets=None)
    return held + estimate_peak_bytes(height, width, ndisp, params=alignment.first_pass(params),
                                      plan=whole_plan, channels=channels)


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
    """Memory a new allocation can get: ``MemAvailable`` and, if lower, the cgroup's free room
    (``meminfo`` and ``cgroup``: where to read them, for tests); int bytes, or None when
    neither can be read (not Linux).

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


def worker_peak_bytes(height: int, width: int, ndisp: int, *, params: Params | None = None,
                      plan: ExecutionPlan | None = None, channels: int = 3) -> int:
    """The estimate of a process that matches one tile of ``plan`` holding only its window
    (a worker of :func:`sswjax.cluster.match_tiles`): the window matched as a whole pair, by
    the method (the alignment runs before, in the caller's process).

    Parameters and returns as :func:`estimate_peak_bytes`; without tiles, the whole pair's.

    Examples
    --------
    >>> whole = estimate_peak_bytes(4000, 6000, 256, plan=ExecutionPlan(tile=512))
    >>> worker_peak_bytes(4000, 6000, 256, plan=ExecutionPlan(tile=512)) < whole
    True
    """
    plan = ExecutionPlan() if plan is None else plan
    if plan.buckets is not None:
        height, width, ndisp = bucket_shape(height, width, ndisp, plan.buckets)
    params = (default_params() if params is None else params).replace(alignment=None)
    rows, cols = window_shape(height, width, plan_tiling(plan, ndisp, align=pyramid_align(params)))
    return estimate_peak_bytes(rows, cols, ndisp, params=params, channels=channels,
                               plan=plan._replace(strip_rows=0, tile=0, buckets=None))


def check_memory(height: int, width: int, ndisp: int, *, params: Params | None = None,
                 plan: ExecutionPlan | None = None, channels: int = 3,
                 limit: float | None = None) -> int:
    """Raise :class:`MemoryEstimateError` if one call would not fit; return the estimate.

    ``height, width, ndisp, params, plan, channels`` as :func:`estimate_peak_bytes`; ``limit``
    (float, optional): bytes allowed; the available memory (:func:`available_bytes`) applies
    as well. Without either (not Linux, no limit) nothing is checked.

    Examples
    --------
    >>> check_memory(100, 200, 16, limit=1e6)
    Traceback (most recent call last):
    ...
    sswjax.runtime.refusal.MemoryEstimateError: ...
    """
    return _assess((height, width, ndisp), params, plan, channels, _bound(limit), choose=False)[0]


def plan_for_memory(height: int, width: int, ndisp: int, *, params: Params | None = None,
                    plan: ExecutionPlan | None = None, channels: int = 3,
                    limit: float | None = None, share: int = 1, local: bool = True,
                    worker_tiles: bool = False) -> ExecutionPlan:
    """The plan with which one call fits in memory: strips or tiles chosen when they must be.

    With a plan of neither (the whole image) and an estimate above the bound, the pair is cut
    in the strips of :data:`STRIP_HEIGHTS` or the square tiles of
    :data:`~sswjax.runtime.tiles.TILE_SIZES` that fit, in the order of
    :func:`~sswjax.runtime.tiles.tilings_by_work` (strips first when the paths are carried; the
    whole collar; cores of 256 rows; the fewest pixels); with explicit strips or tiles, or when
    the whole image fits, the plan as it is. Nothing fits: :class:`MemoryEstimateError`.

    Parameters
    ----------
    height, width, ndisp, params, plan, channels, limit
        As :func:`check_memory`.
    share : int >= 1
        Processes that match at the same time within the bound (the workers of a cluster
        on this machine): each gets ``1 / share`` of it.
    local : bool
        False: the processes run on other machines, the memory available here is no bound
        (only ``limit``, per process).
    worker_tiles : bool
        Each tile is matched by a process that holds only its window
        (:func:`worker_peak_bytes`), instead of one process holding the pair.

    Returns
    -------
    ExecutionPlan

    Examples
    --------
    >>> from sswjax.config import preset
    >>> fitted = plan_for_memory(1988, 2964, 280, params=preset("accurate"), limit=6e9)
    >>> 0 < fitted.strip_rows < 1988
    True
    """
    if isinstance(share, bool) or not isinstance(share, int) or share < 1:
        raise ValueError(f"share must be an integer >= 1, got {share!r}")
    bound = _bound(limit, share=share, local=local)
    return _assess((height, width, ndisp), params, plan, channels, bound, choose=True,
                   worker_tiles=worker_tiles)[1]


def _assess(shape, params, plan, channels, bound, *, choose: bool,
            worker_tiles: bool = False) -> tuple[int, ExecutionPlan]:
    """The estimate of a call and the plan it runs with: ``plan`` when it fits, the tiling
    that does when ``choose`` and the plan has none, else the refusal."""
    params = default_params() if params is None else params
    plan = ExecutionPlan() if plan is None else plan
    estimator = worker_peak_bytes if worker_tiles else estimate_peak_bytes

    def estimate(trial):
        return estimator(*shape, params=params, plan=trial, channels=channels)

    estimated = estimate(plan)
    limit, what = bound
    if limit is None or estimated <= limit:
        return estimated, plan
    fitting = _cheapest_tiling(shape, plan, params, limit, estimate)
    if choose and fitting is not None and not plan.strip_rows and not plan.tile:
        return estimated, fitting
    first = _first_pass_bytes(*shape, params=params, plan=plan, channels=channels)
    raise _refusal(shape, estimated, limit, what, fitting,
                   None if fitting is None else estimate(fitting), first if first > limit else 0)


def _bound(limit, *, share: int = 1, local: bool = True):
    """The tighter of ``limit`` and the available memory (when ``local``), divided among
    ``share`` processes, and its words (``(None, None)`` if there is neither)."""
    free = available_bytes() if local else None
    bounds = [(b, what) for b, what in ((limit, "the limit"), (free, "the available memory"))
              if b is not None]
    if not bounds:
        return None, None
    bound, what = min(bounds)
    return bound / share, what if share == 1 else f"{what} shared by {share} workers"


def _cheapest_tiling(shape, plan, params, bound, estimate):
    """The first strips or tiles of :func:`~sswjax.runtime.tiles.tilings_by_work` under ``bound``
    (bucketed; paths carried as plan and method allow); None: none fits."""
    height, width, ndisp = shape
    carried = plan.carry_paths and carries_paths(params)
    if plan.buckets is not None:
        height, width, ndisp = bucket_shape(height, width, ndisp, plan.buckets)
    for tiling in tilings_by_work(height, width, lead=ndisp, overlap=plan.strip_overlap,
                                  strip_heights=STRIP_HEIGHTS, carried=carried):
        trial = plan._replace(strip_rows=0 if tiling.cols else tiling.rows,
                              tile=tiling.rows if tiling.cols else 0, strip_overlap=tiling.overlap)
        if estimate(trial) <= bound:
            return trial
    return None


def _refusal(shape, estimate, bound, what, fitting, fitted, first=0) -> MemoryEstimateError:
    """The one-line refusal, with what to change in the API's terms: ``first`` (the estimate of
    the alignment's first pass, when it alone does not fit), ``fitting`` (the strips or tiles
    that fit, estimated at ``fitted``), else a smaller ndisp or image."""
    height, width, ndisp = shape
    if fitting is None:
        advice = "a smaller ndisp or image (even strips of 16 rows do not fit), or a larger limit"
    else:
        field = f"tile={fitting.tile}" if fitting.tile else f"strip_rows={fitting.strip_rows}"
        advice = (f"match in {tiling_words(fitting).split(' of ')[0]} with "
                  f"plan=sswjax.ExecutionPlan({field}) (about {format_gb(fitted)}), or a "
                  "smaller ndisp or image")
    if first:
        advice += (f"; the vertical alignment's first pass (the pair halved) needs "
                   f"{format_gb(first)} alone, params.replace(alignment=None) leaves it out")
    return MemoryEstimateError(
        f"a {width}x{height} pair with ndisp {ndisp} needs about {format_gb(estimate)}, more than "
        f"{what} ({format_gb(bound)}): {advice}", estimate=estimate, limit=int(bound),
        bound=what, shape=(width, height, ndisp), strips=fitting, strips_estimate=fitted)
