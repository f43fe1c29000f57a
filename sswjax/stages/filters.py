"""Side-window box and median filters (Yin, Gong & Qiu, "Side Window Filtering", CVPR 2019).

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
        (``benchmarks/box_sums.py``).

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
    return _closest_window_index(_channels_first(guide), radius, method)


def _channels_first(guide: jax.Array) -> jax.Array:
    """Guide (H, W, C) or (H, W) -> (C, H, W), the layout the window sums batch over."""
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
) -> jax.Array:
    """Side-window box filter (S-BOX of Yin et al. 2019), optionally guided.

    Without ``guide`` each element takes the side-window mean closest to its own value (the
    window is chosen independently on every slice of the leading axes). With ``guide`` the
    window of each pixel is the one whose mean is closest to the guide's value, shared by all
    slices of ``x``; the guide itself is filtered with the same windows before the next
    iteration (joint filtering), so guide and ``x`` evolve together.

    Parameters
    ----------
    x : float32 (..., H, W)
    radius : int >= 1
    iterations : int >= 0
    guide : float32 (H, W, C) or (H, W), optional
    method : {"slices", "cumsum", "reduce_window"}

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
        guide = _channels_first(guide)
    for _ in range(iterations):
        if guide is None:
            x = _closest_side_window_mean(x, radius, method)
        else:
            index = _closest_window_index(guide, radius, method)
            x = select_side_window_mean(x, index, radius=radius, method=method)
            guide = select_side_window_mean(guide, index, radius=radius, method=method)
    return x


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


# ---------------------------------------------------------------------------------------------
# Medians through a sorting network (exact; XLA-on-CPU friendly, unlike jnp.median's sort).


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
    instead of one ``(2r+1)^2``-input network (README, "A separable fill median"). Like the square median, it keeps straight edges and removes structures
    thinner than ``r + 1`` pixels in both directions; it differs from it near corners.

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
    it removes isolated errors without moving depth edges.

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
    for _ in range(iterations):
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
        x = best
    return x
