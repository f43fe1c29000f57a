"""One step of the search: the optax optimiser (with frozen keys) and the jitted, sharded update.

Optimiser: :func:`make_optimizer` is Adam wrapped in ``optax.multi_transform``; the raw keys
listed as frozen are labelled ``"frozen"`` and get ``optax.set_to_zero()`` (a zero update, no
Adam moments), so freezing is part of the optimiser and :func:`make_update_step` knows nothing
of it.

Devices: :func:`make_update_step` splits each crop batch over a 1-D mesh of JAX devices
(:func:`sswjax.runtime.devices.device_mesh`; padded with zero-weight crops to a multiple of
the device count) with the parameters and optimizer state replicated, so one step uses every
CPU device, GPU or TPU core and gives the one-device result.

Batches (whole module): ``(lefts, rights, gts, valids, scene_ndisps)``, float32
(B, H, W, C), float32 (B, H, W, C), float32 (B, H, W), bool (B, H, W), int32 (B,), as
:func:`sswjax.search.crops.random_crops` draws them.
"""

from __future__ import annotations

import functools

import jax
import optax
from jax.sharding import NamedSharding, PartitionSpec

from sswjax.config import Params
from sswjax.runtime.devices import BATCH_AXIS, device_mesh, pad_batch
from sswjax.search.objective import batch_loss
from sswjax.search.surrogates import DEFAULT_SURROGATE
from sswjax.search.space import all_raw_keys

__all__ = ["freeze_labels", "make_optimizer", "make_update_step", "shard_crops"]


def shard_crops(batch, mesh) -> tuple[jax.Array, ...]:
    """A crop batch on ``mesh`` (:func:`~sswjax.runtime.devices.device_mesh`), split on its
    batch axis.

    A batch whose size is not a multiple of the device count is padded with copies of its last
    crop whose ``valid`` mask is all False: they have a zero pixel count, so they change neither
    :func:`~sswjax.search.objective.batch_loss` nor its gradient.

    Parameters
    ----------
    batch : (lefts, rights, gts, valids, scene_ndisps)
        As the module docstring.
    mesh : jax.sharding.Mesh
        1-D, axis :data:`~sswjax.runtime.devices.BATCH_AXIS`.

    Returns
    -------
    tuple of jax.Array, the same five with B rounded up to a multiple of ``mesh.size``.
    """
    size = len(batch[0])
    lefts, rights, gts, valids, scene_ndisps = pad_batch(batch, mesh.size)
    valids = valids.copy()
    valids[size:] = False
    sharding = NamedSharding(mesh, PartitionSpec(BATCH_AXIS))
    return jax.device_put((lefts, rights, gts, valids, scene_ndisps), sharding)


def freeze_labels(frozen):
    """optax labels of a ``raw`` dict: ``"frozen"`` for the keys in ``frozen``, else ``"train"``.

    Returns a function of ``raw`` (as ``optax.multi_transform`` takes it). Raises ``ValueError``
    for a key not in :func:`~sswjax.search.space.all_raw_keys`.

    >>> freeze_labels(["temperature"])({"optimizer.p2": 0.0, "temperature": 0.0})
    {'optimizer.p2': 'train', 'temperature': 'frozen'}
    """
    frozen = tuple(frozen)
    known = all_raw_keys()
    unknown = sorted(set(frozen) - set(known))
    if unknown:
        raise ValueError(f"unknown raw keys {unknown}; expected some of {known}")
    return lambda raw: {k: "frozen" if k in frozen else "train" for k in raw}


def make_optimizer(learning_rate: float, *, frozen=()) -> optax.GradientTransformation:
    """Adam on the raw keys not in ``frozen``; the keys in ``frozen`` do not move.

    ``optax.multi_transform`` routes the leaves labelled by :func:`freeze_labels`: ``"train"``
    to ``optax.adam(learning_rate)``, ``"frozen"`` to ``optax.set_to_zero()``. Adam is
    elementwise, so the trained leaves follow exactly the path they would with a zero gradient
    on the frozen ones (which gives Adam a zero update). The state holds Adam moments for the
    trained leaves only; its structure depends on ``frozen``
    (see :func:`sswjax.search.checkpoints.load_checkpoint`).
    """
    return optax.multi_transform(
        {"train": optax.adam(learning_rate), "frozen": optax.set_to_zero()},
        freeze_labels(frozen),
    )


def make_update_step(optimizer, *, base: Params, ndisp: int, devices=None,
                     surrogate: str = DEFAULT_SURROGATE):
    """``(raw, opt_state, batch) -> (raw, opt_state, loss)``: one jitted optax step, sharded.

    ``batch`` (module docstring) is split over a 1-D mesh of ``devices`` (default: all
    ``jax.devices()``) on its batch axis, any size (padded with zero-weight crops to a multiple
    of the device count; a multiple wastes nothing); ``raw`` and ``opt_state`` are replicated,
    so ``jit`` partitions the vmapped loss and its gradient over the devices and all-reduces
    the sums. The returned ``raw`` and ``opt_state`` are replicated, the loss a float32 scalar.
    ``base`` (its values and structure), ``ndisp`` and ``surrogate`` (a name of
    :data:`sswjax.search.surrogates.SURROGATES`) are closed over: another base compiles
    another step. Every key of ``raw`` gets its gradient; to hold some fixed, build
    ``optimizer`` with :func:`make_optimizer` (``frozen=...``).
    """
    mesh = device_mesh(devices=devices)
    replicated = NamedSharding(mesh, PartitionSpec())

    def objective(raw, batch):
        return batch_loss(raw, *batch, base=base, ndisp=ndisp, surrogate=surrogate)

    @functools.partial(jax.jit, out_shardings=replicated)
    def sharded_step(raw, opt_state, batch):
        value, grads = jax.value_and_grad(objective)(raw, batch)
        updates, opt_state = optimizer.update(grads, opt_state, raw)
        return optax.apply_updates(raw, updates), opt_state, value

    def update_step(raw, opt_state, batch):
        raw, opt_state = jax.device_put((raw, opt_state), replicated)
        return sharded_step(raw, opt_state, shard_crops(batch, mesh))

    return update_step
