"""Configuration of the superpixels that the segment-aware stages share (Eq. 6).

Array conventions (whole module): images float32 ``(H, W, C)``, C in {1, 3}, values in [0, 1];
labels int32 ``(H, W)``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax.config.fields import ConfigError, option
from sswjax.config.parts import Part, register
from sswjax.stages.segments import slic, slic_grid_shape

__all__ = ["Slic"]


@register("segments", "slic")
class Slic(Part):
    """SLIC superpixels of the left image (Achanta et al. 2012), shared by the segment-aware
    stages (Eq. 6)."""

    n_segments: int = option(2000, static=True, low=1, high=1_000_000,
                             help="requested superpixel count (Eq. 6)")
    iterations: int = option(10, static=True, low=1, high=100,
                             help="SLIC assignment / update rounds")
    compactness: float = option(10.0, above=0, help="m of Eq. 6: colour against position")

    def validate(self, params) -> None:
        """Superpixels must have a stage that uses them."""
        users = [part for part in (params.aggregation, params.optimizer, params.fill,
                                   params.band)
                 if part is not None and getattr(part, "uses_segments", False)]
        if not users:
            raise ConfigError("segments", "segments: no stage uses the superpixels (the "
                              "segment-side-window aggregation, the semi-global optimiser, the "
                              "plane fill or the band's segment range); set segments to None")

    def labels(self, left: jax.Array) -> tuple[jax.Array, int]:
        """int32 (H, W) labels of the left image and their static count."""
        height, width = left.shape[:2]
        ny, nx = slic_grid_shape(height, width, self.n_segments)
        image = left if left.shape[-1] == 3 else jnp.repeat(left, 3, axis=-1)
        labels = slic(image, n_segments=self.n_segments, compactness=self.compactness,
                      iterations=self.iterations)
        return labels, ny * nx
