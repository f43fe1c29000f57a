"""Lowering a call to a stored trace without importing SciPy, when the trace calls no LAPACK.

Lowering a call to a ``jax.export.Exported`` for the CPU (``Exported.call`` under ``jax.jit``)
first registers jaxlib's LAPACK kernels (``jax._src.export._export._ensure_backends_initialized``
on jax 0.10), which imports ``scipy.linalg`` to take their addresses: 0.14 s of a warm process's
first call, in which the whole lowering takes about 0.2 s. The kernels are needed only by a
module that calls them (a ``lapack_*`` custom call, from ``jnp.linalg`` and the like); of
sswjax's graphs, only those with the ``plane`` fill do. :func:`calls_lapack` tells it from
the module's text when the trace is made, and within :func:`lowering_without_lapack` this
thread lowers calls to traces without the registration. Other threads, and any call where
this jax has no such function, lower as JAX does.

The registration is also what an executable compiled in another process needs before it runs
(a stored one, :mod:`sswjax.runtime.stored`): one that calls LAPACK, loaded where nothing
registered the kernels, dies on its first run with a segmentation fault (reproduced with
``jnp.linalg.inv``; the ``plane`` fill solves with LAPACK). :func:`register_lapack` registers
them first.
"""

from __future__ import annotations

import contextlib
import functools
import sys
import threading
from collections.abc import Iterator

import jax
import jax.export
import jax.numpy as jnp

# JAX's module of exported calls, where jax 0.10 keeps the registration (None in a jax that
# has moved it: its calls lower as it does).
_jax_export = sys.modules.get("jax._src.export._export")

__all__ = ["calls_lapack", "lowering_without_lapack", "register_lapack"]

_LAPACK_TARGET = "lapack_"
_STATE = threading.local()


def calls_lapack(exported: jax.export.Exported) -> bool:
    """Whether the module of ``exported`` calls a LAPACK kernel (a custom call whose target
    starts with ``lapack_``, as jaxlib names them); a module that cannot be read says True.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> spec = jax.ShapeDtypeStruct((3, 3), jnp.float32)
    >>> calls_lapack(jax.export.export(jax.jit(lambda a: a @ a))(spec))
    False
    >>> calls_lapack(jax.export.export(jax.jit(jnp.linalg.inv))(spec))
    True
    """
    try:
        text = exported.mlir_module()
    except Exception:  # noqa: BLE001 - unreadable: register the kernels, as JAX does
        return True
    return _LAPACK_TARGET in text


def _install() -> bool:
    """Put a registration this thread can skip in place of JAX's, once; False where this jax
    has none by that name."""
    original = getattr(_jax_export, "_ensure_backends_initialized", None)
    if original is None:
        return False
    if getattr(original, "_sswjax_skippable", False):
        return True

    def skippable(platforms):
        if not getattr(_STATE, "skip", False):
            original(platforms)

    skippable._sswjax_skippable = True
    _jax_export._ensure_backends_initialized = skippable
    return True


@contextlib.contextmanager
def lowering_without_lapack(*, skip: bool = True) -> Iterator[None]:
    """Within the block, this thread lowers calls to exported modules without registering
    LAPACK's kernels (when ``skip``; a module that calls one must be lowered with ``skip``
    False, see :func:`calls_lapack`)."""
    if not skip or not _install():
        yield
        return
    before = getattr(_STATE, "skip", False)
    _STATE.skip = True
    try:
        yield
    finally:
        _STATE.skip = before


@functools.cache
def register_lapack() -> None:
    """Register LAPACK's kernels in this process for the default backend, as lowering a call
    to one does (it lowers one: ``jnp.linalg.inv`` of a 1 x 1 matrix; nothing is compiled).
    Once per process: the registration holds for every later executable."""
    jax.jit(jnp.linalg.inv).lower(jax.ShapeDtypeStruct((1, 1), jnp.float32))
