"""Side-window box filters (Yin, Gong & Qiu, "Side Window Filtering", CVPR 2019); their median
counterparts are :mod:`sswjax.stages.medians`.

Array conventions (whole module): arrays are float32 ``(..., H, W)``: the filters act on the
last two axes and treat leading axes (disparities, channels) as a batch. Borders are
edge-replicated once, before filtering, as in the authors' code.

The eight side windows of radius ``r`` have the centre pixel on an edge or a corner: the halves
L, R, U, D ((2r+1) x (r+1)) and the quadrants NW, NE, SW, SE ((r+1) x (r+1)). Each is the
product of a vertical extent (up ``[y-r, y]``, down ``[y, y+r]`` or full) and a horizontal
extent (left, right or full), minus full x full. So all eight sums come from three 1-D sums
per axis, computed in O(1) per pixel from running sums or in O(r) from shifted slices.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from sswjax._checks import (
    check_floating,
    check_integer,
    check_map,
    check_positive_int,
    check_rank,
)
from sswjax.stages.loops import repeated

# (vertical extent, horizontal extent) of each window, in the order L, R, U, D, NW, NE, SW, SE.
SIDE_WINDOWS = (
    ("full", "before"),
    ("full", "after"),
    ("before", "full"),
    ("after", "full"),
    ("before", "before"),
    ("before", "after"),
    ("after", "before"),
    ("after", "after"),
)
SUM_METHODS = ("slices", "cumsum", "reduce_window")


def edge_pad(x: jax.Array, radius: int) -> jax.Array:
    """Edge-replicate ``radius`` samples on both sides of the last two axes of ``(..., H, W)``."""
    return jnp.pad(x, [(0, 0)] * (x.ndim - 2) + [(radius, radius), (radius, radius)], mode="edge")


def _extent_sums(padded: jax.Array, radius: int, axis: int, method: str) -> dict[str, jax.Array]:
    """1-D sums over ``[i-r, i]``, ``[i, i+r]`` and ``[i-r, i+r]`` along ``axis``.

    ``padded`` carries ``radius`` extra samples at both ends of ``axis``; the outputs do not.
    """
    n = padded.shape[axis] - 2 * radius

    def take(start: int, size: int) -> jax.Array:
        return jax.lax.slice_in_dim(padded, start, start + size, axis=axis)

    if method == "slices":
        before = sum(take(radius - k, n) for k in range(radius + 1))
        after = sum(take(radius + k, n) for k in range(radius + 1))
    elif method == "cumsum":
        zero = jnp.zeros_like(take(0, 1))
        running = jnp.concatenate([zero, jnp.cumsum(padded, axis=axis)], axis=axis)
        # sum of padded[a : b] = running[b] - running[a]
        before = take_running(running, 0, radius + 1, n, axis)
        after = take_running(running, radius, 2 * radius + 1, n, axis)
    elif method == "reduce_window":
        dims = [1] * padded.ndim
        dims[axis] = radius + 1
        # window sums of r + 1 samples starting at every position: sums[j] = padded[j : j + r + 1]
        sums = jax.lax.reduce_window(padded, 0.0, jax.lax.add, tuple(dims), (1,) * padded.ndim, "VALID")
        before = jax.lax.slice_in_dim(sums, 0, n, axis=axis)
        after = jax.lax.slice_in_dim(sums, radius, radius + n, axis=axis)
    else:
        raise ValueError(f"method must be one of {SUM_METHODS}, got {method!r}")
    return {"before": before, "after": after, "full": before + after - take(radius, n)}


def take_running(running: jax.Array, start: int, stop: int, n: int, axis: int) -> jax.Array:
    """Window sums ``padded[i + start : i + stop]`` for i in [0, n) from an exclusive prefix sum."""
    upper = jax.lax.slice_in_dim(running, stop, stop + n, axis=axis)
    lower = jax.lax.slice_in_dim(running, start, start + n, axis=axis)
    return upper - lower


def _side_window_mean_fn(x: jax.Array, radius: int, method: str) -> Callable[[int], jax.Array]:
    """Return ``mean(k)``: the mean of ``x`` over side window ``k`` (in ``SIDE_WINDOWS`` order)."""
    r = radius
    padded = edge_pad(x, r)
    vertical = _extent_sums(padded, r, x.ndim - 2, method)  # (..., H, W + 2r) each
    count = {"before": r + 1, "after": r + 1, "full": 2 * r + 1}
    cache: dict[str, dict[str, jax.Array]] = {}

    def mean(k: int) -> jax.Array:
        v, h = SIDE_WINDOWS[k]
        if v not in cache:
            cache[v] = _extent_sums(vertical[v], r, x.ndim - 1, method)
        return cache[v][h] / (count[v] * count[h])

    return mean


def side_window_means(x: jax.Array, *, radius: int, method: str = "slices") -> jax.Array:
    """Means of ``x`` over the eight side windows of every pixel.

    Parameters
    ----------
    x : float32 (..., H, W)
    radius : int >= 1
    method : {"slices", "cumsum", "reduce_window"}
        Sum of ``r + 1`` shifted slices, differences of a running sum (O(1) in ``r``), or XLA's
        windowed reduction. On XLA CPU shifted slices measured fastest for r <= 9
        (``box_sums.py``, since out of the tree: ``docs/notes/benchmarks-concluded.md``).

    Returns
    -------
    float32 (8, ..., H, W), windows in the order L R U D NW NE SW SE (``SIDE_WINDOWS``).

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> x = jnp.zeros((5, 5)).at[:, 3:].set(1.0)   # a vertical step edge
    >>> m = side_window_means(x, radius=1)
    >>> [float(v) for v in m[:, 2, 2]]   # at the column left of the edge: L and NW/SW are pure
    [0.0, 0.5, 0.3333333432674408, 0.3333333432674408, 0.0, 0.5, 0.0, 0.5]
    """
    check_map("x", x, radius)
    mean = _side_window_mean_fn(x, radius, method)
    return jnp.stack([mean(k) for k in range(8)])


def side_window_index(guide: jax.Array, *, radius: int, method: str = "slices") -> jax.Array:
    """Index (0..7) of the side window whose mean is closest to each pixel of ``guide``.

    Parameters
    ----------
    guide : float32 (H, W, C) or (H, W)
        Guidance image; with channels, distances are summed over them (L1).
    radius : int >= 1

    Returns
    -------
    int32 (H, W)
    """
    check_rank("guide", guide, (2, 3))
    check_floating("guide", guide)
    check_positive_int("radius", radius)
    return _closest_window_index(channels_first(guide), radius, method)


def channels_first(guide: jax.Array) -> jax.Array:
    """Guide (H, W, C) or (H, W) -> (C, H, W) of the same dtype, the layout the window sums
    batch over."""
    return jnp.moveaxis(guide, -1, 0) if guide.ndim == 3 else guide[None]


def _closest_window_index(g: jax.Array, radius: int, method: str) -> jax.Array:
    mean = _side_window_mean_fn(g, radius, method)
    best_distance = best_index = None
    for k in range(8):
        distance = jnp.abs(mean(k) - g).sum(axis=0)
        if best_distance is None:
            best_distance, best_index = distance, jnp.zeros(distance.shape, jnp.int32)
        else:
            better = distance < best_distance
            best_distance = jnp.where(better, distance, best_distance)
            best_index = jnp.where(better, k, best_index)
    return best_index


def select_side_window_mean(
    x: jax.Array, index: jax.Array, *, radius: int, method: str = "slices"
) -> jax.Array:
    """Mean of ``x`` over the side window ``index[y, x]`` of every pixel.

    Never materialises all eight means of a large volume at once.

    Parameters
    ----------
    x : float32 (..., H, W)
    index : int (H, W), values in 0..7, broadcast over the leading axes of ``x``.

    Returns
    -------
    float32 (..., H, W)
    """
    check_map("x", x, radius)
    check_rank("index", index, 2)
    check_integer("index", index)
    mean = _side_window_mean_fn(x, radius, method)
    out = mean(0)
    for k in range(1, 8):
        out = jnp.where(index == k, mean(k), out)
    return out


def side_window_box_filter(
    x: jax.Array,
    *,
    radius: int,
    iterations: int = 1,
    guide: jax.Array | None = None,
    method: str = "slices",
    between: Callable[[jax.Array, int], jax.Array] | None = None,
) -> jax.Array:
    """Side-window box filter (S-BOX of Yin et al. 2019), optionally guided.

    Without ``guide`` each element takes the side-window mean closest to its own value (the
    window is chosen independently on every slice of the leading axes). With ``guide`` the
    window of each pixel is the one whose mean is closest to the guide's value, shared by all
    slices of ``x``; the guide itself is filtered with the same windows before the next
    iteration (joint filtering), so guide and ``x`` evolve together. The passes after the
    first are one loop of the graph (:func:`~sswjax.stages.loops.repeated`: compiled once; the
    first pass stays outside it, where XLA fuses it with the cost before): ``fast``'s three
    passes compiled in the same time within 0.15 s and its warm call took 2-7 % less
    (docs/notes/speed-and-memory.md).

    Parameters
    ----------
    x : float32 (..., H, W)
    radius : int >= 1
    iterations : int >= 0
    guide : float32 (H, W, C) or (H, W), optional
    method : {"slices", "cumsum", "reduce_window"}
    between : callable, optional
        ``between(values, radius)``: a function of an array (..., H, W) and of how far
        beyond a pixel the next pass reads, applied to ``x`` (and to a guide, channels first)
        between passes; the graph copies the edge into a shape bucket's padding with it.

    Returns
    -------
    float32, shape of ``x``

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> step = jnp.zeros((6, 6)).at[:, 3:].set(1.0)
    >>> bool((side_window_box_filter(step, radius=2, iterations=2) == step).all())  # edge kept
    True
    """
    check_map("x", x, radius)
    if iterations < 0:
        raise ValueError(f"iterations must be >= 0, got {iterations}")
    if guide is not None:
        check_rank("guide", guide, (2, 3))
        check_floating("guide", guide)
        if guide.shape[:2] != x.shape[-2:]:
            raise ValueError(f"guide size {guide.shape[:2]} differs from x size {x.shape[-2:]}")
        guide = channels_first(guide)

    def one_pass(carry):
        x, guide = carry
        if guide is None:
            return _closest_side_window_mean(x, radius, method), None
        index = _closest_window_index(guide, radius, method)
        return (select_side_window_mean(x, index, radius=radius, method=method),
                select_side_window_mean(guide, index, radius=radius, method=method))

    def later_pass(carry):
        x, guide = carry
        if between is not None:
            x, guide = between(x, radius), None if guide is None else between(guide, radius)
        return one_pass((x, guide))

    if iterations == 0:
        return x
    return repeated(later_pass, one_pass((x, guide)), times=iterations - 1)[0]


def _closest_side_window_mean(x: jax.Array, radius: int, method: str) -> jax.Array:
    mean = _side_window_mean_fn(x, radius, method)
    best = mean(0)
    best_distance = jnp.abs(best - x)
    for k in range(1, 8):
        candidate = mean(k)
        distance = jnp.abs(candidate - x)
        better = distance < best_distance
        best = jnp.where(better, candidate, best)
        best_distance = jnp.where(better, distance, best_distance)
    return best
