"""Values written once to memory instead of recomputed by each reader.

Array conventions (whole module): any array, integer or floating.

Why: XLA's CPU pipeline expands ``lax.optimization_barrier`` before it fuses, so a chain of
cheap elementwise operations (a map's upsampling, say) is fused into every reader and
recomputed for every element it reads; a reader that broadcasts a ``(H, W)`` plane over the
``K`` planes of a band recomputes the chain ``K`` times. A reduction is not fused into its
readers: its result is a buffer.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["written_once"]


def written_once(x: jax.Array) -> jax.Array:
    """``x`` unchanged, computed once into a buffer its readers load.

    The maximum over ``x`` stacked with its dtype's lowest value (``-inf`` for floats): a
    reduction, so XLA does not fuse the chain that makes ``x`` into the readers of the result
    (measured: a 7-plane reader of an upsampled map, 37 ms fused, 11 ms with this).

    Parameters
    ----------
    x : any shape, bool, integer or floating dtype

    Returns
    -------
    The same values, shape and dtype (NaN stays NaN).

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> written_once(jnp.array([3, -2**31, 5], jnp.int32)).tolist()
    [3, -2147483648, 5]
    >>> written_once(jnp.array([True, False])).tolist()
    [True, False]
    """
    if x.dtype == jnp.bool_:
        lowest = False
    elif jnp.issubdtype(x.dtype, jnp.integer):
        lowest = jnp.iinfo(x.dtype).min
    else:
        lowest = -jnp.inf
    return jnp.max(jnp.stack([x, jnp.full_like(x, lowest)]), axis=0)
