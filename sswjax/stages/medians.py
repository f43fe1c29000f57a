"""Medians through a sorting network (exact; XLA-on-CPU friendly, unlike ``jnp.median``'s sort):
the square and separable medians of the fills, and the side-window median of the refinement
(Yin, Gong & Qiu, "Side Window Filtering", CVPR 2019, Sec. 4).

Array conventions (whole module): arrays are float32 ``(..., H, W)``: the filters act on the
last two axes and treat leading axes as a batch. Borders are edge-replicated once, before
filtering, as in :mod:`sswjax.stages.filters`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax._checks import check_map
from sswjax.stages.filters import SIDE_WINDOWS, edge_pad
from sswjax.stages.loops import repeated

__all__ = ["median_filter", "median_of_stack", "separable_median_filter",
           "side_window_median_filter"]


def _odd_even_merge_sort_pairs(n: int) -> list[tuple[int, int]]:
    """Comparator pairs of Batcher's odd-even merge sort for ``n`` (a power of two) inputs."""
    pairs = []
    p = 1
    while p < n:
        k = p
        while k >= 1:
            for j in range(k % p, n - k, 2 * k):
                for i in range(min(k, n - j - k)):
                    if (i + j) // (2 * p) == (i + j + k) // (2 * p):
                        pairs.append((i + j, i + j + k))
            k //= 2
        p *= 2
    return pairs


def median_of_stack(values: list[jax.Array]) -> jax.Array:
    """Exact elementwise (lower) median of a list of equally shaped arrays.

    Uses Batcher's odd-even merge sorting network (min/max only), padded with ``+inf``; only
    the comparators that can influence the median are kept.

    Parameters
    ----------
    values : list of n float32 arrays of one shape

    Returns
    -------
    float32 array of that shape: element ``(n - 1) // 2`` of the sorted values.
    """
    n = len(values)
    if n == 0:
        raise ValueError("median of an empty list")
    size = 1 << (n - 1).bit_length()
    pairs = _odd_even_merge_sort_pairs(size)
    # Keep only comparators on which the median output depends (backwards reachability).
    needed = {(n - 1) // 2}
    kept = []
    for a, b in reversed(pairs):
        if a in needed or b in needed:
            kept.append((a, b))
            needed.update((a, b))
    kept.reverse()
    pad = jnp.full_like(values[0], jnp.inf)
    lanes = list(values) + [pad] * (size - n)
    for a, b in kept:
        lanes[a], lanes[b] = jnp.minimum(lanes[a], lanes[b]), jnp.maximum(lanes[a], lanes[b])
    return lanes[(n - 1) // 2]


def _shifted(padded: jax.Array, radius: int, dy: int, dx: int) -> jax.Array:
    h = padded.shape[-2] - 2 * radius
    w = padded.shape[-1] - 2 * radius
    return padded[..., radius + dy : radius + dy + h, radius + dx : radius + dx + w]


def median_filter(x: jax.Array, *, radius: int) -> jax.Array:
    """Median over the ``(2r+1) x (2r+1)`` window of every pixel (edge-replicated borders).

    Parameters
    ----------
    x : float32 (..., H, W)
    radius : int >= 1

    Returns
    -------
    float32, shape of ``x``
    """
    check_map("x", x, radius)
    r = radius
    padded = edge_pad(x, r)
    offsets = range(-r, r + 1)
    return median_of_stack([_shifted(padded, r, dy, dx) for dy in offsets for dx in offsets])


def separable_median_filter(x: jax.Array, *, radius: int) -> jax.Array:
    """Separable median: the median over each row's ``2r+1`` values of the medians over columns.

    Narendra, "A Separable Median Filter for Image Noise Smoothing", IEEE TPAMI 3(1), 1981: the
    median of the ``2r + 1`` column medians of a ``(2r+1) x (2r+1)`` window, an approximation of
    its median (:func:`median_filter`) that needs two ``2r + 1``-input sorting networks per pixel
    instead of one ``(2r+1)^2``-input network (``docs/notes/beyond-the-paper.md``, "A separable fill
    median"). Like the square median, it keeps straight edges and removes structures thinner
    than ``r + 1`` pixels in both directions; it differs from it near corners.

    Parameters
    ----------
    x : float32 (..., H, W)
    radius : int >= 1
        Window radius; edge-replicated borders.

    Returns
    -------
    float32, shape of ``x``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.zeros((5, 6)).at[:, 3:].set(3.0).at[2, 1].set(9.0)   # an edge and an outlier
    >>> separable_median_filter(d, radius=1)[2].tolist()
    [0.0, 0.0, 0.0, 3.0, 3.0, 3.0]
    """
    check_map("x", x, radius)
    r = radius
    height, width = x.shape[-2:]
    padded = edge_pad(x, r)
    # Column medians over the padded width: at the replicated border columns they are the
    # border column's medians, i.e. the column medians edge-padded, as the row pass needs.
    columns = median_of_stack([padded[..., dy:dy + height, :] for dy in range(2 * r + 1)])
    return median_of_stack([columns[..., dx:dx + width] for dx in range(2 * r + 1)])


_EXTENT_OFFSETS = {
    "before": lambda r: range(-r, 1),
    "after": lambda r: range(0, r + 1),
    "full": lambda r: range(-r, r + 1),
}


def side_window_median_filter(x: jax.Array, *, radius: int, iterations: int = 1) -> jax.Array:
    """Side-window median filter: each pixel takes the side-window median closest to its value.

    The median counterpart of S-BOX (Yin et al. 2019, Sec. 4), used to refine disparity maps:
    it removes isolated errors without moving depth edges. Two or more iterations are one loop
    of the graph (:func:`~sswjax.stages.loops.repeated`: compiled once).

    Parameters
    ----------
    x : float32 (..., H, W)
    radius : int >= 1
    iterations : int >= 0

    Returns
    -------
    float32, shape of ``x``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.zeros((7, 7)).at[:, 4:].set(5.0).at[3, 1].set(9.0)  # edge + one outlier
    >>> out = side_window_median_filter(d, radius=2)
    >>> float(out[3, 1]), bool((out[:, 4:] == 5).all())
    (0.0, True)
    """
    check_map("x", x, radius)
    r = radius

    def one(x):
        padded = edge_pad(x, r)
        best = best_distance = None
        for v, h in SIDE_WINDOWS:
            stack = [
                _shifted(padded, r, dy, dx)
                for dy in _EXTENT_OFFSETS[v](r)
                for dx in _EXTENT_OFFSETS[h](r)
            ]
            candidate = median_of_stack(stack)
            distance = jnp.abs(candidate - x)
            if best is None:
                best, best_distance = candidate, distance
            else:
                better = distance < best_distance
                best = jnp.where(better, candidate, best)
                best_distance = jnp.where(better, distance, best_distance)
        return best
    return repeated(one, x, times=iterations)
