"""Entry checks shared by every public function.

Each check raises ``ValueError`` (or ``TypeError`` for dtypes) with a one-line message naming
the argument, so that the CLI can show it to the user as is. Checks work on anything with
``.ndim``, ``.shape`` and ``.dtype`` (NumPy arrays, JAX arrays and tracers alike) and only
look at static information, so they are free inside ``jax.jit``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def check_rank(name: str, x, ranks: int | Sequence[int]) -> None:
    """Raise ``ValueError`` unless ``x.ndim`` is one of ``ranks``."""
    allowed = (ranks,) if isinstance(ranks, int) else tuple(ranks)
    if x.ndim not in allowed:
        want = " or ".join(str(r) for r in allowed)
        raise ValueError(f"{name} must have rank {want}, got shape {tuple(x.shape)}")


def check_floating(name: str, x) -> None:
    """Raise ``TypeError`` unless ``x`` has a floating dtype."""
    if not np.issubdtype(np.dtype(x.dtype), np.floating):
        raise TypeError(f"{name} must have a floating dtype, got {x.dtype}")


def check_integer(name: str, x) -> None:
    """Raise ``TypeError`` unless ``x`` has an integer dtype."""
    if not np.issubdtype(np.dtype(x.dtype), np.integer):
        raise TypeError(f"{name} must have an integer dtype, got {x.dtype}")


def check_same_shape(name_a: str, a, name_b: str, b) -> None:
    """Raise ``ValueError`` unless ``a`` and ``b`` have the same shape."""
    if tuple(a.shape) != tuple(b.shape):
        raise ValueError(
            f"{name_a} and {name_b} must have the same shape, got {tuple(a.shape)} and {tuple(b.shape)}"
        )


def check_positive_int(name: str, value, *, minimum: int = 1) -> None:
    """Raise ``ValueError`` unless ``value`` is a Python/NumPy integer >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")


def check_map(name: str, x, radius: int) -> None:
    """Filter inputs: a floating ``(..., H, W)`` array (rank 2 to 5) and an integer radius >= 1."""
    check_rank(name, x, range(2, 6))
    check_floating(name, x)
    check_positive_int("radius", radius)


def check_guide(guide, x, *, channels: tuple[int, ...] | None = None) -> None:
    """Guide: floating (H, W, C) or (H, W), spatial size of ``x``, optionally C in ``channels``."""
    check_rank("guide", guide, (2, 3))
    check_floating("guide", guide)
    if tuple(guide.shape[:2]) != tuple(x.shape[-2:]):
        raise ValueError(
            f"guide size {tuple(guide.shape[:2])} differs from x size {tuple(x.shape[-2:])}"
        )
    num_channels = guide.shape[2] if guide.ndim == 3 else 1
    if channels is not None and num_channels not in channels:
        want = " or ".join(str(c) for c in channels)
        raise ValueError(f"guide must have {want} channels, got shape {tuple(guide.shape)}")


def check_positive(name: str, value) -> None:
    """Reject non-positive Python numbers; traced or array values pass unchecked."""
    if isinstance(value, (int, float)) and not isinstance(value, bool) and not value > 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
