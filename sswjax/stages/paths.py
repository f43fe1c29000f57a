"""The loops of the semi-global paths: Eq. 13 line by line along one axis of a volume, and the
states that carry a path from one window of an image into the next.

Array conventions (whole module): a volume is ``(D, S, N)``, disparity first, scanned along
axis 1 (S steps), each step a *line* ``(D, N)`` of D contiguous runs; float32, int16 (paths
quantised, :mod:`sswjax.stages.quantisation`) or uint8 (stored levels, widened by
``levels_step``). Penalty maps are ``(S, N)``, the penalty of the step that reaches each pixel.
A path's state before its first line is the zero line (``L_r = C`` at the border).

Carried paths (:class:`Seeds`). A window of an image cut into row strips knows nothing of the
lines above or below it: its vertical paths would start afresh at its edges. Seeded, the
forward paths take, before line ``entry[0]``, the state a neighbouring window left at that row
instead of the state the window itself reached, and the backward ones likewise before line
``S - 1 - entry[1]``; each direction's state after step ``capture[k]`` (forward: after line
``capture[0]``; backward: after line ``S - 1 - capture[1]``) is returned, the seed of the next
window. The seed enters where the window's cost is that of the whole image (inside its
collar, away from the edge), so from there on its paths are the whole image's exactly.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from sswjax.stages.bands import align_band, band_deltas

__all__ = ["Seeds", "no_seeds", "scan_axis", "scan_band_axis", "seeded_scan_axis"]


class Seeds(NamedTuple):
    """Path states entering one window along its scanned axis, and where they enter and leave.

    ``forward``, ``backward``: one ``(D, N)`` line per path shift of the axis (in the order of
    the scan's ``shifts``), of the paths' dtype; ``entry``: int32 ``(2,)``, the steps of the
    forward and the backward loop before which the seeds replace the state (0 with zero lines:
    no neighbour, the border's fresh start); ``capture``: int32 ``(2,)``, the steps after which
    each direction's state is kept (a step before ``entry`` keeps the seed)."""

    forward: tuple
    backward: tuple
    entry: jax.Array
    capture: jax.Array


def no_seeds(line_shape: tuple[int, int], count: int, dtype) -> Seeds:
    """Zero seeds entering at step 0 and captures at step 0: the paths of a window as if it
    were the whole image (``count`` lines of ``line_shape`` (D, N) per direction)."""
    zeros = tuple(jnp.zeros(line_shape, dtype) for _ in range(count))
    return Seeds(zeros, zeros, jnp.zeros(2, jnp.int32), jnp.zeros(2, jnp.int32))


def _path_step(previous, cost, p1, p2, levels_step=None, delta=None):
    """One step of Eq. 13 for a line of pixels: ``previous``, ``cost`` (D, N); ``p1``, ``p2`` (N,).

    Float32 or int16 alike: the first and last disparities' missing neighbour is the disparity
    itself (edge-replicated), which ``+ p1`` can never make the minimum, so no sentinel such as
    ``inf`` (which int16 has not, and whose sum would overflow) is needed. A uint8 ``cost`` is
    widened to ``previous``'s dtype and multiplied by ``levels_step`` (int16 steps per level).

    ``delta`` (int32 (N,)): the lines are bands (:mod:`sswjax.stages.bands`) whose starts differ
    by ``delta`` from the predecessor's; its band is realigned to the pixel's disparities, and a
    disparity it did not search costs ``min + P2`` (reachable only by the jump).
    """
    if levels_step is not None:
        cost = cost.astype(previous.dtype) * levels_step
    lowest = previous.min(axis=0)
    if delta is None:
        below = jnp.concatenate([previous[:1], previous[:-1]])
        above = jnp.concatenate([previous[1:], previous[-1:]])
    else:
        aligned = align_band(previous, delta, lowest + p2)
        previous, below, above = aligned[1:-1], aligned[:-2], aligned[2:]
    best = jnp.minimum(jnp.minimum(previous, jnp.minimum(below, above) + p1), lowest + p2)
    return cost + best - lowest


def _shift_line(line: jax.Array, dx: int) -> jax.Array:
    """``out[:, x] = line[:, x - dx]`` with zeros shifted in (a path starting at the border)."""
    if dx == 0:
        return line
    zeros = jnp.zeros_like(line[:, :1])
    if dx > 0:
        return jnp.concatenate([zeros, line[:, :-1]], axis=1)
    return jnp.concatenate([line[:, 1:], zeros], axis=1)


def _axis_step(cost, penalties, shifts, *, reverse: bool, fresh: bool, levels_step):
    """The body of one direction's loop of :func:`scan_axis`: ``step(i, (lines, total))``
    advances the paths to line ``i`` (``S - 1 - i`` backward) and adds them into ``total``
    (written without reading it when ``fresh``)."""
    steps = cost.shape[1]
    pens = {shift: penalties[(not reverse, shift)] for shift in shifts}

    def step(i, state):
        lines, total = state
        s = steps - 1 - i if reverse else i
        line_cost = lax.dynamic_index_in_dim(cost, s, axis=1, keepdims=False)
        partial = None if fresh else lax.dynamic_index_in_dim(total, s, axis=1, keepdims=False)
        new = []
        for k, shift in enumerate(shifts):
            p1, p2 = (lax.dynamic_index_in_dim(m, s, keepdims=False) for m in pens[shift])
            line = _path_step(_shift_line(lines[k], -shift if reverse else shift),
                              line_cost, p1, p2, levels_step)
            new.append(line)
            partial = line if partial is None else partial + line
        return tuple(new), lax.dynamic_update_index_in_dim(total, partial, s, axis=1)

    return step


def _zero_total(cost, total, dtype):
    """``total``, or a zero sum of the volume's shape in ``dtype`` (default the cost's)."""
    if total is not None:
        return total
    return jnp.zeros(cost.shape, cost.dtype if dtype is None else dtype)


def scan_axis(cost: jax.Array, penalties: dict, shifts: tuple[int, ...], total: jax.Array | None,
              *, levels_step=None, dtype=None) -> jax.Array:
    """``total`` plus the paths along axis 1 of ``cost`` (D, S, N), forward then backward.

    ``total`` None: the sum of these paths alone, in ``dtype`` (the forward loop writes its
    lines without reading a zero sum). ``levels_step``: see :func:`_path_step`.

    ``shifts`` are the per-step shifts along N of the paths (0 straight, +-1 diagonal);
    ``penalties[(forward, shift)]`` are their (P1, P2) maps, (S, N) each. A line is the (D, N)
    slice at one step: D runs of N contiguous values, read without transposing the volume.
    Each step reads the line of ``total`` it reaches, adds its paths and writes it back in
    place (a loop-carried buffer that XLA updates without copying), so the sum of every path of
    both axes needs one volume besides the inputs.
    """
    fresh = total is None
    total = _zero_total(cost, total, dtype)
    for reverse in (False, True):
        step = _axis_step(cost, penalties, shifts, reverse=reverse,
                          fresh=fresh and not reverse, levels_step=levels_step)
        start = tuple(jnp.zeros(cost[:, 0].shape, total.dtype) for _ in shifts)
        total = lax.fori_loop(0, cost.shape[1], step, (start, total))[1]
    return total


def seeded_scan_axis(cost: jax.Array, penalties: dict, shifts: tuple[int, ...],
                     total: jax.Array | None, seeds: Seeds, *, levels_step=None,
                     dtype=None) -> tuple[jax.Array, Seeds]:
    """:func:`scan_axis` with its paths carried in from neighbouring windows (module docstring).

    Each direction runs three loops with the same body: from the zero line up to its
    ``entry``, from the seed up to its ``capture`` (at least to ``entry``), and on to the
    end. With :func:`no_seeds` the sums are :func:`scan_axis`'s.

    Parameters
    ----------
    cost, penalties, shifts, total, levels_step, dtype
        As for :func:`scan_axis`.
    seeds : Seeds
        Lines of the paths' dtype (``total``'s, or ``dtype``), one per shift and direction.

    Returns
    -------
    (sums, captured)
        The sums as :func:`scan_axis`'s, the window's paths seeded; ``captured`` the
        :class:`Seeds` with each direction's state after its capture step (``entry`` and
        ``capture`` as given).
    """
    fresh = total is None
    total = _zero_total(cost, total, dtype)
    steps = cost.shape[1]
    kept = []
    for k, reverse in enumerate((False, True)):
        step = _axis_step(cost, penalties, shifts, reverse=reverse,
                          fresh=fresh and not reverse, levels_step=levels_step)
        entry = jnp.clip(seeds.entry[k], 0, steps)
        stop = jnp.clip(jnp.maximum(seeds.capture[k] + 1, entry), 0, steps)
        start = tuple(jnp.zeros(cost[:, 0].shape, total.dtype) for _ in shifts)
        _, total = lax.fori_loop(0, entry, step, (start, total))
        lines = tuple(line.astype(total.dtype) for line in (seeds.backward if reverse
                                                              else seeds.forward))
        lines, total = lax.fori_loop(entry, stop, step, (lines, total))
        kept.append(lines)
        _, total = lax.fori_loop(stop, steps, step, (lines, total))
    return total, seeds._replace(forward=kept[0], backward=kept[1])


def scan_band_axis(cost: jax.Array, penalties: dict, shifts: tuple[int, ...],
                    total: jax.Array | None, starts: jax.Array, *, levels_step=None,
                    dtype=None) -> jax.Array:
    """:func:`scan_axis` of a band volume ``cost`` (K, S, N) with first disparities
    ``starts`` (int32 (S, N)): each step realigns the predecessor's band
    (:func:`~sswjax.stages.bands.band_deltas`).

    A band's lines are small, and on XLA CPU each iteration of a loop has a fixed cost that they
    do not hide: step ``i`` advances the forward paths to line ``i`` and the backward ones to
    line ``S - 1 - i``, side by side in lines of 2N, in half the iterations; each direction
    writes into a buffer of its own (one in-place update per buffer and step), added to
    ``total`` at the end. (Reversing the volume instead, ``jnp.flip``, cost more than the
    paths.)
    """
    steps, size = cost.shape[1:]

    def paired(forward_map, backward_map):  # (S, N) maps, the backward one read reversed
        return jnp.concatenate([forward_map, backward_map[::-1]], axis=-1)

    pens = {shift: tuple(paired(a, b) for a, b in zip(penalties[(True, shift)],
                                                       penalties[(False, shift)]))
            for shift in shifts}
    deltas = {shift: paired(band_deltas(starts, shift, True),
                            band_deltas(starts, -shift, False)) for shift in shifts}
    sum_dtype = (cost.dtype if dtype is None else dtype) if total is None else total.dtype

    def along(line, shift):
        # The forward half steps by +shift along N, the backward half by -shift.
        return jnp.concatenate([_shift_line(line[:, :size], shift),
                                _shift_line(line[:, size:], -shift)], axis=1)

    def step(i, state):
        lines, forward, backward = state
        back = steps - 1 - i
        line_cost = jnp.concatenate([lax.dynamic_index_in_dim(cost, i, axis=1, keepdims=False),
                                     lax.dynamic_index_in_dim(cost, back, axis=1,
                                                              keepdims=False)], axis=1)
        partial = None
        new = []
        for k, shift in enumerate(shifts):
            p1, p2 = (lax.dynamic_index_in_dim(m, i, keepdims=False) for m in pens[shift])
            delta = lax.dynamic_index_in_dim(deltas[shift], i, keepdims=False)
            line = _path_step(along(lines[k], shift), line_cost, p1, p2, levels_step, delta)
            new.append(line)
            partial = line if partial is None else partial + line
        forward = lax.dynamic_update_index_in_dim(forward, partial[:, :size], i, axis=1)
        backward = lax.dynamic_update_index_in_dim(backward, partial[:, size:], back, axis=1)
        return tuple(new), forward, backward

    start = tuple(jnp.zeros((cost.shape[0], 2 * size), sum_dtype) for _ in shifts)
    buffers = (jnp.zeros(cost.shape, sum_dtype), jnp.zeros(cost.shape, sum_dtype))
    _, forward, backward = lax.fori_loop(0, steps, step, (start, *buffers))
    result = forward + backward
    return result if total is None else total + result
