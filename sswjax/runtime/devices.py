"""The devices a batch is split over: a 1-D mesh, and batches padded to its size.

Conventions: a batch is a sequence of NumPy arrays sharing their leading axis ``B``; the mesh's
one axis is :data:`BATCH_AXIS`. The same code uses every CPU device
(``XLA_FLAGS=--xla_force_host_platform_device_count=N``), GPU or TPU core.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import numpy as np
from jax.sharding import Mesh

__all__ = ["BATCH_AXIS", "device_mesh", "pad_batch"]

BATCH_AXIS = "batch"
"""Name of the mesh axis the batch is split over."""


def device_mesh(*, devices: Sequence[jax.Device] | None = None) -> Mesh:
    """1-D mesh with axis :data:`BATCH_AXIS` over ``devices`` (default: all ``jax.devices()``).

    Examples
    --------
    >>> device_mesh().axis_names
    ('batch',)
    """
    devices = list(jax.devices() if devices is None else devices)
    if not devices:
        raise ValueError("devices is empty")
    return Mesh(np.array(devices), (BATCH_AXIS,))


def pad_batch(arrays: Sequence[np.ndarray], multiple: int) -> tuple[np.ndarray, ...]:
    """Pad the leading axis of the arrays to a multiple of ``multiple`` with copies of the last row.

    Parameters
    ----------
    arrays : sequence of numpy.ndarray (B, ...), one B for all, B >= 1
    multiple : int >= 1

    Returns
    -------
    tuple of numpy.ndarray (ceil(B / multiple) * multiple, ...)

    Examples
    --------
    >>> pad_batch([np.arange(3)], 2)[0].tolist()
    [0, 1, 2, 2]
    """
    arrays = [np.asarray(a) for a in arrays]
    size = arrays[0].shape[0]
    extra = -size % multiple
    return tuple(np.concatenate([a, np.repeat(a[-1:], extra, axis=0)]) if extra else a
                 for a in arrays)
