"""Pre-processing of the pair before the matching cost (the paper's Figure 2 names the stage and
never specifies it).

Array conventions (whole module): images are float32 ``(H, W, C)``, C in {1, 3}, values in
[0, 1]; outputs have the same shape, dtype and range.

Local contrast normalisation maps each pixel to its deviation from the local mean in units of
the local standard deviation, ``z = (I - mean_w(I)) / (std_w(I) + eps)`` over a
``(2r+1) x (2r+1)`` window, squashed into [0, 1] by ``(1 + tanh(z / 2)) / 2``. It makes TAD and
the gradient term, whose truncations are in absolute intensity units, see dark or low-contrast
regions as well as bright ones; census, which only compares intensities, is nearly unchanged.
It is the windowed normalisation of normalised cross-correlation (and of the prefilters of
block matchers, e.g. OpenCV's ``PREFILTER_NORMALIZED_RESPONSE``), applied once to the images.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax._checks import check_floating, check_positive_int, check_rank
from sswjax.stages.baselines import box_filter

__all__ = ["local_contrast_normalization"]


def local_contrast_normalization(image: jax.Array, *, radius: int = 7, eps=4 / 255) -> jax.Array:
    """Local contrast normalisation of an image, channel by channel.

    Parameters
    ----------
    image : float32 (H, W, C), values in [0, 1]
    radius : int >= 1
        Window radius of the local mean and standard deviation.
    eps : float or scalar array, > 0
        Added to the local standard deviation: flat regions (std << eps) stay near 0.5
        instead of amplifying noise.

    Returns
    -------
    float32 (H, W, C), values in [0, 1]

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> dark = jnp.tile(jnp.array([0.02, 0.04]), (6, 3))[..., None]     # a faint texture
    >>> bright = dark * 10                                               # the same, brighter
    >>> a = local_contrast_normalization(dark, radius=1, eps=1e-3)
    >>> b = local_contrast_normalization(bright, radius=1, eps=1e-3)
    >>> bool(jnp.abs(a - b).max() < 0.02)
    True
    """
    check_rank("image", image, 3)
    check_floating("image", image)
    check_positive_int("radius", radius)
    planes = jnp.moveaxis(image, -1, 0)
    mean = box_filter(planes, radius=radius)
    variance = jnp.maximum(box_filter(planes * planes, radius=radius) - mean * mean, 0.0)
    z = (planes - mean) / (jnp.sqrt(variance) + eps)
    return jnp.moveaxis(0.5 * (1.0 + jnp.tanh(0.5 * z)), 0, -1).astype(jnp.float32)
