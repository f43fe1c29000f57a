"""Edge-aware smoothing of a finished disparity map: a joint bilateral mean gated by disparity.

Array conventions (whole module): disparity maps float32 ``(H, W)`` in pixels; guides float32
``(H, W, C)`` with C in {1, 3}, values in [0, 1]. Borders are edge-replicated.

Why: the semi-global map is piecewise flat on the integer grid. Its sub-pixel values come from
a parabola through three integer costs (Eq. 8), which on census-heavy costs locks to the
integers, and its windows are fronto-parallel, so on a slanted surface the disparity steps
where it should ramp. Both errors are below a pixel: they count at bad 0.5 and 1.0, not at 2.0.
Averaging each pixel's disparity with its neighbours' on the same surface turns the steps back
into the ramp, and where the neighbours lie on the surface, the mean is the surface's value
between grid points. "Same surface" is decided twice: by the colour (the range weight of the
joint bilateral filter, Petschnigg et al. 2004, Kopf et al. 2007, with the left image as the
guide) and by the disparity itself (a neighbour more than ``gate`` pixels away is on another
surface and has no weight), so depth edges are not blurred even where both sides share a
colour. Measured in ``docs/notes/precision.md``.

Tilted (``tilted=True``): on a slanted surface a neighbour ``k`` pixels away lies ``k`` times
the slope away in disparity, and a gate measured from the pixel's own disparity drops the far
neighbours of a steep surface (a road seen from a car) and keeps the near ones, unevenly where
the colour weights are. Tilted, the gate is measured from the line through the pixel along the
map's own slope there, as the trilateral filter tilts the bilateral filter's window along the
signal's gradient (Choudhury and Tumblin, "The Trilateral Filter for High Contrast Images and
Meshes", EGSR 2003, Sec. 4). The slope along an axis is read from the window's two ends
(:func:`_slope`); where the two halves disagree by ``gate`` or more (a depth edge, not a slope)
or it exceeds one pixel per pixel, it is 0: the untilted gate. The mean itself is the
neighbours' disparities as before: on a slanted surface whose neighbours all pass, their mean
is the surface's value at the pixel.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax._checks import check_guide, check_map, check_rank
from sswjax.stages.buffers import written_once
from sswjax.stages.filters import edge_pad
from sswjax.stages.loops import repeated

__all__ = ["gated_bilateral_line_mean", "gated_bilateral_mean", "gated_bilateral_smoothing",
           "line_colour_weights"]


def gated_bilateral_mean(disparity: jax.Array, guide: jax.Array, *, radius: int, gate,
                         colour_scale, tilted: bool = False) -> jax.Array:
    """The mean of each pixel's neighbours' disparities, weighted by colour and gated by
    disparity.

    ``out(p) = sum_q w(p, q) d(q) / sum_q w(p, q)`` over the ``(2 radius + 1)^2`` window of
    ``p``, with ``w(p, q) = exp(-sum_c |I_c(q) - I_c(p)| / colour_scale)`` where
    ``|d(q) - d(p)| < gate``, else 0 (``p`` itself always weighs 1). ``tilted``: where
    ``|d(q) - d(p) - (q - p) . s(p)| < gate`` instead, ``s(p)`` the map's slope along the rows
    and the columns at ``p`` (:func:`_slope`; module docstring).

    Parameters
    ----------
    disparity : float32 (H, W), finite
    guide : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    radius : int >= 1
    gate : float > 0
        Largest disparity difference (pixels) of a neighbour that is averaged.
    colour_scale : float > 0
        Scale of the colour weight (sum of absolute channel differences).
    tilted : bool
        Measure the gate from the map's local slope through ``p`` (module docstring).

    Returns
    -------
    float32 (H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> steps = jnp.repeat(jnp.arange(4.0), 2)[None].repeat(3, 0)   # a staircase of 1 px steps
    >>> guide = jnp.zeros((3, 8, 1))
    >>> out = gated_bilateral_mean(steps, guide, radius=1, gate=1.5, colour_scale=0.1)
    >>> [round(v, 2) for v in out[1].tolist()]                      # ... becomes a ramp
    [0.0, 0.33, 0.67, 1.33, 1.67, 2.33, 2.67, 3.0]
    """
    return _gated_mean(disparity, guide, radius=radius, gate=gate, colour_scale=colour_scale,
                       offsets=[(dy, dx) for dy in range(-radius, radius + 1)
                                for dx in range(-radius, radius + 1)], tilted=tilted)


def gated_bilateral_line_mean(disparity: jax.Array, guide: jax.Array, *, radius: int, gate,
                              colour_scale, axis: int, tilted: bool = False) -> jax.Array:
    """:func:`gated_bilateral_mean` over a line of ``2 radius + 1`` pixels along ``axis`` (0:
    a column, 1: a row) instead of the square window.

    A pass along the rows then one along the columns is the separable approximation of the
    square window (Pham and van Vliet, "Separable bilateral filtering for fast video
    preprocessing", ICME 2005): ``2 (2 radius + 1)`` weights per pixel instead of
    ``(2 radius + 1)^2``, 3.5x fewer at radius 3. It is not the square window's result: the
    column pass averages row means, so a neighbour on the diagonal counts through the pixel in
    its row, with the colour weight of that pixel.

    Takes float32 ``disparity`` (H, W) and ``guide`` (H, W, C) and ``radius``, ``gate`` and
    ``colour_scale`` as :func:`gated_bilateral_mean`, ``axis`` (0 or 1) and ``tilted`` (the
    gate measured from the map's slope along ``axis``); returns float32 (H, W).

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> steps = jnp.repeat(jnp.arange(4.0), 2)[None].repeat(3, 0)
    >>> out = gated_bilateral_line_mean(steps, jnp.zeros((3, 8, 1)), radius=1, gate=1.5,
    ...                                 colour_scale=0.1, axis=1)
    >>> [round(v, 2) for v in out[1].tolist()]   # the same ramp: the steps lie along the rows
    [0.0, 0.33, 0.67, 1.33, 1.67, 2.33, 2.67, 3.0]
    """
    _check_inputs(disparity, guide, radius)
    weights = line_colour_weights(guide, radius=radius, colour_scale=colour_scale, axis=axis)
    return _gated_line_mean(disparity, weights, gate=gate, axis=axis, tilted=tilted)


def line_colour_weights(guide: jax.Array, *, radius: int, colour_scale, axis: int
                        ) -> tuple[jax.Array, ...]:
    """The colour weights of :func:`gated_bilateral_line_mean` along ``axis``, once for every
    pass over the same guide.

    The weight is symmetric, ``w(p, p + k) = w(p + k, p)``, so offset ``k`` and ``-k`` share one
    plane: plane ``k - 1`` (k = 1 .. radius) holds ``exp(-sum_c |I_c(q + k) - I_c(q)| /
    colour_scale)`` for every ``q`` of the guide edge-padded by ``radius``, ``q + k`` taken along
    ``axis``; pixel ``p`` reads it at ``p`` for ``+k`` and at ``p - k`` for ``-k``.

    Takes float32 ``guide`` (H, W, C) with C in {1, 3}, ``radius`` >= 1, ``colour_scale`` > 0
    and ``axis`` (0 or 1); returns ``radius`` float32 planes, ``(H + 2 radius - k, W)`` along
    the columns (axis 0) or ``(H, W + 2 radius - k)`` along the rows: the guide is padded along
    ``axis`` only (:func:`_line_pad`).
    """
    if axis not in (0, 1):
        raise ValueError(f"axis must be 0 or 1, got {axis}")
    check_rank("guide", guide, 3)
    # Channels first, one plane each: a sum over a trailing channel axis ran 15x slower on XLA
    # CPU (as in stages.cost).
    padded = _line_pad(jnp.moveaxis(guide, -1, 0), radius, axis=1 + axis)
    scale = -1.0 / jnp.asarray(colour_scale, jnp.float32)
    size = padded.shape[1 + axis]
    planes = []
    for k in range(1, radius + 1):
        ahead = jax.lax.slice_in_dim(padded, k, size, axis=1 + axis)
        here = jax.lax.slice_in_dim(padded, 0, size - k, axis=1 + axis)
        difference = sum(jnp.abs(ahead[c] - here[c]) for c in range(padded.shape[0]))
        planes.append(jnp.exp(difference * scale))
    return tuple(planes)


def gated_bilateral_smoothing(disparity: jax.Array, guide: jax.Array, *, radius: int, gate,
                              colour_scale, iterations: int, separable: bool,
                              tilted: bool = False) -> jax.Array:
    """``iterations`` passes of :func:`gated_bilateral_mean`, or of a row then a column of
    :func:`gated_bilateral_line_mean` each when ``separable``.

    Takes float32 ``disparity`` (H, W) and ``guide`` (H, W, C) and ``radius``, ``gate`` and
    ``colour_scale`` as :func:`gated_bilateral_mean`, ``iterations`` >= 1, ``tilted`` as
    there (each pass reads the slope of the map it smooths); returns float32 (H, W), the
    passes' result exactly.

    The map is written to a buffer once, before the first pass
    (:func:`~sswjax.stages.buffers.written_once`): XLA CPU fuses the stage before (the side-window
    median's sorting networks) into the edge padding of the first pass, whose concatenation it
    runs element by element; with the map in a buffer first, ``accurate``'s whole graph took
    15 % less on trainingQ Motorcycle and Teddy (docs/notes/speed-and-memory.md); an
    ``optimization_barrier`` does not survive XLA CPU's fusion passes. The row pass's result
    needs no buffer of its own: its exponentials are not fused into the column pass's readers
    (a buffer after every pass cost ``fast``, 6 passes, about 10 % of its whole call on
    Motorcycle and Teddy, docs/notes/speed.md). Two or more iterations are one loop of the graph
    (:func:`~sswjax.stages.loops.repeated`: compiled once), whose carry is a buffer per
    iteration: the same warm time for ``accurate`` and ``fast`` (docs/notes/speed-and-memory.md).
    The separable passes read the colour weights of
    :func:`line_colour_weights`, computed once for all of them (the guide does not change from
    pass to pass): the same result, bit for bit.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> steps = jnp.repeat(jnp.arange(4.0), 2)[None].repeat(3, 0)
    >>> out = gated_bilateral_smoothing(steps, jnp.zeros((3, 8, 1)), radius=1, gate=1.5,
    ...                                 colour_scale=0.1, iterations=1, separable=False)
    >>> [round(v, 2) for v in out[1].tolist()]
    [0.0, 0.33, 0.67, 1.33, 1.67, 2.33, 2.67, 3.0]
    """
    disparity = written_once(disparity)
    if not separable:
        return repeated(lambda d: gated_bilateral_mean(
            d, guide, radius=radius, gate=gate, colour_scale=colour_scale, tilted=tilted),
            disparity, times=iterations)
    _check_inputs(disparity, guide, radius)
    weights = {axis: line_colour_weights(guide, radius=radius, colour_scale=colour_scale,
                                         axis=axis) for axis in (1, 0)}

    def row_then_column(d):
        for axis in (1, 0):
            d = _gated_line_mean(d, weights[axis], gate=gate, axis=axis, tilted=tilted)
        return d
    return repeated(row_then_column, disparity, times=iterations)


def _gated_mean(disparity, guide, *, radius, gate, colour_scale, offsets, tilted) -> jax.Array:
    """The gated, colour-weighted mean over the window ``offsets`` ``(dy, dx)``, each within
    ``radius``; shapes as :func:`gated_bilateral_mean`."""
    _check_inputs(disparity, guide, radius)
    height, width = disparity.shape
    disparities = edge_pad(disparity, radius)

    def window(plane, dy, dx):    # the (H, W) window at offset (dy, dx) of a padded plane
        return plane[..., radius + dy:radius + dy + height, radius + dx:radius + dx + width]
    if tilted:
        slope_y = _slope(lambda k: window(disparities, k, 0), disparity, span=radius, gate=gate)
        slope_x = _slope(lambda k: window(disparities, 0, k), disparity, span=radius, gate=gate)
    # Channels first, one plane each: a sum over a trailing channel axis ran 15x slower on XLA
    # CPU (as in stages.cost).
    planes = jnp.moveaxis(guide, -1, 0)
    padded = edge_pad(planes, radius)
    scale = -1.0 / jnp.asarray(colour_scale, jnp.float32)
    total = jnp.zeros_like(disparity)
    weights = jnp.zeros_like(disparity)
    # One shifted window per offset: elementwise passes that XLA fuses into one loop.
    for dy, dx in offsets:
        near = window(disparities, dy, dx)
        difference = sum(jnp.abs(window(padded[c], dy, dx) - planes[c])
                         for c in range(planes.shape[0]))
        expected = disparity + dy * slope_y + dx * slope_x if tilted else disparity
        weight = jnp.where(jnp.abs(near - expected) < gate, jnp.exp(difference * scale), 0.0)
        total += weight * near
        weights += weight
    return total / weights


def _gated_line_mean(disparity, weights, *, gate, axis: int, tilted: bool) -> jax.Array:
    """:func:`gated_bilateral_line_mean` with the colour weights of
    :func:`line_colour_weights` (its ``radius`` planes); ``disparity`` float32 (H, W) in and
    out, checked by the caller (:func:`_check_inputs`). The offsets are summed in the order
    -r .. r, as :func:`_gated_mean` sums them."""
    radius = len(weights)
    disparities = _line_pad(disparity, radius, axis=axis)

    def window(plane, start):     # the (H, W) window of a plane padded along axis
        return jax.lax.slice_in_dim(plane, start, start + disparity.shape[axis], axis=axis)

    if tilted:
        slope = _slope(lambda k: window(disparities, radius + k), disparity, span=radius,
                       gate=gate)
    total = jnp.zeros_like(disparity)
    norm = jnp.zeros_like(disparity)
    for k in range(-radius, radius + 1):
        near = window(disparities, radius + k)
        colour = 1.0 if k == 0 else window(weights[abs(k) - 1], radius + min(k, 0))
        expected = disparity + k * slope if tilted else disparity
        weight = jnp.where(jnp.abs(near - expected) < gate, colour, 0.0)
        total += weight * near
        norm += weight
    return total / norm


def _slope(near, disparity, *, span: int, gate) -> jax.Array:
    """The map's slope along one axis at each pixel, in pixels of disparity per pixel, from the
    window's ends: ``(d(p + span) - d(p - span)) / (2 span)`` where the two halves, ``d(p +
    span) - d(p)`` and ``d(p) - d(p - span)``, differ by less than ``gate`` (one surface through
    ``p``, not an edge beside it) and the slope is at most 1; 0 elsewhere.

    ``near(k)`` is the map at offset ``k`` along the axis (edge-replicated), float32 (H, W) like
    ``disparity``; returns float32 (H, W).
    """
    ahead = near(span) - disparity
    behind = disparity - near(-span)
    one_surface = (jnp.abs(ahead - behind) < gate) & (jnp.abs(ahead + behind) <= 2 * span)
    return jnp.where(one_surface, (ahead + behind) / (2 * span), 0.0)


def _line_pad(x: jax.Array, radius: int, *, axis: int) -> jax.Array:
    """``x`` edge-replicated by ``radius`` samples at both ends of ``axis`` only: a line pass
    reads no neighbour across the other axis, and each padded sample is a buffer to write
    (XLA CPU writes a padding's concatenation element by element)."""
    widths = [(0, 0)] * x.ndim
    widths[axis] = (radius, radius)
    return jnp.pad(x, widths, mode="edge")


def _check_inputs(disparity, guide, radius: int) -> None:
    """The checks at every entry of the module: a (H, W) map at least ``radius`` wide (finite)
    and a (H, W, C) guide of its size."""
    check_rank("disparity", disparity, 2)
    check_map("disparity", disparity, radius)
    check_rank("guide", guide, 3)
    check_guide(guide, disparity)
