"""Configurations of the pre-processing: what the matching cost sees of the images.

Array conventions (whole module): images float32 ``(H, W, C)``, C in {1, 3}, values in [0, 1].
"""

from __future__ import annotations

import jax

from sswjax.config.fields import option
from sswjax.config.parts import Part, register
from sswjax.stages.preprocess import local_contrast_normalization

__all__ = ["LocalContrast", "Preprocessor"]


class Preprocessor(Part):
    """Base of the pre-processors: ``apply(image) -> image`` on each image of the pair before
    the matching cost (the superpixels and the guides keep the images as given)."""

    def apply(self, image: jax.Array) -> jax.Array:
        """float32 (H, W, C) in [0, 1] -> the same shape, dtype and range."""
        raise NotImplementedError


@register("preprocess", "lcn")
class LocalContrast(Preprocessor):
    """Local contrast normalisation of the images the cost sees (dark, low-contrast pairs)."""

    radius: int = option(7, static=True, low=1, high=50, help="window radius of the local mean "
                         "and standard deviation")
    eps: float = option(4 / 255, above=0, help="added to the local standard deviation "
                        "(intensities in [0, 1])")

    def apply(self, image: jax.Array) -> jax.Array:
        """:func:`~sswjax.stages.preprocess.local_contrast_normalization`, float32 (H, W, C)."""
        return local_contrast_normalization(image, radius=self.radius, eps=self.eps)
