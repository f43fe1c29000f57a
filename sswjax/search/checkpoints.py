"""Checkpoints of a search: its raw variables, optimizer state, step and random stream.

A checkpoint is a pickle of NumPy arrays and plain values, written atomically
(:func:`sswjax._files.atomic_output`), so an interrupted search resumes from the last complete
one.
"""

from __future__ import annotations

import pickle

import jax
import jax.numpy as jnp
import numpy as np

from sswjax._files import atomic_output

__all__ = ["load_checkpoint", "save_checkpoint"]


def save_checkpoint(path, *, raw: dict, opt_state, step: int, rng: np.random.Generator,
                    extra=None) -> None:
    """Pickle the raw variables, the optimizer state, the step, the RNG's state and ``extra``
    (a JSON-like dict, e.g. the log) to ``path``, atomically."""
    state = {
        "raw": jax.tree_util.tree_map(np.asarray, raw),
        "opt_state": jax.tree_util.tree_map(np.asarray, opt_state),
        "step": int(step),
        "rng": rng.bit_generator.state,
        "extra": extra or {},
    }
    with atomic_output(path) as tmp, open(tmp, "wb") as handle:
        pickle.dump(state, handle)


def load_checkpoint(path, *, opt_state_like):
    """The inverse of :func:`save_checkpoint`: ``(raw, opt_state, step, rng, extra)``, the
    arrays as JAX arrays.

    ``opt_state_like`` (e.g. ``optimizer.init(raw)``) gives the pytree structure to restore; a
    checkpoint whose optimizer state has another structure (another ``frozen`` set of
    :func:`sswjax.search.step.make_optimizer`, other raw keys, or written before the optimizer
    was a ``multi_transform``) raises ``ValueError``.
    """
    with open(path, "rb") as handle:
        state = pickle.load(handle)
    raw = {k: jnp.asarray(v) for k, v in state["raw"].items()}
    leaves, stored = jax.tree_util.tree_flatten(state["opt_state"])
    expected = jax.tree_util.tree_structure(opt_state_like)
    if stored != expected:
        raise ValueError(f"{path}: its optimizer state does not match this optimizer (written "
                         "with another frozen set or search space, or before make_optimizer)")
    opt_state = jax.tree_util.tree_unflatten(expected, [jnp.asarray(x) for x in leaves])
    rng = np.random.default_rng()
    rng.bit_generator.state = state["rng"]
    return raw, opt_state, state["step"], rng, state["extra"]
