"""Tiles: a pair matched in overlapping windows, the results stitched.

A tiling cuts the image into *cores* of ``rows x cols`` pixels; each core is matched inside a
*window* that adds a collar of ``overlap`` rows above and below it and, when the columns are
cut, ``lead + overlap`` columns on either side. ``lead`` is the number of disparities
searched: a left pixel ``x`` is compared with the right columns ``x - lead + 1 .. x``, so the
window of the core ``[x0, x1)`` holds the right image's columns from ``x0 - lead - overlap``;
and the right view's map, which the left-right check reads at ``x - d``, compares a right
pixel with the left columns up to ``lead - 1`` on its right, so the window reaches
``x1 + lead + overlap``. Both images are cut alike (the graph matches two images of one
shape), and only the core of each window is kept. Every window has one shape (those at the
borders slide inside the image), so one compilation serves every tile, and two images larger
than the window share it too. What a window cannot see is what changes: the semi-global paths
and the superpixels start afresh at its edges, which the collar keeps away from the core
(``benchmarks/tiles.py`` measures the seams).

Row strips (``ExecutionPlan(strip_rows=R)``) are the tiling of one column (``cols = 0``); a
tiling whose window covers the image is the whole image, matched as such.

Array conventions: images float32 ``(H, W, C)`` NumPy arrays; a run returns a map ``(h, w)``
(or a NamedTuple of maps of any dtypes) for a window of ``h x w`` pixels.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import NamedTuple

import jax
import numpy as np

__all__ = ["CARRIED_COLLAR", "PREFERRED_CORE", "TILE_SIZES", "Tiling", "Window", "assemble",
           "core_of", "in_tiles", "tile_count", "tile_windows", "tilings_by_work", "to_numpy",
           "window_shape"]

TILE_SIZES = (2048, 1536, 1024, 768, 512, 384, 256, 192, 128)
"""Square tile sizes (core rows and columns) the memory guard tries besides full-width strips."""

PREFERRED_CORE = 256
"""Cores of at least this many rows come first in :func:`tilings_by_work` among those with the
whole collar, whatever their work. A thin core cuts every vertical semi-global path of a
textureless region often: on a 4000 x 3000 pair with 256 disparities under a 3 GB budget, the
fewest-pixels choice (strips of 64 rows) changed 3.36 % of the pixels against tiles of 1024,
tiles of 512 0.03 % for about 14 % more work; on KITTI 2012, strips of 48 rows changed 14.5 %
(``docs/cluster.md``, "The seams, measured")."""


CARRIED_COLLAR = 48
"""The least collar the memory guard gives strips whose semi-global paths are carried
(:mod:`sswjax.runtime.carried`), even when it is wider than their core: the seed enters half
of it in, and the fill, medians and smoothing of ``accurate`` reach about 27 rows (KITTI 2012
000122 under 1 GB: strips of 32 rows with a collar of 32 changed 1.44 % of the pixels, strips
of 16 with 48 0.002 %, ``docs/cluster.md``)."""


class Tiling(NamedTuple):
    """How an image is cut: cores of ``rows x cols`` (0: the whole height or width), a collar
    of ``overlap`` pixels, ``lead`` more columns either side when columns are cut (the
    disparities searched), window origins rounded down to multiples of ``align`` (the
    pyramid's factor, so that a halved window is a window of the halved image; the windows
    are ``align - 1`` pixels longer for it)."""

    rows: int
    cols: int
    overlap: int
    lead: int
    align: int = 1


class Window(NamedTuple):
    """One tile: its window ``[top, top + height) x [left, left + width)`` in the image, and
    the core ``[first, last) x [start, stop)`` it gives (image coordinates)."""

    top: int
    left: int
    height: int
    width: int
    first: int
    last: int
    start: int
    stop: int


def _axis(size: int, core: int, before: int, after: int, align: int
          ) -> tuple[int, list[tuple[int, int, int]]]:
    """The window length along one axis and its ``(window start, core first, core last)``s.

    A core of 0, or a window at least as long as the axis, is the whole axis at once."""
    window = core + before + after + align - 1  # room to round a start down
    if core <= 0 or window >= size:
        return size, [(0, 0, size)]
    spans = []
    for first in range(0, size, core):
        last = min(first + core, size)
        start = max(first - before, 0)
        # rounded down to the pyramid's factor, except at the far end, which it would lose
        spans.append((start - start % align if start + window <= size else size - window,
                      first, last))
    return window, spans


def window_shape(height: int, width: int, tiling: Tiling) -> tuple[int, int]:
    """``(h, w)`` of every window of ``tiling`` on an ``height x width`` image.

    Examples
    --------
    >>> window_shape(1000, 3000, Tiling(rows=256, cols=256, overlap=32, lead=128))
    (320, 576)
    >>> window_shape(1000, 3000, Tiling(rows=256, cols=0, overlap=32, lead=128))
    (320, 3000)
    """
    rows, _ = _axis(height, tiling.rows, tiling.overlap, tiling.overlap, tiling.align)
    cols, _ = _axis(width, tiling.cols, tiling.lead + tiling.overlap, tiling.lead + tiling.overlap,
                    tiling.align)
    return rows, cols


def tile_count(height: int, width: int, tiling: Tiling) -> int:
    """How many windows ``tiling`` cuts an ``height x width`` image into.

    >>> tile_count(1000, 3000, Tiling(rows=256, cols=256, overlap=32, lead=128))
    48
    """
    h, w = window_shape(height, width, tiling)
    return ((1 if h >= height else math.ceil(height / tiling.rows))
            * (1 if w >= width else math.ceil(width / tiling.cols)))


def tilings_by_work(height: int, width: int, *, lead: int, overlap: int,
                    strip_heights: Iterable[int], tile_sizes: Iterable[int] = TILE_SIZES,
                    carried: bool = False) -> list[Tiling]:
    """The full-width strips of ``strip_heights`` lower than the image and the square tiles of
    ``tile_sizes`` that cut its columns, in the memory guard's order of preference. The collar
    is capped at the core's size; those with the whole ``overlap`` come first (a capped collar
    lets each window's paths start too close to its core: on KITTI 2012 under a 1 GB budget,
    strips of 48 rows with a collar of 48 changed 13.5 % of a pair's pixels, tiles of 128 with
    96 1.7 %, ``docs/cluster.md``); then cores of :data:`PREFERRED_CORE` rows or more; within
    each group the fewest computed pixels first (windows times their area: the collars and the
    ``lead`` columns are computed again); on a tie strips first, then the larger.

    ``carried``: the method's paths along the rows run on from strip to strip
    (:mod:`sswjax.runtime.carried`), so a strip's height no longer matters and strips, whose
    paths are then the whole image's, come before every tiling that cuts the columns (whose
    paths along the rows still restart); then the whole collar, then a collar of at least
    :data:`CARRIED_COLLAR` (strips thinner than it are tried with it too), then the fewest
    pixels.

    Examples
    --------
    >>> [t[:2] for t in tilings_by_work(2000, 6000, lead=256, overlap=32, strip_heights=(512,),
    ...                                 tile_sizes=(2048, 256))]
    [(512, 0), (2048, 2048), (256, 256)]
    >>> [t[:2] for t in tilings_by_work(3000, 4000, lead=256, overlap=96,
    ...                                 strip_heights=(64, 32), tile_sizes=(512, 128))]
    [(512, 512), (128, 128), (64, 0), (32, 0)]
    >>> [t[:3] for t in tilings_by_work(3000, 4000, lead=256, overlap=96, carried=True,
    ...                                 strip_heights=(64, 32), tile_sizes=(512, 128))]
    [(64, 0, 64), (32, 0, 48), (32, 0, 32), (512, 512, 96), (128, 128, 96)]
    """
    trials = [Tiling(rows, 0, min(overlap, rows), lead) for rows in strip_heights if rows < height]
    enough = min(overlap, CARRIED_COLLAR)
    if carried:
        trials += [Tiling(rows, 0, enough, lead) for rows in strip_heights
                   if rows < min(height, enough)]
    trials += [tiling for tiling in (Tiling(size, size, min(overlap, size), lead)
                                     for size in tile_sizes)
               if window_shape(height, width, tiling)[1] < width]

    def work(tiling):
        rows, cols = window_shape(height, width, tiling)
        pixels = tile_count(height, width, tiling) * rows * cols
        if carried:
            return (tiling.cols > 0, tiling.overlap < overlap, tiling.overlap < enough, pixels,
                    -tiling.rows)
        return (tiling.overlap < overlap, tiling.rows < PREFERRED_CORE, pixels, tiling.cols > 0,
                -tiling.rows)

    return sorted(trials, key=work)


def tile_windows(height: int, width: int, tiling: Tiling) -> list[Window]:
    """The windows of ``tiling`` on an ``height x width`` image, row by row; their cores
    partition the image.

    Examples
    --------
    >>> [w[:2] + w[4:] for w in tile_windows(10, 60, Tiling(4, 16, 1, 8))]
    [(0, 0, 0, 4, 0, 16), (0, 7, 0, 4, 16, 32), (0, 23, 0, 4, 32, 48), (0, 26, 0, 4, 48, 60), \
(3, 0, 4, 8, 0, 16), (3, 7, 4, 8, 16, 32), (3, 23, 4, 8, 32, 48), (3, 26, 4, 8, 48, 60), \
(4, 0, 8, 10, 0, 16), (4, 7, 8, 10, 16, 32), (4, 23, 8, 10, 32, 48), (4, 26, 8, 10, 48, 60)]
    """
    h, rows = _axis(height, tiling.rows, tiling.overlap, tiling.overlap, tiling.align)
    w, cols = _axis(width, tiling.cols, tiling.lead + tiling.overlap, tiling.lead + tiling.overlap,
                    tiling.align)
    return [Window(top, left, h, w, first, last, start, stop)
            for top, first, last in rows for left, start, stop in cols]


def core_of(window: Window, maps):
    """The core of a window's result: ``maps`` (a NumPy ``(h, w)`` map or a NamedTuple of
    them) cropped to ``(last - first, stop - start)``."""
    rows = slice(window.first - window.top, window.last - window.top)
    cols = slice(window.start - window.left, window.stop - window.left)
    if isinstance(maps, tuple):
        return type(maps)(*(np.asarray(m)[rows, cols] for m in maps))
    return np.asarray(maps)[rows, cols]


def assemble(height: int, width: int, pieces: Iterable[tuple[Window, object]]):
    """The ``height x width`` maps stitched from ``(window, core)`` pieces (in any order)
    whose cores partition the image: each pixel comes from the one tile whose core holds it.

    Returns a NumPy ``(H, W)`` map of the cores' dtype, or the cores' NamedTuple of them.
    """
    out, kind = None, None
    for window, part in pieces:
        kind = type(part) if isinstance(part, tuple) else None
        parts = part if kind else (part,)
        if out is None:
            out = [np.empty((height, width), np.asarray(p).dtype) for p in parts]
        for whole, piece in zip(out, parts):
            whole[window.first:window.last, window.start:window.stop] = piece
    if out is None:
        raise ValueError("no tiles to assemble")
    return kind(*out) if kind else out[0]


def to_numpy(result):
    """A map, or a (Named)tuple of maps, as NumPy arrays of the same structure."""
    if isinstance(result, tuple):
        return type(result)(*(np.asarray(part) for part in result))
    return np.asarray(result)


def in_tiles(run: Callable, left: np.ndarray, right: np.ndarray, tiling: Tiling):
    """``run(window, left, right)`` on the windows of ``tiling``, one after the other, stitched.

    Memory follows the window instead of the image. A tiling of one window that covers the
    image runs the whole pair at once.

    Parameters
    ----------
    run : callable
        ``run(window, left, right) -> (h, w)`` map of float32 ``(h, w, C)`` JAX images (the
        crops of the :class:`Window`, or the whole pair with ``window`` None), or a
        NamedTuple of such maps of any dtypes: each is stitched.
    left, right : float32 (H, W, C)
    tiling : Tiling

    Returns
    -------
    numpy.ndarray (H, W) of the map's dtype, or the same NamedTuple of them

    Examples
    --------
    >>> image = np.arange(10.0)[:, None, None] * np.ones((10, 40, 1))
    >>> seen = in_tiles(lambda w, l, r: l[..., 0], image, image, Tiling(4, 8, 1, 4))
    >>> seen[:, 0].tolist() == list(range(10)) and seen.shape == (10, 40)
    True
    """
    height, width = left.shape[:2]
    windows = tile_windows(height, width, tiling)
    if len(windows) == 1:
        return to_numpy(run(None, jax.device_put(left), jax.device_put(right)))

    def pieces():
        for w in windows:
            rows, cols = slice(w.top, w.top + w.height), slice(w.left, w.left + w.width)
            yield w, core_of(w, to_numpy(run(w, jax.device_put(left[rows, cols]),
                                             jax.device_put(right[rows, cols]))))

    return assemble(height, width, pieces())
