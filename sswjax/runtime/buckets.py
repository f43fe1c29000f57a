"""Shape buckets: image sizes and disparity counts rounded up so that pairs share a graph.

Array conventions: a pair is two float32 ``(H, W, C)`` NumPy images; padding replicates the
last row and column (bottom and right), and the results are cropped back by the caller.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["ShapeBuckets", "bucket_shape", "pad_to_bucket"]


class ShapeBuckets(NamedTuple):
    """Round image sizes and disparity counts up so that many pairs share one compiled graph.

    Height and width are padded (edge-replicated, bottom and right) to multiples of
    ``size_step`` and the volume to a multiple of ``ndisp_step`` disparities (the extra ones are
    never chosen); results are cropped back. The graph is told the pair's own size and
    matches the padding as the world beyond the pair's edge (:mod:`sswjax.graph.padding`), so
    the maps equal those of the exact shape (measured on the three shared sets:
    ``docs/notes/speed-and-memory.md``). The defaults put the 15 MiddEval3 trainingQ pairs
    into three shapes (512x512x96, 512x768x96, 512x768x192).
    """

    size_step: int = 256
    ndisp_step: int = 96


def bucket_shape(height: int, width: int, ndisp: int, buckets: ShapeBuckets) -> tuple[int, int, int]:
    """Padded ``(height, width, ndisp)`` of a pair under ``buckets`` (``ndisp`` < width kept).

    Examples
    --------
    >>> bucket_shape(375, 450, 64, ShapeBuckets())
    (512, 512, 96)
    """

    def up(value, step):
        return -(-value // step) * step

    padded_ndisp = up(ndisp, buckets.ndisp_step)
    padded_width = max(up(width, buckets.size_step), up(padded_ndisp + 1, buckets.size_step))
    return up(height, buckets.size_step), padded_width, padded_ndisp


def pad_to_bucket(left: np.ndarray, right: np.ndarray, height: int, width: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Edge-replicate a pair ``(H, W, C)`` at the bottom and right up to ``height x width``."""
    pad = ((0, height - left.shape[0]), (0, width - left.shape[1]), (0, 0))
    return tuple(np.pad(image, pad, mode="edge") for image in (left, right))
