"""The search's surrogates of the bad-pixel rate: per-pixel losses on a cost volume.

The metric the search should improve (bad 2.0 and 1.0 of the winner-takes-all map) has no
gradient. Each surrogate here is a differentiable stand-in computed from the volume the
winner-takes-all would read and the softmax over disparities it implies,
``p = softmax(-cost / temperature)`` (the temperature is a search variable). Which one tracks
the metric is measured, not assumed: ``surrogates.py`` (a concluded benchmark, in git history:
``docs/notes/benchmarks-concluded.md``) ranked parameter points by each surrogate on crops and
by bad 2.0 / 1.0 on whole held-out images, and ``docs/parameter-search.md`` reports the rank
correlations.

Array conventions: ``cost`` float32 ``(D, H, W)``, lower = better, disparities ``0 .. D - 1``
(those out of a scene's range already at the out-of-range cost); ``ground_truth`` float32
``(H, W)`` in pixels (unknown pixels hold any finite value; the caller masks them); the result
float32 ``(H, W)``, lower = better. ``temperature`` a positive float32 scalar.

Registry: :data:`SURROGATES` maps a name to its function; adding one is one function and one
entry. All take ``(cost, ground_truth, *, temperature)``.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from sswjax.stages.selection import soft_argmin

__all__ = ["DEFAULT_SURROGATE", "HUBER_DELTA", "SURROGATES", "smooth_l1", "soft_bad",
           "surrogate", "window_nll"]

HUBER_DELTA = 1.0
"""Where the smooth L1 turns from quadratic to linear, in pixels."""
WINDOW_FLOOR = 1e-6
"""The probability below which :func:`window_nll` stops growing (a wrong pixel with all its
mass far away costs ``-log(1e-6)`` = 13.8, not infinity)."""


def smooth_l1(error, *, delta: float = HUBER_DELTA):
    """Huber loss of an error (any shape): quadratic below ``delta`` pixels, linear above.

    >>> smooth_l1(jnp.array([0.5, 3.0])).tolist()
    [0.125, 2.5]
    """
    a = jnp.abs(error)
    return jnp.where(a < delta, 0.5 * a * a / delta, a - 0.5 * delta)


def soft_l1(cost, ground_truth, *, temperature):
    """Smooth L1 of the soft-argmin disparity (Kendall et al. 2017, GC-Net, eq. 1): the loss
    learned matchers regress with, and the search's loss before the surrogates were measured.

    It rewards a mean of the disparity distribution near the truth, so a bimodal distribution
    whose modes straddle the truth scores well although its winner is wrong.
    """
    return smooth_l1(soft_argmin(cost, temperature=temperature) - ground_truth)


def soft_bad(cost, ground_truth, *, temperature, threshold: float = 2.0, width: float = 0.25):
    """A smoothed bad-pixel indicator of the soft-argmin disparity:
    ``sigmoid((|d_soft - gt| - threshold) / width)``, which tends to the bad-``threshold``
    count as ``width`` tends to 0. Its gradient vanishes far from the threshold, on either
    side, so it learns from the pixels the metric could flip."""
    error = jnp.abs(soft_argmin(cost, temperature=temperature) - ground_truth)
    return jax.nn.sigmoid((error - threshold) / width)


def window_nll(cost, ground_truth, *, temperature, radius: float = 1.0):
    """Negative log of the probability the softmax puts within ``radius`` pixels of the truth:
    ``-log sum_{|d - gt| <= radius} p_d`` (floored at :data:`WINDOW_FLOOR`).

    The winner-takes-all is right (bad-``radius``) when the largest ``p_d`` falls in that
    window; this loss asks for the mass there, whatever its shape elsewhere, and so does not
    reward a mean between two wrong modes. The cross-entropy of learned matchers (e.g. the
    sub-pixel cross-entropy of PSMNet's successors) is the ``radius`` -> 0 case.
    """
    d = jnp.arange(cost.shape[0], dtype=cost.dtype)[:, None, None]
    log_p = jax.nn.log_softmax(-cost / temperature, axis=0)
    inside = jnp.abs(d - ground_truth[None]) <= radius
    log_window = jax.nn.logsumexp(jnp.where(inside, log_p, -jnp.inf), axis=0)
    return -jnp.maximum(log_window, jnp.log(WINDOW_FLOOR))


SURROGATES = {
    "soft_l1": soft_l1,
    "soft_bad2": functools.partial(soft_bad, threshold=2.0),
    "soft_bad1": functools.partial(soft_bad, threshold=1.0),
    "window_nll1": functools.partial(window_nll, radius=1.0),
    "window_nll2": functools.partial(window_nll, radius=2.0),
}
"""Name -> ``(cost, ground_truth, *, temperature) -> float32 (H, W)``."""
DEFAULT_SURROGATE = "soft_l1"
"""The loss of :func:`sswjax.search.objective.loss` unless told otherwise."""


def surrogate(name: str):
    """The surrogate named ``name`` (:data:`SURROGATES`); an unknown name raises
    ``ValueError`` listing the known ones."""
    try:
        return SURROGATES[name]
    except KeyError:
        raise ValueError(f"unknown surrogate {name!r}; known: {', '.join(SURROGATES)}") from None
