"""Pairs through ``jax.vmap``, the batch sharded over all JAX devices.

Conventions: a batch is float32 ``(B, H, W, C)`` (C in {1, 3}, values in [0, 1]) for the left
and right images; the result is float32 ``(B, H, W)``. The batch axis is split over a 1-D device
mesh (:func:`sswjax.runtime.devices.device_mesh`), so the same code uses every CPU device
(``XLA_FLAGS=--xla_force_host_platform_device_count=N``), GPU or TPU core; a batch whose
size is not a multiple of the device count is padded with copies of its last pair
(:func:`~sswjax.runtime.devices.pad_batch`), then cropped.

Two entry points: :func:`match_batch` runs equal-size pairs in one call (``B / devices`` pairs
per device); :func:`match_scenes` (and :func:`iter_match_scenes`, which yields each map as soon
as it is done) runs pairs of different sizes, grouped by
:func:`~sswjax.runtime.buckets.bucket_shape` and padded as ``sswjax.match(..., buckets=)`` pads
them, one pair per device per call, so a call never holds more than one cost volume per device.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from sswjax._checks import check_rank, check_same_shape
from sswjax.api.images import checked_pair
from sswjax.config import Params, check_params, default_params
from sswjax.graph import DEFAULT_CHUNK, align_right, ssw_disparity
from sswjax.runtime.buckets import ShapeBuckets, bucket_shape, pad_to_bucket
from sswjax.runtime.devices import BATCH_AXIS, device_mesh, pad_batch
from sswjax.runtime.executables import bounded

__all__ = ["iter_match_scenes", "match_batch", "match_scenes"]


def _vmapped(lefts, rights, valid_ndisps, valid_shapes, params, *, ndisp, chunk):
    """:func:`~sswjax.graph.ssw_disparity` of each pair of a batch (``jax.vmap``), its right
    image aligned first (:func:`~sswjax.graph.align_right`) when ``params.alignment``."""
    def one(left, right, valid_ndisp, valid_shape):
        call = {"ndisp": ndisp, "valid_ndisp": valid_ndisp, "chunk": chunk,
                "valid_shape": valid_shape}
        if params.alignment is not None:
            right, _ = align_right(left, right, params, **call)
        return ssw_disparity(left, right, params.replace(alignment=None), **call)

    return jax.vmap(one)(lefts, rights, valid_ndisps, valid_shapes)


_batched = bounded(_vmapped, static_argnames=("ndisp", "chunk"))
"""The batched graph, its executables bounded (:mod:`sswjax.runtime.executables`)."""


def _run_sharded(lefts, rights, valid, params: Params, ndisp: int, mesh: Mesh,
                 chunk: int = DEFAULT_CHUNK) -> np.ndarray:
    """``ssw_disparity`` of a batch split over ``mesh`` (padded to a multiple of its size).

    ``valid``: ``(valid_ndisps, valid_shapes)``, int32 ``(B,)`` traced search ranges and
    int32 ``(B, 2)`` sizes of the pairs within their padding, or ``None`` for ``ndisp`` and
    the whole images.
    """
    size = len(lefts)
    arrays = (lefts, rights) + (() if valid is None else tuple(valid))
    sharding = NamedSharding(mesh, PartitionSpec(BATCH_AXIS))
    sharded = jax.device_put(pad_batch(arrays, mesh.size), sharding)
    if valid is None:
        sharded += (None, None)
    return np.asarray(_batched(*sharded, params, ndisp=ndisp, chunk=chunk))[:size]


def match_batch(lefts, rights, ndisp: int, *, params: Params | None = None, devices=None) -> np.ndarray:
    """Disparity maps of a batch of equal-size pairs, the batch split over ``devices`` in one call.

    Parameters
    ----------
    lefts, rights : array_like (B, H, W) or (B, H, W, 1|3|4), uint8, uint16 or float
    ndisp : int, 1 <= ndisp < W
    params : Params, optional
        Default: the ``accurate`` preset (:func:`sswjax.config.default_params`).
    devices : sequence of jax.Device, optional
        Default: all of ``jax.devices()``.

    Returns
    -------
    numpy.ndarray float32 (B, H, W), equal to :func:`sswjax.match` on each pair.

    Examples
    --------
    >>> import numpy as np
    >>> r = np.random.default_rng(0).random((3, 24, 40, 3), dtype=np.float32)
    >>> small = Params().replace(**{"segments.n_segments": 8})
    >>> match_batch(np.roll(r, 2, axis=2), r, 8, params=small).shape
    (3, 24, 40)
    """
    lefts, rights = np.asarray(lefts), np.asarray(rights)
    check_rank("lefts", lefts, (3, 4))
    check_same_shape("lefts", lefts, "rights", rights)
    if lefts.shape[0] == 0:
        raise ValueError("the batch is empty")
    params = default_params() if params is None else check_params(params)
    pairs = [checked_pair(left, right, ndisp, params) for left, right in zip(lefts, rights)]
    left_batch, right_batch = (np.stack(views) for views in zip(*pairs))
    return _run_sharded(left_batch, right_batch, None, params, int(ndisp), device_mesh(devices=devices))


def iter_match_scenes(
    pairs: Sequence[tuple[np.ndarray, np.ndarray]],
    ndisps: Sequence[int],
    *,
    params: Params | None = None,
    buckets: ShapeBuckets = ShapeBuckets(),
    devices: Sequence[jax.Device] | None = None,
) -> Iterator[tuple[int, np.ndarray, float]]:
    """Disparity maps of pairs of different sizes, grouped by bucket, one pair per device per call.

    Pairs are grouped by their padded shape (:func:`~sswjax.runtime.buckets.bucket_shape` and the
    channel count), groups in order of their first pair; each pair is edge-padded at the bottom
    and right as ``sswjax.match(..., buckets=buckets)`` pads it, and its own ``ndisp`` and size
    are passed as the traced ``valid_ndisp`` and ``valid_shape``. A group runs in steps of ``len(devices)`` pairs, one per
    device (``jax.vmap`` over a batch sharded on :func:`device_mesh`); a short last step is
    filled with copies of its last pair. Every input is checked before the first step.

    Parameters
    ----------
    pairs : sequence of (left, right)
        Each image array_like (H, W) or (H, W, 1|3|4), uint8, uint16 or float in [0, 1]; sizes
        may differ between pairs.
    ndisps : sequence of int
        Each pair's search range 0 .. ndisp - 1, 1 <= ndisp < W.
    params : Params, optional
        Default: the ``accurate`` preset (:func:`sswjax.config.default_params`).
    buckets : ShapeBuckets
        Shape bucketing (default ``ShapeBuckets()``); each distinct bucket compiles once.
    devices : sequence of jax.Device, optional
        Default: all of ``jax.devices()``.

    Yields
    ------
    (int, numpy.ndarray float32 (H, W), float)
        The pair's index in ``pairs``, its disparity map (equal to
        ``sswjax.match(left, right, ndisp, params=params, buckets=buckets)``) and its share of the
        step's wall time in seconds: the step's time (conversion, padding, transfers, the
        sharded call, compilation on a bucket's first step) divided by the number of pairs of
        the step (copies not counted). A step's maps are yielded together when it is done.
    """
    if len(pairs) != len(ndisps):
        raise ValueError(f"got {len(pairs)} pairs but {len(ndisps)} ndisp values")
    params = default_params() if params is None else check_params(params)
    mesh = device_mesh(devices=devices)
    groups: dict[tuple[int, ...], list[int]] = {}
    for index, ((left, right), ndisp) in enumerate(zip(pairs, ndisps)):
        left, _ = checked_pair(left, right, ndisp, params)
        key = bucket_shape(*left.shape[:2], int(ndisp), buckets) + (left.shape[2],)
        groups.setdefault(key, []).append(index)
    for (height, width, ndisp, _), indices in groups.items():
        for first in range(0, len(indices), mesh.size):
            step = indices[first:first + mesh.size]
            start = time.perf_counter()
            views, sizes = [], []
            for index in step:
                left, right = checked_pair(*pairs[index], ndisps[index], params)
                sizes.append(left.shape[:2])
                views.append(list(pad_to_bucket(left, right, height, width)))
            left_batch, right_batch = (np.stack(side) for side in zip(*views))
            valid = (np.array([ndisps[index] for index in step], np.int32),
                     np.array(sizes, np.int32))
            disparities = _run_sharded(left_batch, right_batch, valid, params, ndisp, mesh)
            seconds = (time.perf_counter() - start) / len(step)
            for index, disparity, (h, w) in zip(step, disparities, sizes):
                yield index, disparity[:h, :w], seconds


def match_scenes(
    pairs: Sequence[tuple[np.ndarray, np.ndarray]],
    ndisps: Sequence[int],
    *,
    params: Params | None = None,
    buckets: ShapeBuckets = ShapeBuckets(),
    devices: Sequence[jax.Device] | None = None,
) -> list[np.ndarray]:
    """Disparity maps of pairs of different sizes, in the order of ``pairs``.

    The maps of :func:`iter_match_scenes` (same parameters), each float32 ``(H, W)`` of its
    pair and equal to ``sswjax.match(left, right, ndisp, params=params, buckets=buckets)``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> rights = [rng.random((h, w, 3), dtype=np.float32) for h, w in ((24, 40), (20, 44))]
    >>> pairs = [(np.roll(r, 2, axis=1), r) for r in rights]
    >>> maps = match_scenes(pairs, [8, 6], params=Params().replace(**{"segments.n_segments": 8}),
    ...                     buckets=ShapeBuckets(size_step=32, ndisp_step=8))
    >>> [m.shape for m in maps]
    [(24, 40), (20, 44)]
    """
    maps: list[np.ndarray | None] = [None] * len(pairs)
    done = iter_match_scenes(pairs, ndisps, params=params, buckets=buckets, devices=devices)
    for index, disparity, _ in done:
        maps[index] = disparity
    return maps
