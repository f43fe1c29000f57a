"""Colour-space conversions.

Array conventions (used by every function in this module):

* An RGB image is a float array of shape ``(H, W, 3)`` holding gamma-encoded sRGB values in
  ``[0, 1]`` (channel order R, G, B). A gray image is a float array of shape ``(H, W)`` in
  ``[0, 1]``.
* A CIELAB image is a float32 array of shape ``(H, W, 3)`` with channels ``(L*, a*, b*)``:
  ``L*`` in ``[0, 100]``, ``a*`` and ``b*`` roughly in ``[-128, 128]``, relative to the D65
  reference white (CIE 1931 2-degree observer).
* Outputs are float32. All functions are pure JAX and can be traced by ``jax.jit`` and
  differentiated by ``jax.grad``.
"""

from __future__ import annotations

import jax.numpy as jnp

from sswjax._checks import check_floating, check_rank

__all__ = ["rgb_to_gray", "rgb_to_lab"]

# IEC 61966-2-1 (sRGB) linear RGB -> CIE XYZ matrix, rows X, Y, Z.
_XYZ_FROM_LINEAR_RGB = (
    (0.412453, 0.357580, 0.180423),
    (0.212671, 0.715160, 0.072169),
    (0.019334, 0.119193, 0.950227),
)
# CIE D65 reference white, 2-degree observer, normalised to Y = 1.
_D65_WHITE_XYZ = (0.95047, 1.0, 1.08883)
# ITU-R BT.601 luma weights for R, G, B.
_BT601_LUMA_WEIGHTS = (0.299, 0.587, 0.114)

# sRGB transfer function: linear segment below this encoded value.
_SRGB_LINEAR_LIMIT = 0.04045
# CIE f(t): cube root above (6/29)^3, linear segment below.
_CIE_DELTA = 6.0 / 29.0


def _srgb_to_linear(encoded: jnp.ndarray) -> jnp.ndarray:
    """Undo the sRGB gamma (IEC 61966-2-1); gradient-safe at the branch point."""
    in_power_branch = encoded > _SRGB_LINEAR_LIMIT
    # Feed the power law only with values of its own branch so its gradient stays finite.
    power_input = jnp.where(in_power_branch, encoded, _SRGB_LINEAR_LIMIT)
    power_part = ((power_input + 0.055) / 1.055) ** 2.4
    return jnp.where(in_power_branch, power_part, encoded / 12.92)


def _cie_f(t: jnp.ndarray) -> jnp.ndarray:
    """CIE f(t) = t^(1/3) above (6/29)^3, t / (3 (6/29)^2) + 4/29 below."""
    threshold = _CIE_DELTA**3
    in_root_branch = t > threshold
    root_input = jnp.where(in_root_branch, t, threshold)
    return jnp.where(
        in_root_branch,
        jnp.cbrt(root_input),
        t / (3.0 * _CIE_DELTA**2) + 4.0 / 29.0,
    )


def rgb_to_lab(image: jnp.ndarray) -> jnp.ndarray:
    """Convert an sRGB image to CIELAB (D65).

    The sRGB values are linearised with the standard IEC 61966-2-1 transfer function, mapped to
    CIE XYZ, normalised by the D65 white point and passed through the CIE ``f(t)`` (cube root
    above ``(6/29)^3``, linear below), following the CIE 1976 L*a*b* definition as used by
    SLIC (Achanta et al., "SLIC Superpixels Compared to State-of-the-Art Superpixel Methods",
    IEEE TPAMI 34(11), 2012).

    Parameters
    ----------
    image : array, shape (H, W, 3), floating
        sRGB image in ``[0, 1]``.

    Returns
    -------
    lab : array, shape (H, W, 3), float32
        ``(L*, a*, b*)`` with ``L*`` in ``[0, 100]``.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> lab = rgb_to_lab(jnp.ones((2, 2, 3)))  # white
    >>> lab.shape, round(float(lab[0, 0, 0]), 2), bool(jnp.abs(lab[..., 1:]).max() < 0.01)
    ((2, 2, 3), 100.0, True)
    """
    check_rank("image", image, 3)
    check_floating("image", image)
    if image.shape[-1] != 3:
        raise ValueError(f"image must have 3 channels in the last axis, got shape {tuple(image.shape)}")

    linear_rgb = _srgb_to_linear(jnp.asarray(image, jnp.float32))
    xyz = linear_rgb @ jnp.asarray(_XYZ_FROM_LINEAR_RGB, jnp.float32).T
    f_xyz = _cie_f(xyz / jnp.asarray(_D65_WHITE_XYZ, jnp.float32))
    f_x, f_y, f_z = f_xyz[..., 0], f_xyz[..., 1], f_xyz[..., 2]
    lightness = 116.0 * f_y - 16.0
    green_red = 500.0 * (f_x - f_y)
    blue_yellow = 200.0 * (f_y - f_z)
    return jnp.stack([lightness, green_red, blue_yellow], axis=-1).astype(jnp.float32)


def rgb_to_gray(image: jnp.ndarray) -> jnp.ndarray:
    """Convert an sRGB image to gray with the ITU-R BT.601 luma weights.

    ``gray = 0.299 R + 0.587 G + 0.114 B``, applied directly to the gamma-encoded values
    (luma, Recommendation ITU-R BT.601). A gray ``(H, W)`` image is returned unchanged (as
    float32).

    Parameters
    ----------
    image : array, shape (H, W, 3) or (H, W), floating
        sRGB image in ``[0, 1]``, or an already gray image.

    Returns
    -------
    gray : array, shape (H, W), float32
        Luma in ``[0, 1]``.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> gray = rgb_to_gray(jnp.ones((2, 2, 3)) * jnp.array([1.0, 0.0, 0.0]))
    >>> round(float(gray[0, 0]), 3)
    0.299
    """
    check_rank("image", image, (2, 3))
    check_floating("image", image)
    image = jnp.asarray(image, jnp.float32)
    if image.ndim == 2:
        return image
    if image.shape[-1] != 3:
        raise ValueError(f"image must have 3 channels in the last axis, got shape {tuple(image.shape)}")
    return image @ jnp.asarray(_BT601_LUMA_WEIGHTS, jnp.float32)
