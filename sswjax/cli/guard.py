"""The memory guard of ``sswjax match``, in the command line's terms.

Before any image is read, the largest pair's peak memory is estimated from the image headers
(:mod:`sswjax.runtime.memory`) against ``--max-memory`` and the memory available: a pair
that does not fit whole is matched in strips or tiles (a note on stderr says so), and one that
does not fit at all is refused with the options that would make it fit (``--strip-rows``,
``--tile``). With ``--workers N`` the bound is shared by the N workers of this machine; with
``--scheduler`` it is each worker's (``--max-memory``, else the workers' own memory limit).
"""

from __future__ import annotations

import sys
from collections.abc import Iterable

from sswjax.config import Params
from sswjax.runtime.memory import (
    MemoryEstimateError,
    estimate_peak_bytes,
    format_gb,
    plan_for_memory,
    worker_peak_bytes,
)
from sswjax.runtime.plan import ExecutionPlan, tiling_words

__all__ = ["guard_memory", "refusal"]


def refusal(error: MemoryEstimateError, plan: ExecutionPlan) -> MemoryEstimateError:
    """``error`` (raised by :func:`~sswjax.runtime.memory.plan_for_memory` for ``plan``) said
    with the command line's options instead of the API's.

    Examples
    --------
    >>> error = MemoryEstimateError("...", estimate=9_100_000_000, limit=2_000_000_000,
    ...                             shape=(2964, 1988, 280), strips=ExecutionPlan(strip_rows=64),
    ...                             strips_estimate=1_240_000_000)
    >>> print(refusal(error, ExecutionPlan()))
    a 2964x1988 pair with ndisp 280 needs about 9.10 GB, more than the limit (2.00 GB): match in strips with --strip-rows 64 (about 1.24 GB), or a smaller ndisp or image
    """
    width, height, ndisp = error.shape
    strips = error.strips
    if strips is None:
        advice = "a smaller ndisp or image (even strips of 16 rows do not fit)"
        if error.bound.startswith("the limit"):
            advice += ", or a larger --max-memory"
    else:
        options = f"--tile {strips.tile}" if strips.tile else f"--strip-rows {strips.strip_rows}"
        if strips.strip_overlap != plan.strip_overlap:
            options += f" --strip-overlap {strips.strip_overlap}"
        advice = (f"match in {'tiles' if strips.tile else 'strips'} with {options} (about "
                  f"{format_gb(error.strips_estimate)}), or a smaller ndisp or image")
    message = (f"a {width}x{height} pair with ndisp {ndisp} needs about "
               f"{format_gb(error.estimate)}, more than {error.bound} ({format_gb(error.limit)}): "
               f"{advice}")
    return MemoryEstimateError(message, estimate=error.estimate, limit=error.limit,
                               bound=error.bound, shape=error.shape, strips=strips,
                               strips_estimate=error.strips_estimate)


def guard_memory(sizes: Iterable[tuple[int, int, int]], ndisp: int, *, params: Params,
                 plan: ExecutionPlan, limit_gb: float | None = None, min_disp: int = 0,
                 share: int = 1, local: bool = True,
                 worker_tiles: bool = False) -> ExecutionPlan:
    """The plan with which the largest of ``sizes`` fits: ``plan`` itself, or strips or tiles
    chosen when the whole pair does not fit (a note on stderr says so).

    Parameters
    ----------
    sizes : iterable of (height, width, channels)
    ndisp, min_disp : int
        The search range (a negative ``min_disp`` widens the matched frame by ``-min_disp``).
    params : Params
    plan : ExecutionPlan
        The plan asked for (strips, buckets, disparity blocks).
    limit_gb : float, optional
        ``--max-memory`` in GB (1e9 bytes); the available memory applies as well.
    share, local, worker_tiles
        As :func:`sswjax.runtime.memory.plan_for_memory`: the workers sharing this machine's
        bound, workers elsewhere (``local=False``: ``limit_gb`` is each one's), workers that
        hold one tile's window each.

    Returns
    -------
    ExecutionPlan

    Raises
    ------
    MemoryEstimateError
        When nothing fits, with a one-line message naming the options to change.
    """
    pad = max(-int(min_disp), 0)
    shapes = sorted({(h, w + pad, c) for h, w, c in sizes})
    estimate = worker_peak_bytes if worker_tiles else estimate_peak_bytes
    largest = max(shapes, key=lambda s: estimate(s[0], s[1], ndisp, params=params, plan=plan,
                                                 channels=s[2]))
    height, width, channels = largest
    limit = None if limit_gb is None else limit_gb * 1e9
    try:
        fitted = plan_for_memory(height, width, ndisp, params=params, plan=plan,
                                 channels=channels, limit=limit, share=share, local=local,
                                 worker_tiles=worker_tiles)
    except MemoryEstimateError as error:
        raise refusal(error, plan) from None
    if (fitted.strip_rows, fitted.tile) != (plan.strip_rows, plan.tile):
        peak = estimate(height, width, ndisp, params=params, plan=fitted, channels=channels)
        each = " for each worker" if share > 1 or worker_tiles or not local else ""
        print(f"sswjax: note: matching in {tiling_words(fitted)} to fit in memory (about "
              f"{format_gb(peak)}{each})", file=sys.stderr)
    return fitted
