"""How a call runs, apart from what it computes: the execution plan.

An :class:`ExecutionPlan` is passed beside the parameters, never inside the jitted pytree:
tiles or row strips (memory follows the tile, :mod:`sswjax.runtime.tiles`), shape buckets
(pairs of nearby sizes share a compiled graph) and the disparity blocks of the volume's scans.
The memory guard (:mod:`sswjax.runtime.memory`) chooses or refuses plans;
:func:`sswjax.runtime.execute.execute` runs a jitted graph of :mod:`sswjax.graph` under one.

Array conventions: images float32 ``(H, W, C)`` NumPy arrays, C in {1, 3}, values in [0, 1];
maps ``(H, W)`` NumPy arrays.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

import numpy as np

from sswjax.config import Params
from sswjax.graph import DEFAULT_CHUNK
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.runtime.tiles import Tiling

__all__ = ["ExecutionPlan", "check_plan", "plan_tiling", "pyramid_align", "split_settings",
           "tiling_words"]

_BOUNDS = {"strip_rows": 1_000_000, "strip_overlap": 10_000, "disparity_chunk": 100_000,
           "tile": 1_000_000}


class ExecutionPlan(NamedTuple):
    """How one call of the graph is executed; none of it is a parameter of the method.

    Attributes
    ----------
    strip_rows : int
        ``R > 0``: match the pair in horizontal strips of ``R`` rows (the tiling of one
        column, :mod:`sswjax.runtime.tiles`), each seen with ``strip_overlap`` more rows above
        and below: memory follows the strip, not the image. 0 (default): the whole image at
        once. The memory guard chooses strips or tiles when the whole pair does not fit.
    strip_overlap : int
        The collar (default 96): rows of context above and below each strip or tile, and
        columns left and right of each tile (besides the ``ndisp`` columns on either side).
        96, measured: tiles give the whole image's maps on MiddEval3 trainingQ and Middlebury
        2001 (``docs/cluster.md``); 32 computes less and changes more pixels.
    buckets : ShapeBuckets or None
        Pad the pair to a bucketed shape so that pairs of nearby sizes reuse one compilation
        (results near the bottom and right borders can change slightly); None: exact shape.
    disparity_chunk : int
        K > 0 (default 4): the volume is built and folded K disparities at a time, memory for
        about ``3 K`` slices; 0: the whole volume at once. The same result either way.
    tile : int
        ``S > 0``: match the pair in tiles of ``S x S`` pixels, each seen with the collar
        around it and ``ndisp`` more columns on either side (what its disparities and the
        left-right check reach; rows or columns the tile covers whole are not cut); not with
        ``strip_rows``. 0 (default): no tiles.
    engine : object or None
        Where the windows run: None (default) in this process, one after the other; an engine
        such as :class:`sswjax.cluster.DaskEngine` runs them elsewhere (its ``execute`` has
        the signature of :func:`sswjax.runtime.execute.run_windows`: the method's call on the
        pair padded to its bucket and aligned). Never changes the maps.
    carry_paths : bool
        True (default): row strips of a method with semi-global paths over the full-resolution
        volume carry the paths along the rows from strip to strip (two sweeps,
        :mod:`sswjax.runtime.carried`), so that the strips give the whole image's maps;
        False: each strip's paths start afresh at its edges (one sweep, and its strips
        independent tasks under an engine). Tiles that cut the columns never carry them.
    """

    strip_rows: int = 0
    strip_overlap: int = 96
    buckets: ShapeBuckets | None = None
    disparity_chunk: int = DEFAULT_CHUNK
    tile: int = 0
    engine: object = None
    carry_paths: bool = True


def check_plan(plan) -> ExecutionPlan:
    """Validate an execution plan given to the API; return it unchanged.

    Raises ``TypeError`` for another type and ``ValueError`` with a one-line message naming
    the field for a bad value.
    """
    if not isinstance(plan, ExecutionPlan):
        raise TypeError(f"plan must be a sswjax.ExecutionPlan, got {type(plan).__name__}")
    for name, high in _BOUNDS.items():
        value = getattr(plan, name)
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
                or not 0 <= value <= high:
            raise ValueError(f"plan.{name} must be an integer in [0, {high}], got {value!r}")
    if not isinstance(plan.carry_paths, (bool, np.bool_)):
        raise ValueError(f"plan.carry_paths must be True or False, got {plan.carry_paths!r}")
    if plan.engine is not None and not callable(getattr(plan.engine, "execute", None)):
        raise TypeError(f"plan.engine must be None or have an execute method (a "
                        f"sswjax.cluster.DaskEngine), got {type(plan.engine).__name__}")
    if plan.tile and plan.strip_rows:
        raise ValueError(f"plan.tile ({plan.tile}) and plan.strip_rows ({plan.strip_rows}) are "
                         "both set: give tile=S for S x S tiles or strip_rows=R for strips")
    if plan.buckets is not None:
        if not isinstance(plan.buckets, ShapeBuckets):
            raise TypeError(f"plan.buckets must be a sswjax.ShapeBuckets, got "
                            f"{type(plan.buckets).__name__}")
        for name in ShapeBuckets._fields:
            value = getattr(plan.buckets, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"buckets.{name} must be an integer >= 1, got {value!r}")
    return plan


def split_settings(params, changes: Mapping) -> tuple[Params, ExecutionPlan]:
    """``params`` with the parameter changes of ``changes`` applied (stages and dotted
    options, :meth:`sswjax.config.Params.replace`), and the plan of its execution fields: one
    mapping of both, as the benchmarks' configurations list them.

    Examples
    --------
    >>> from sswjax.config import preset
    >>> params, plan = split_settings(preset("paper"), {"strip_rows": 64, "fill.median_radius": 3})
    >>> plan.strip_rows, params.fill.median_radius
    (64, 3)
    """
    execution = {k: v for k, v in changes.items() if k in ExecutionPlan._fields}
    rest = {k: v for k, v in changes.items() if k not in execution}
    return params.replace(**rest), check_plan(ExecutionPlan(**execution))


def plan_tiling(plan: ExecutionPlan, ndisp: int, *, align: int = 1) -> Tiling:
    """The tiling of ``plan`` for a search of ``ndisp`` disparities: ``tile x tile`` cores,
    or strips of ``strip_rows`` full rows, with the plan's collar.

    >>> plan_tiling(ExecutionPlan(tile=256), 64)
    Tiling(rows=256, cols=256, overlap=96, lead=64, align=1)
    """
    if plan.tile:
        return Tiling(plan.tile, plan.tile, plan.strip_overlap, int(ndisp), align)
    return Tiling(plan.strip_rows, 0, plan.strip_overlap, int(ndisp), align)


def tiling_words(plan: ExecutionPlan) -> str:
    """How ``plan`` cuts a pair, in words.

    >>> tiling_words(ExecutionPlan(tile=512)), tiling_words(ExecutionPlan(strip_rows=64))
    ('tiles of 512 x 512', 'strips of 64 rows')
    """
    if plan.tile:
        return f"tiles of {plan.tile} x {plan.tile}"
    return f"strips of {plan.strip_rows} rows" if plan.strip_rows else "the whole image"


def pyramid_align(params: Params) -> int:
    """The factor window origins are rounded to: ``2 ** levels`` of coarse-to-fine, else 1."""
    return 1 if params.coarse is None else 2 ** params.coarse.levels
