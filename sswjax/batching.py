"""Batches of equal-size pairs through ``jax.vmap``, sharded over all JAX devices.

Conventions: a batch is float32 ``(B, H, W, C)`` (C in {1, 3}, values in [0, 1]) for the left
and right images; the result is float32 ``(B, H, W)``. The batch axis is split over a 1-D device
mesh (``jax.sharding``), so the same code uses every CPU device
(``XLA_FLAGS=--xla_force_host_platform_device_count=N``), GPU or TPU core; a batch whose size
is not a multiple of the device count is padded with copies of its last pair, then cropped.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from sswjax._checks import check_rank, check_same_shape
from sswjax.params import Params
from sswjax.pipeline import prepare_pair, ssw_disparity


@functools.partial(jax.jit, static_argnames=("ndisp",))
def _batched(lefts, rights, params, *, ndisp):
    return jax.vmap(lambda left, right: ssw_disparity(left, right, params, ndisp=ndisp))(lefts, rights)


def match_batch(lefts, rights, ndisp: int, params: Params | None = None, *, devices=None) -> np.ndarray:
    """Disparity maps of a batch of equal-size pairs, the batch split over ``devices``.

    Parameters
    ----------
    lefts, rights : array_like (B, H, W) or (B, H, W, 1|3|4), uint8, uint16 or float
    ndisp : int, 1 <= ndisp < W
    params : Params, optional
    devices : sequence of jax.Device, optional
        Default: all of ``jax.devices()``.

    Returns
    -------
    numpy.ndarray float32 (B, H, W), equal to :func:`sswjax.match` on each pair.

    Examples
    --------
    >>> import numpy as np
    >>> r = np.random.default_rng(0).random((3, 24, 40, 3), dtype=np.float32)
    >>> match_batch(np.roll(r, 2, axis=2), r, 8, Params().replace(n_segments=8)).shape
    (3, 24, 40)
    """
    lefts, rights = np.asarray(lefts), np.asarray(rights)
    check_rank("lefts", lefts, (3, 4))
    check_same_shape("lefts", lefts, "rights", rights)
    if lefts.shape[0] == 0:
        raise ValueError("the batch is empty")
    pairs = [prepare_pair(left, right) for left, right in zip(lefts, rights)]
    left_batch = np.stack([p[0] for p in pairs])
    right_batch = np.stack([p[1] for p in pairs])
    if not 1 <= ndisp < left_batch.shape[2]:
        raise ValueError(f"ndisp must be in [1, {left_batch.shape[2] - 1}] for this width, got {ndisp}")
    params = Params() if params is None else params
    devices = list(jax.devices() if devices is None else devices)
    size = left_batch.shape[0]
    padded = -(-size // len(devices)) * len(devices)
    if padded != size:
        extra = padded - size
        left_batch = np.concatenate([left_batch, np.repeat(left_batch[-1:], extra, axis=0)])
        right_batch = np.concatenate([right_batch, np.repeat(right_batch[-1:], extra, axis=0)])
    sharding = NamedSharding(Mesh(np.array(devices), ("batch",)), PartitionSpec("batch"))
    left_batch = jax.device_put(jnp.asarray(left_batch), sharding)
    right_batch = jax.device_put(jnp.asarray(right_batch), sharding)
    disparities = _batched(left_batch, right_batch, params, ndisp=int(ndisp))
    return np.asarray(disparities)[:size]
