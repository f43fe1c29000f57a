"""Row strips: a pair matched in overlapping horizontal strips, the results stitched.

Array conventions: images float32 ``(H, W, C)`` NumPy arrays; a run returns a map ``(H', W)``
(or a NamedTuple of maps of any dtypes) for a strip of ``H'`` rows.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

__all__ = ["in_strips"]


def in_strips(run, left: np.ndarray, right: np.ndarray, *, rows: int, overlap: int) -> np.ndarray:
    """``run(left, right)`` on overlapping horizontal strips of the pair, stitched.

    Each call sees ``rows + 2 * overlap`` image rows (one shape, so one compilation) and gives
    its ``rows`` central rows; strips at the top and bottom slide inside the image. Memory
    follows the strip's height instead of the image's; what a strip cannot see (the image
    beyond its overlap) is what changes: vertical SGM paths and the superpixels start afresh
    at its edges. ``rows=0`` (or a strip taller than the image) runs the whole pair at once.

    Parameters
    ----------
    run : callable
        ``run(left, right) -> (H', W)`` map of float32 ``(H', W, C)`` images, or a NamedTuple
        of such maps of any dtypes: each is stitched.
    left, right : float32 (H, W, C)
    rows, overlap : int >= 0

    Returns
    -------
    numpy.ndarray (H, W) of the map's dtype, or the same NamedTuple of them

    Examples
    --------
    >>> import numpy as np
    >>> image = np.arange(10.0)[:, None, None] * np.ones((10, 3, 1))
    >>> rows_seen = in_strips(lambda l, r: l[..., 0], image, image, rows=4, overlap=1)
    >>> rows_seen[:, 0].tolist()
    [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]
    """
    height = left.shape[0]
    window = rows + 2 * overlap
    if rows <= 0 or window >= height:
        return _to_numpy(run(jnp.asarray(left), jnp.asarray(right)))
    out = None
    for first in range(0, height, rows):
        last = min(first + rows, height)
        top = min(max(first - overlap, 0), height - window)
        strip = _to_numpy(run(jnp.asarray(left[top:top + window]),
                              jnp.asarray(right[top:top + window])))
        parts = strip if isinstance(strip, tuple) else (strip,)
        if out is None:
            out = [np.empty(left.shape[:2], part.dtype) for part in parts]
        for whole, part in zip(out, parts):
            whole[first:last] = part[first - top:last - top]
    return type(strip)(*out) if isinstance(strip, tuple) else out[0]


def _to_numpy(result):
    """A map, or a (Named)tuple of maps, as NumPy arrays of the same structure."""
    if isinstance(result, tuple):
        return type(result)(*(np.asarray(part) for part in result))
    return np.asarray(result)
