"""The vertical alignment, a step before the method: a first pass on the pair halved, the offset
measured on the cost at its map at that level, the full-resolution right image moved
(:func:`align_right`); the method then matches the left image with the moved right one.

Array conventions: images float32 ``(H, W, C)`` in [0, 1]; maps float32 ``(H, W)`` in pixels;
coefficients float32 ``(3,)``, or ``(3 + tiles * tiles,)`` with the 'grid' model
(:meth:`sswjax.config.VerticalAlignment.coefficients`).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from sswjax.config import Params
from sswjax.graph.coarse import halved_pair
from sswjax.graph.match import (DEFAULT_CHUNK, check_pair, match_maps, ssw_cues, ssw_disparity,
                                ssw_outputs)
from sswjax.graph.padding import padding_as_edge
from sswjax.graph.scopes import Stage, scope
from sswjax.graph.volume import cost_features
from sswjax.stages.alignment import shift_rows

__all__ = ["METHODS", "align_right", "alignment_coefficients", "halved_levels", "ssw_aligned"]

METHODS = {"ssw_disparity": ssw_disparity, "ssw_outputs": ssw_outputs, "ssw_cues": ssw_cues}
"""The methods :func:`ssw_aligned` runs after the alignment, by name."""

# Columns from the left edge whose cost is left out: their census window reaches past the
# right image's edge at small disparities.
_EDGE = 4


def alignment_coefficients(left: jax.Array, right: jax.Array, params: Params,
                           disparity: jax.Array, rejected: jax.Array, *, limit, scale: int = 1,
                           valid_shape=None) -> jax.Array:
    """The coefficients of ``params.alignment``'s offset model, measured at ``disparity``.

    For each candidate offset the two images are moved apart by it (each by half) and the cost
    of Eq. (5) of every left pixel at its rounded disparity gathered
    (:meth:`~sswjax.config.MatchingCost.at`); the pixels the first pass's checks ``rejected``,
    those within a few columns of the left edge or whose match falls outside the right image,
    and a bucket's padding do not count.

    Parameters
    ----------
    left, right : float32 (H, W, C)
        The pair at the level of ``disparity`` (``scale`` times coarser than the pair whose
        offset is wanted).
    params : Params
        With ``alignment`` set.
    disparity : float32 (H, W)
        The first pass's map.
    rejected : bool (H, W)
        Pixels whose first-pass disparity was filled in.
    limit : int or int32 scalar
        Disparities are ``0 .. limit - 1``.
    scale : int
        ``2 ** levels``: the coefficients are returned in the full pair's pixels.
    valid_shape : int32 (2,), optional
        The pair's own ``(H, W)`` within a bucket's padding, at this level.

    Returns
    -------
    float32 (3,) or (3 + tiles * tiles,)
        :meth:`~sswjax.config.VerticalAlignment.coefficients`.
    """
    alignment = params.alignment
    height, width = disparity.shape
    rounded = jnp.clip(jnp.round(disparity), 0, limit - 1).astype(jnp.int32)
    columns = jnp.arange(width)[None, :]
    valid = ~rejected & (columns - rounded >= _EDGE) & (columns >= _EDGE)
    if valid_shape is not None:
        valid &= (jnp.arange(height)[:, None] < valid_shape[0]) & (columns < valid_shape[1])

    def candidate_cost(offset):
        # Each image moved by half the offset, in opposite directions: both are then read
        # between their rows alike (the linear interpolation's blur the same on both sides,
        # where moving the right image alone favours the offsets of whole rows).
        half = jnp.full((height, width), offset / 2)
        features = cost_features(shift_rows(left, -half), shift_rows(right, half), params,
                                 valid_shape=valid_shape)
        # The features written before the gather reads them: fused into it, XLA computed them
        # again for each of its reads (the measure on Motorcycle halved: 40 -> 22 ms, the
        # same costs to the bit).
        return params.cost.at(jax.lax.optimization_barrier(features), rounded)

    # A loop over the candidates: one cost plane alive at a time besides the stack.
    costs = jax.lax.map(candidate_cost, alignment.offsets(scale))
    return alignment.coefficients(costs, valid, scale=scale, size=valid_shape)


def halved_levels(left: jax.Array, right: jax.Array, ndisp: int, valid_ndisp, levels: int, *,
                  valid_shape=None):
    """:func:`~sswjax.graph.coarse.halved_pair` ``levels`` times: ``(left, right, ndisp,
    valid_ndisp, valid_shape)`` of the pair halved so."""
    level = (left, right, ndisp, valid_ndisp, valid_shape)
    for _ in range(levels):
        level = halved_pair(*level[:4], valid_shape=level[4])
    return level


@functools.partial(jax.jit, static_argnames=("ndisp", "chunk"))
def align_right(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int,
                valid_ndisp=None, chunk: int = DEFAULT_CHUNK,
                valid_shape=None) -> tuple[jax.Array, jax.Array]:
    """The right image with its rows moved onto the left's, and the model's coefficients: the
    step ``params.alignment`` runs before the method, as one jitted pure function.

    The first pass (``params.alignment.first_pass(params)``,
    :func:`~sswjax.graph.match.match_maps`) runs on the pair halved ``params.alignment.levels``
    times; its map and the pixels its checks rejected give :func:`alignment_coefficients` at
    that level, and the right image is moved by them at full resolution. A pair too small for
    a tile to be measured (:meth:`~sswjax.config.VerticalAlignment.measurable`) has an offset
    of 0: its right image comes back as it is, the coefficients 0, and no first pass is
    compiled. The method then runs on ``(left, moved)`` with ``params.replace(alignment=None)``
    (:func:`~sswjax.graph.ssw_disparity`'s docstring shows both under ``jax.vmap``).

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    params : Params
        With ``alignment`` set.
    ndisp, valid_ndisp, chunk, valid_shape
        As for :func:`~sswjax.graph.ssw_disparity` (``ndisp`` and ``chunk`` static).

    Returns
    -------
    (float32 (H, W, C), float32 (3,) or (3 + tiles * tiles,))
        The moved right image and the coefficients
        (:meth:`~sswjax.config.VerticalAlignment.coefficients`).
    """
    check_pair(left, right, ndisp)
    alignment = params.alignment
    if alignment is None:
        raise ValueError("align_right needs params.alignment (a VerticalAlignment)")
    if not alignment.measurable(left.shape[:2]):
        size = 3 if alignment.model == "plane" else 3 + alignment.tiles ** 2
        return right, jnp.zeros((size,), jnp.float32)
    # The whole stage under one scope, the first pass's own stages nested in it: a profile
    # that counts each operation under its outermost stage counts the first pass here.
    with scope(Stage.ALIGNMENT):
        small_left, small_right, small_ndisp, small_valid, small_shape = halved_levels(
            left, right, ndisp, valid_ndisp, alignment.levels, valid_shape=valid_shape)
        disparity, cues, _ = match_maps(small_left, small_right, alignment.first_pass(params),
                                        small_ndisp, small_valid, chunk,
                                        valid_shape=small_shape)
        coefficients = alignment_coefficients(
            small_left, small_right, params, padding_as_edge(disparity, small_shape),
            cues.lr_failed, limit=small_ndisp if small_valid is None else small_valid,
            scale=2 ** alignment.levels, valid_shape=small_shape)
        return alignment.apply(right, coefficients, size=valid_shape), coefficients


@functools.partial(jax.jit, static_argnames=("method", "ndisp", "chunk", "options"))
def ssw_aligned(left: jax.Array, right: jax.Array, params: Params, *, method: str, ndisp: int,
                valid_ndisp=None, chunk: int = DEFAULT_CHUNK, valid_shape=None,
                options: tuple = ()):
    """:func:`align_right`, then the method ``METHODS[method]`` on ``left`` and the moved right
    image with ``params.replace(alignment=None)``, in one program: how a pair matched whole
    runs. (Compiled apart, the two can compute differently: on Middlebury 2001's Sawtooth
    padded to its shape bucket, 0.11 % of ``accurate``'s disparities moved, by up to 4e-4 px.)

    Parameters
    ----------
    left, right, params, ndisp, valid_ndisp, chunk, valid_shape
        As for :func:`align_right`.
    method : str
        A key of :data:`METHODS` (static).
    options : tuple of (str, object)
        More static keyword arguments of the method (``(("measure", "pkrn"),)``).

    Returns
    -------
    What the method returns.
    """
    call = {"ndisp": ndisp, "valid_ndisp": valid_ndisp, "chunk": chunk,
            "valid_shape": valid_shape}
    moved, _ = align_right(left, right, params, **call)
    return METHODS[method](left, moved, params.replace(alignment=None), **call, **dict(options))
