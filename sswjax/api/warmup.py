"""Compile ahead of time: the graphs a later call on pairs of given shapes will run.

A new image shape costs a trace and an XLA compilation (seconds; ``docs/notes/speed-and-memory.md``).
:func:`warm_up` runs :func:`sswjax.match` (or :func:`sswjax.match_with_confidence`) once on a
blank pair of the shape, with the same parameters and plan, so that this process holds the
compiled graph, and, when the persistent compilation cache is on
(:func:`sswjax.runtime.compilation.enable_compilation_cache`, as ``sswjax warmup`` does), so
that later processes load it from disk, trace included (:mod:`sswjax.runtime.stored`). The graph
does not depend on the pixels, only on their shape: a blank pair compiles what a real one would.

Array conventions: shapes are NumPy's, ``(H, W)`` for a gray pair and ``(H, W, C)`` for
``C`` channels, as the images a later call passes (a gray and a colour pair run different
graphs).
"""

from __future__ import annotations

import numpy as np

from sswjax.api.match import match, match_with_confidence
from sswjax.config import Params
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.runtime.plan import ExecutionPlan

__all__ = ["warm_up"]


def _checked_shape(shape) -> tuple[int, ...]:
    try:
        dims = tuple(int(n) for n in shape)
    except (TypeError, ValueError):
        raise ValueError(f"a shape is (H, W) or (H, W, C) of integers, got {shape!r}") from None
    if len(dims) not in (2, 3) or min(dims[:2]) < 1 or (len(dims) == 3 and dims[2] not in (1, 3, 4)):
        raise ValueError(f"a shape is (H, W) or (H, W, C) with H, W >= 1 and C in 1, 3, 4; "
                         f"got {shape!r}")
    return dims


def warm_up(
    shape, ndisp: int, *, min_disp: int = 0, params: Params | None = None,
    buckets: ShapeBuckets | None = None, plan: ExecutionPlan | None = None,
    confidence: bool = False, check_memory: bool = True,
) -> None:
    """Compile the graph that ``match`` (``confidence``: ``match_with_confidence``) runs on a
    pair of ``shape`` with these options, by running it once on a blank pair.

    Parameters
    ----------
    shape : (H, W) or (H, W, C), C in {1, 3, 4}
        The shape of each image of the pairs to come.
    ndisp, min_disp, params, buckets, plan, check_memory
        As for :func:`sswjax.match`: the graph compiled is the one these select (a plan that
        cuts the pair in strips compiles the strips' graphs). ``ndisp`` must be given.
    confidence : bool
        Warm :func:`sswjax.match_with_confidence`'s graph instead of :func:`sswjax.match`'s.

    Raises
    ------
    ValueError
        For a shape that is not an image's, or ``ndisp`` None; as ``match`` for the rest.

    Examples
    --------
    >>> warm_up((497, 741, 3), 70)        # doctest: +SKIP
    >>> sswjax.match(left, right, 70)     # doctest: +SKIP
    ... # left and right (497, 741, 3): the graph is compiled already
    """
    dims = _checked_shape(shape)
    if ndisp is None:
        raise ValueError("warm_up needs ndisp: the range decides the graph")
    blank = np.zeros(dims, np.uint8)
    run = match_with_confidence if confidence else match
    run(blank, blank, ndisp, min_disp=min_disp, params=params, buckets=buckets, plan=plan,
        check_memory=check_memory)
