"""A pair padded to a shape bucket, matched as at its own size.

Shape buckets (:mod:`sswjax.runtime.buckets`) pad a pair at the bottom and right by
replicating its last row and column, so that pairs of nearby sizes share one compiled graph;
the pair's own size reaches the graph traced, as ``valid_shape`` (int32 (2,): height, width).
Matched as it is, the padding is evidence the pair does not hold (its replicated left
columns compared with the real right image), which the semi-global paths carry into the
pair: on KITTI 2012 pair 000114 it cost 2.3 points of bad 2.0. Here every stage sees the
padding as it sees the world beyond the pair's edge at its own size:

- the filters pad by replicating the edge, so each map a filter reads has its padding
  replaced by the edge's values (:func:`padding_as_edge`), and the cost volume's padded
  columns take the last column's cost (:func:`edge_cost_slices`);
- the optimiser's paths start at the edge, so the aggregated cost of the padding is one
  value at every disparity (:func:`outside_as_border`): no evidence.

Array conventions (whole module): maps and volumes ``(..., H, W)`` of the padded size;
``valid_shape`` int32 (2,) or None (nothing padded: every function returns its input).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax import lax

from sswjax.stages.buffers import written_once

__all__ = ["edge_cost_slices", "edge_filler", "outside_as_border", "padding_as_edge"]


def padding_as_edge(values: jax.Array, valid_shape, *, reach: int | None = None) -> jax.Array:
    """``values`` (..., H, W) with the padding a copy of the nearest pixel of the pair.

    ``reach`` (static, optional): how many rows and columns beyond the pair's edge a reader
    looks (a filter's radius); only those are copied, the rest of the padding is left as it
    is. Without it, all of the padding.

    Examples
    --------
    >>> padding_as_edge(jnp.arange(6.0).reshape(2, 3), jnp.array([1, 2])).tolist()
    [[0.0, 1.0, 1.0], [0.0, 1.0, 1.0]]
    >>> padding_as_edge(jnp.arange(4.0)[None], jnp.array([1, 2]), reach=1).tolist()
    [[0.0, 1.0, 1.0, 3.0]]
    """
    if valid_shape is None:
        return values
    if reach is not None:
        # Strips of `reach` columns, then rows, written in place: a volume between the passes
        # of a filter is not read whole again (measured: `fast` on a padded Motorcycle, 102 ms
        # of aggregation by the gather below, 73 ms so).
        values = _edge_strip(values, valid_shape[1], reach, axis=values.ndim - 1)
        return _edge_strip(values, valid_shape[0], reach, axis=values.ndim - 2)
    height, width = values.shape[-2:]
    if values.ndim <= 2:
        # A map written once: the gather would otherwise carry its producer (a reduction over
        # the disparities for the winners' map: 30 ms of `fast`'s refinement, 11 ms so).
        values = written_once(values)
    # One gather at clamped indices: it fuses into its readers where a copy of the edge
    # column and row, read at a traced index, would make XLA write the volume out first.
    rows = jnp.minimum(jnp.arange(height), valid_shape[0] - 1)
    columns = jnp.minimum(jnp.arange(width), valid_shape[1] - 1)
    return values[..., rows[:, None], columns[None, :]]


def _edge_strip(values: jax.Array, valid, reach: int, *, axis: int) -> jax.Array:
    """``values`` with the ``reach`` indices of ``axis`` from ``valid`` on (fewer at the end
    of the axis) a copy of index ``valid - 1``."""
    size = values.shape[axis]
    reach = min(reach, size)
    # The strip moves left at the end of the axis; what it then holds of the pair stays.
    start = jnp.minimum(valid, size - reach)
    strip = lax.dynamic_slice_in_dim(values, start, reach, axis=axis)
    edge = lax.dynamic_slice_in_dim(values, valid - 1, 1, axis=axis)
    index = (start + jnp.arange(reach)).reshape((reach,) + (1,) * (values.ndim - 1 - axis))
    return lax.dynamic_update_slice_in_dim(values, jnp.where(index < valid, strip, edge),
                                           start, axis=axis)


def edge_filler(valid_shape) -> Callable[..., jax.Array] | None:
    """:func:`padding_as_edge` bound to ``valid_shape``: a function of the values and the
    reach, what a filter of several passes applies between them; None without padding."""
    if valid_shape is None:
        return None
    return lambda values, reach: padding_as_edge(values, valid_shape, reach=reach)


def outside_as_border(values: jax.Array, valid_shape, border) -> jax.Array:
    """``values`` (..., H, W) with the padding at ``border`` (a scalar).

    At the border value of Eq. (5) at every disparity, the padding holds no evidence and a
    semi-global path enters the pair as it would at the pair's own edge.

    Examples
    --------
    >>> outside_as_border(jnp.zeros((2, 3)), jnp.array([1, 2]), 3.0).tolist()
    [[0.0, 0.0, 3.0], [3.0, 3.0, 3.0]]
    """
    if valid_shape is None:
        return values
    height, width = values.shape[-2:]
    inside = ((jnp.arange(height)[:, None] < valid_shape[0])
              & (jnp.arange(width)[None, :] < valid_shape[1]))
    return jnp.where(inside, values, jnp.asarray(border, values.dtype))


def edge_cost_slices(slices: Callable, features, first, count: int, valid_shape, border
                     ) -> jax.Array:
    """``slices(features, first, count)`` (float32 (count, H, W), the cost of disparities
    ``first .. first + count - 1``) with the padded columns at the last column's cost.

    The features (a NamedTuple of ``(..., H, W)`` arrays of the left and right view, named
    ``*left`` and ``*right``) are those of :func:`padding_as_edge`, so the padded rows already
    cost what the last row does. The last column's cost is computed on its own, on a window
    of ``count`` columns: the left view's last column and the right columns it meets at each
    disparity (a copy taken from the volume would stop XLA fusing the cost into the
    aggregation). ``border``: the cost where the right pixel is left of the image.
    """
    cost = slices(features, first, count)
    if valid_shape is None:
        return cost
    width = cost.shape[-1]
    last = valid_shape[1] - 1
    steps = jnp.arange(count)
    # Window column j holds the left view's column last - count + 1 + j (only the last, at
    # j = count - 1, is read) and the right view's last - first - count + 1 + j: the last
    # column meets the right view at last - first - k for disparity first + k.
    columns = {"left": jnp.clip(last - count + 1 + steps, 0, width - 1),
               "right": jnp.clip(last - first - count + 1 + steps, 0, width - 1)}
    narrow = features._replace(**{
        name: jnp.take(value, columns["left" if name.endswith("left") else "right"], axis=-1)
        for name, value in features._asdict().items() if isinstance(value, jax.Array)})
    edge = slices(narrow, 0, count)[..., -1:]
    edge = jnp.where((last - first - steps < 0)[:, None, None],
                     jnp.asarray(border, edge.dtype), edge)
    return jnp.where(jnp.arange(width) <= last, cost, edge)
