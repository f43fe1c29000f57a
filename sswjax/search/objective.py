"""The differentiable objective of the parameter search: soft-argmin of the inference volume.

The search runs the *same* functions as inference (:mod:`sswjax.graph.volume`): the scene
(pre-processing, the cost's features, SLIC, traced once) and the aggregated volume; with an
optimizer, :func:`~sswjax.graph.volume.optimised_volume`, the one function that makes the
optimised volume for inference too. Then :func:`sswjax.stages.selection.soft_argmin` takes the
place of the winner-takes-all. The static options that declare a differentiable value run with
it (:func:`sswjax.search.space.differentiable`). The loss is a surrogate of the bad-pixel rate
(:mod:`sswjax.search.surrogates`; by default the smooth L1 of the soft-argmin disparity)
against the ground truth over the valid pixels (:func:`sswjax.search.crops.valid_mask`).

Array conventions: images float32 ``(H, W, C)``, C in {1, 3}, in [0, 1]; ground truth float32
``(H, W)`` in pixels (unknown = 0, excluded by ``valid``); ``valid`` bool ``(H, W)``; batches
add a leading axis ``B``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax.config import Params
from sswjax.graph.volume import OUT_OF_RANGE_COST, aggregate_slices, optimised_volume, prepare_scene
from sswjax.search.space import differentiable, from_unconstrained
from sswjax.search.surrogates import DEFAULT_SURROGATE, HUBER_DELTA, smooth_l1
from sswjax.search.surrogates import surrogate as surrogate_of
from sswjax.stages.quantisation import as_volume
from sswjax.stages.selection import soft_argmin

__all__ = ["HUBER_DELTA", "batch_loss", "loss", "search_volume", "smooth_l1", "soft_disparity"]


def _masked(cost: jax.Array, scene_ndisp) -> jax.Array:
    """``cost`` (D, H, W) with the disparities ``>= scene_ndisp`` at OUT_OF_RANGE_COST."""
    if scene_ndisp is None:
        return cost
    d = jnp.arange(cost.shape[0])[:, None, None]
    return jnp.where(d < scene_ndisp, cost, OUT_OF_RANGE_COST)


def search_volume(raw: dict, left: jax.Array, right: jax.Array, *, base: Params, ndisp: int,
                  scene_ndisp=None) -> tuple[jax.Array, jax.Array]:
    """The volume the winner-takes-all would read, with the parameters of ``raw``, and the
    soft-argmin temperature.

    ``scene_ndisp`` (traced, optional) masks disparities ``>= scene_ndisp``, so that a common,
    padded ``ndisp`` gives each scene its own range: every slice is computed and aggregated
    on its own, so the kept slices are those of the scene's own ``ndisp``; as in inference,
    the optimiser sees the others at :data:`~sswjax.graph.volume.OUT_OF_RANGE_COST`.

    Parameters
    ----------
    raw : dict of float32 arrays
        Search variables (:func:`sswjax.search.space.to_unconstrained`).
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    base : Params
        The values of the options ``raw`` does not set, and the structure (static).
    ndisp : int
        Disparities of the volume (static).
    scene_ndisp : int32 scalar, optional

    Returns
    -------
    float32 (ndisp, H, W), float32 scalar
    """
    params, temperature = from_unconstrained(raw, base=base)
    params = differentiable(params)
    scene = prepare_scene(left, right, params)
    if params.optimizer is None:
        cost = aggregate_slices(scene, params, 0, ndisp)
    else:
        _, optimised = optimised_volume(scene, params, ndisp=ndisp, valid_ndisp=scene_ndisp,
                                        chunk=0)
        cost = as_volume(optimised)
    return _masked(cost, scene_ndisp), temperature


def soft_disparity(raw: dict, left: jax.Array, right: jax.Array, *, base: Params, ndisp: int,
                   scene_ndisp=None) -> jax.Array:
    """Soft-argmin disparity (float32 (H, W), in [0, ndisp - 1]) of :func:`search_volume`."""
    cost, temperature = search_volume(raw, left, right, base=base, ndisp=ndisp,
                                      scene_ndisp=scene_ndisp)
    return soft_argmin(cost, temperature=temperature)


def loss(raw: dict, left, right, ground_truth, valid, *, base: Params, ndisp: int,
         scene_ndisp=None, surrogate: str = DEFAULT_SURROGATE) -> tuple[jax.Array, jax.Array]:
    """Mean ``surrogate`` (:data:`sswjax.search.surrogates.SURROGATES`) over the ``valid``
    pixels of one crop.

    Returns ``(loss, count)``: a float32 scalar and the int32 count of valid pixels. The
    temperature is part of ``raw``.
    """
    cost, temperature = search_volume(raw, left, right, base=base, ndisp=ndisp,
                                      scene_ndisp=scene_ndisp)
    gt = jnp.where(valid, ground_truth, 0.0)
    per_pixel = jnp.where(valid, surrogate_of(surrogate)(cost, gt, temperature=temperature), 0.0)
    count = valid.sum()
    return per_pixel.sum() / jnp.maximum(count, 1), count


def batch_loss(raw: dict, lefts, rights, gts, valids, scene_ndisps, *, base: Params,
               ndisp: int, surrogate: str = DEFAULT_SURROGATE) -> jax.Array:
    """Pixel-weighted mean loss (float32 scalar) over a batch of crops (``jax.vmap``).

    The batch is that of :func:`sswjax.search.crops.random_crops`: float32 (B, H, W, C) twice,
    float32 (B, H, W), bool (B, H, W), int32 (B,).
    """
    per_crop, counts = jax.vmap(
        lambda l, r, g, v, n: loss(raw, l, r, g, v, base=base, ndisp=ndisp, scene_ndisp=n,
                                   surrogate=surrogate)
    )(lefts, rights, gts, valids, scene_ndisps)
    total = jnp.maximum(counts.sum(), 1)
    return (per_crop * counts).sum() / total
