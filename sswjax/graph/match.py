"""The jitted graph: the stages of :mod:`sswjax.stages` composed into the SSW method.

Array conventions (whole module): the pure functions take images float32 ``(H, W, C)`` with
C in {1, 3} and values in [0, 1], a :class:`~sswjax.config.Params` pytree, a static ``ndisp``
and a static ``chunk`` (disparities per block of the volume's scans, an execution choice that
does not change the result); they return float32 ``(H, W)`` disparities in pixels, dense, in
[0, ndisp - 1]. The NumPy front door (validation, conversion, shape buckets, strips) is
:mod:`sswjax.api`.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax

from sswjax._checks import check_floating, check_positive_int, check_rank, check_same_shape
from sswjax.config import Params
from sswjax.graph.band import match_band
from sswjax.graph.coarse import match_coarse_to_fine
from sswjax.graph.refine import refine
from sswjax.graph.padding import padding_as_edge
from sswjax.graph.scopes import Stage, scope
from sswjax.graph.volume import (Selected, aggregate_slices, optimised_volume, prepare_scene,
                                 select_optimised, streamed_winners)
from sswjax.stages.confidence import DEFAULT_MEASURE, ConfidenceCues, ambiguous, confidence
from sswjax.stages.paths import Seeds

__all__ = ["DEFAULT_CHUNK", "SSWOutputs", "aggregated_cost", "carries_paths", "check_carried",
           "check_pair", "check_unaligned", "match_maps", "ssw_carried", "ssw_cues",
           "ssw_disparity", "ssw_disparity_seeded", "ssw_outputs", "ssw_outputs_seeded"]

DEFAULT_CHUNK = 4
"""Disparities per block of the volume's scans: memory for about ``3 K`` slices instead of the
volume; K = 4 was fastest on XLA CPU (2x faster than the whole volume: the blocks stay in
cache)."""


def check_pair(left, right, ndisp: int) -> None:
    """Entry checks of the graph: float (H, W, C) images of one shape, C in {1, 3}, and
    ``1 <= ndisp < W``."""
    check_rank("left", left, 3)
    check_floating("left", left)
    check_same_shape("left", left, "right", right)
    if left.shape[-1] not in (1, 3):
        raise ValueError(f"images must have 1 or 3 channels, got shape {tuple(left.shape)}")
    check_positive_int("ndisp", ndisp)
    if ndisp >= left.shape[1]:
        raise ValueError(f"ndisp must be smaller than the image width {left.shape[1]}, got {ndisp}")


def aggregated_cost(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int) -> jax.Array:
    """Eq. (5)-(7) of the pair as given: matching cost, superpixels and aggregation.

    The whole volume at once, before any optimiser (for analyses).

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    params : Params
    ndisp : int, 1 <= ndisp < W

    Returns
    -------
    float32 (ndisp, H, W), lower is better.
    """
    check_pair(left, right, ndisp)
    return aggregate_slices(prepare_scene(left, right, params), params, 0, ndisp)


def match_maps(left, right, params: Params, ndisp: int, valid_ndisp, chunk: int, *,
               valid_shape=None, seeds=None) -> tuple[jax.Array, ConfidenceCues, object]:
    """The body of :func:`ssw_disparity`: the map, its confidence cues and, with ``seeds``
    (:class:`~sswjax.stages.paths.Seeds`), the paths' states for the neighbouring windows
    (else None).

    The pair is matched as it is: ``params.alignment`` is a step before the method
    (:func:`sswjax.graph.alignment.align_right`), refused here (:func:`check_unaligned`).
    Three ways through the volume: coarse-to-fine recurses on the halved pair; with an
    optimiser the volume is stored, optimised and folded; without one each block is folded
    as soon as it is aggregated. With a band, the method then runs again over a few
    disparities around that map (:mod:`sswjax.graph.band`). Seeds carry the paths of the
    second way only (:func:`check_carried`).
    """
    check_pair(left, right, ndisp)
    if seeds is not None:
        check_carried(params)
    limit = ndisp if valid_ndisp is None else valid_ndisp
    check_unaligned(params)
    scene = carried = None
    if params.coarse is not None:
        inner = functools.partial(match_maps, chunk=chunk)
        # The smoothing acts once, on the full-resolution map; the band at every level that
        # has a coarser one below it.
        band = params.band if params.coarse.levels > 1 else None
        disparity, cues = match_coarse_to_fine(left, right,
                                               params.replace(smoothing=None, band=band),
                                               ndisp, valid_ndisp, inner, valid_shape=valid_shape)
    else:
        scene = prepare_scene(left, right, params, valid_shape=valid_shape)
        if params.optimizer is None:
            selected = Selected(streamed_winners(scene, params, ndisp=ndisp, limit=limit,
                                                 chunk=chunk))
        else:
            selected = select_optimised(scene, params, ndisp=ndisp, valid_ndisp=valid_ndisp,
                                        chunk=chunk, seeds=seeds)
        carried = selected.carried
        disparity, cues = refine(selected, scene, params, limit)
    # The band and the smoothing filter the map: each reads it with a bucket's padding holding
    # the edge, as at the pair's own size (a coarser level's caller copies the edge itself).
    if params.band is not None:
        # Again over a few disparities around that map, at this resolution.
        disparity, cues = match_band(left, right, params, padding_as_edge(disparity, valid_shape),
                                     ndisp=ndisp, limit=limit, scene=scene,
                                     valid_shape=valid_shape)
    if params.smoothing is not None:
        with scope(Stage.SMOOTHING):
            disparity = params.smoothing.smooth(padding_as_edge(disparity, valid_shape), left,
                                                limit)
    return disparity, cues, carried


def check_unaligned(params: Params) -> None:
    """Raise ``ValueError`` (one line) when ``params`` set the vertical alignment, which runs
    before the method, not in it."""
    if params.alignment is not None:
        raise ValueError("params.alignment is a step before the method: moved, _ = "
                         "align_right(left, right, params, ndisp=N), then the method on "
                         "(left, moved) with params.replace(alignment=None)")


def carries_paths(params: Params) -> bool:
    """Whether windows of ``params``' method can carry the semi-global paths along the rows
    from one to the next (:mod:`sswjax.stages.paths`): a full-resolution volume (no
    coarse-to-fine, no band) optimised by an optimiser that ``carries_paths``."""
    return (params.coarse is None and params.band is None
            and params.optimizer is not None and params.optimizer.carries_paths)


def check_carried(params: Params) -> None:
    """Raise ``ValueError`` (one line) unless :func:`carries_paths`."""
    if not carries_paths(params):
        raise ValueError("seeds carry the semi-global paths of a full-resolution volume: this "
                         "method has no such optimiser, or runs coarse-to-fine or in a band")


@functools.partial(jax.jit, static_argnames=("ndisp", "chunk"))
def ssw_disparity(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int,
                  valid_ndisp=None, chunk: int = DEFAULT_CHUNK, valid_shape=None) -> jax.Array:
    """The whole SSW method as one jitted pure function.

    The static options of ``params`` and its choice of stages are pytree structure, so
    changing one (or the image size, ``ndisp`` or ``chunk``) recompiles; its traced options
    are traced. The vertical alignment (``params.alignment``, the ``accurate`` preset's) is a
    step before the method, :func:`~sswjax.graph.align_right`: the method refuses it, and runs
    on the aligned pair with ``params.replace(alignment=None)``. ``jax.vmap`` batches both
    over pairs of one size::

        def disparity(left, right):
            moved, _ = align_right(left, right, params, ndisp=n)
            return ssw_disparity(left, moved, params.replace(alignment=None), ndisp=n)

        jax.vmap(disparity)(lefts, rights)

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    params : Params
        Without ``alignment``.
    ndisp : int, 1 <= ndisp < W
        Size of the disparity volume (static: a new value recompiles).
    valid_ndisp : int32 scalar, optional
        Traced search range ``0 .. valid_ndisp - 1`` within the volume (default ``ndisp``):
        shape bucketing runs a padded ``ndisp`` and passes the true one here.
    chunk : int >= 0
        K > 0 (default :data:`DEFAULT_CHUNK`): disparities K at a time with a running minimum
        of both views, memory for a few ``(K, H, W)`` blocks; 0: the whole volume at once.
    valid_shape : int32 (2,), optional
        Traced height and width of the pair within images padded to a shape bucket (default:
        the whole images): the padding holds no evidence (its matching cost is the border
        value at every disparity).

    Returns
    -------
    float32 (H, W), dense disparities of the left view in pixels, in [0, valid_ndisp - 1].
    """
    return match_maps(left, right, params, ndisp, valid_ndisp, chunk,
                      valid_shape=valid_shape)[0]


@functools.partial(jax.jit, static_argnames=("ndisp", "chunk"))
def ssw_disparity_seeded(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int,
                         seeds: Seeds, valid_ndisp=None, chunk: int = DEFAULT_CHUNK,
                         valid_shape=None) -> tuple[jax.Array, Seeds]:
    """:func:`ssw_disparity` of a window of row strips whose semi-global paths along the rows
    enter from the windows above and below (``seeds``, :mod:`sswjax.stages.paths`,
    :func:`carries_paths`), and the :class:`Seeds` its paths leave for them.

    Returns
    -------
    (float32 (H, W), Seeds)
    """
    disparity, _, carried = match_maps(left, right, params, ndisp, valid_ndisp, chunk,
                                       valid_shape=valid_shape, seeds=seeds)
    return disparity, carried


class SSWOutputs(NamedTuple):
    """What :func:`ssw_outputs` returns, all ``(H, W)``: the dense disparity (float32, as
    :func:`ssw_disparity`), its confidence (float32 in [0, 1], higher = more reliable), the
    pixels the checks rejected and the fill filled (bool) and those whose cost has no distinct
    minimum (bool, :func:`sswjax.stages.confidence.ambiguous`)."""

    disparity: jax.Array
    confidence: jax.Array
    lr_failed: jax.Array
    ambiguous: jax.Array


# A stored graph's results are a pytree jax.export writes by this name (sswjax.runtime.stored).
jax.export.register_namedtuple_serialization(SSWOutputs, serialized_name="sswjax.SSWOutputs")
jax.export.register_namedtuple_serialization(Seeds, serialized_name="sswjax.Seeds")


def _outputs(disparity: jax.Array, cues: ConfidenceCues, measure: str) -> SSWOutputs:
    """The map and what :func:`ssw_outputs` gives besides it, from the cues."""
    return SSWOutputs(disparity, confidence(cues, disparity, measure=measure), cues.lr_failed,
                      ambiguous(cues))


@functools.partial(jax.jit, static_argnames=("ndisp", "chunk", "measure"))
def ssw_outputs(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int,
                valid_ndisp=None, chunk: int = DEFAULT_CHUNK, measure: str = DEFAULT_MEASURE,
                valid_shape=None) -> SSWOutputs:
    """:func:`ssw_disparity` with the confidence of each pixel, in one jitted graph.

    The same graph as :func:`ssw_disparity` (which keeps only the map; ``jit`` drops the rest)
    plus the confidence measure of :mod:`sswjax.stages.confidence` on the cues it gathers.

    Parameters
    ----------
    left, right, params, ndisp, valid_ndisp, chunk, valid_shape
        As for :func:`ssw_disparity`.
    measure : str
        A key of :data:`sswjax.stages.confidence.MEASURES` (static).

    Returns
    -------
    SSWOutputs
        float32 (H, W) disparity, float32 (H, W) confidence, bool (H, W) lr_failed, bool
        (H, W) ambiguous.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> image = jnp.linspace(0, 1, 40 * 48).reshape(40, 48, 1) ** 2
    >>> out = ssw_outputs(image, image, Params().replace(**{"segments.n_segments": 8}), ndisp=8)
    >>> out.confidence.shape, str(out.confidence.dtype)
    ((40, 48), 'float32')
    """
    disparity, cues, _ = match_maps(left, right, params, ndisp, valid_ndisp, chunk,
                                    valid_shape=valid_shape)
    return _outputs(disparity, cues, measure)


@functools.partial(jax.jit, static_argnames=("ndisp", "chunk", "measure"))
def ssw_outputs_seeded(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int,
                       seeds: Seeds, valid_ndisp=None, chunk: int = DEFAULT_CHUNK,
                       measure: str = DEFAULT_MEASURE,
                       valid_shape=None) -> tuple[SSWOutputs, Seeds]:
    """:func:`ssw_outputs` of a window of row strips, with ``seeds`` as for
    :func:`ssw_disparity_seeded`.

    Returns
    -------
    (SSWOutputs, Seeds)
    """
    disparity, cues, carried = match_maps(left, right, params, ndisp, valid_ndisp, chunk,
                                          valid_shape=valid_shape, seeds=seeds)
    return _outputs(disparity, cues, measure), carried


@functools.partial(jax.jit, static_argnames=("ndisp", "chunk"))
def ssw_cues(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int, valid_ndisp=None,
             chunk: int = DEFAULT_CHUNK, valid_shape=None) -> tuple[jax.Array, ConfidenceCues]:
    """The dense disparity of :func:`ssw_disparity` and the raw cues of its confidence.

    For analyses that compare confidence measures on one run (``benchmarks/sparsification.py``).

    Returns
    -------
    (float32 (H, W), ConfidenceCues)
    """
    return match_maps(left, right, params, ndisp, valid_ndisp, chunk, valid_shape=valid_shape)[:2]


@functools.partial(jax.jit, static_argnames=("ndisp", "chunk"))
def ssw_carried(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int, seeds,
                valid_ndisp=None, chunk: int = DEFAULT_CHUNK, valid_shape=None):
    """Only the paths' states a window of row strips leaves for its neighbours: the cost,
    the aggregation and the optimiser of :func:`ssw_disparity` with ``seeds``, nothing after
    (the first sweep of :mod:`sswjax.runtime.carried`, which needs the forward states of
    every window before the maps of any).

    Parameters
    ----------
    left, right, params, ndisp, valid_ndisp, chunk, valid_shape, seeds
        As for :func:`ssw_disparity_seeded`.

    Returns
    -------
    Seeds
        The states captured where ``seeds`` say (:mod:`sswjax.stages.paths`).
    """
    check_pair(left, right, ndisp)
    check_unaligned(params)
    check_carried(params)
    scene = prepare_scene(left, right, params, valid_shape=valid_shape)
    _, optimised = optimised_volume(scene, params, ndisp=ndisp, valid_ndisp=valid_ndisp,
                                    chunk=chunk, seeds=seeds)
    return optimised.carried
