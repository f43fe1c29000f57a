"""Confidence and validity of a disparity map, from what the pipeline already computed.

Array conventions (whole module): maps are ``(H, W)``; costs float32 (lower is better, as the
aggregated or optimised volume gives them); disparities float32 in pixels; confidence float32 in
[0, 1], higher = more reliable; validity uint8 bit masks.

The cues (:class:`ConfidenceCues`) come out of the running winner-takes-all fold
(:class:`~sswjax.stages.selection.Winners`) and the refinement, at no extra pass over the volume:

- ``cost`` and ``second``: the winner's cost ``c1`` and the smallest cost at a disparity not
  adjacent to it, ``c2`` (the runner-up of the cost curve's other valleys);
- ``lr_distance``: ``|d_L(x) - d_R(x - d_L(x))|`` in pixels of the winners of both views,
  ``+inf`` where ``x - d_L(x) < 0`` (no pixel of the right image to compare with;
  :func:`~sswjax.stages.checks.left_right_distance`, what the left-right check thresholds);
- ``initial``: the winner with its sub-pixel parabola, before filling and the median;
- ``lr_failed``: the pixels the left-right check rejected (then filled), with those the
  uniqueness and aggregated-view tests add (``checks.uniqueness_gap``,
  ``checks.aggregated_gap``); all False when the check is off;
- ``margin``: how far the matching cost's minimum stands out, before any optimiser:
  ``(c2' - c1') / B`` for the winner ``c1'`` and runner-up ``c2'`` (as above) of the aggregated
  cost as the optimiser reads it (its uint8 or int16 levels where it stores them), ``B`` the
  largest aggregated cost of a matching pixel (:func:`sswjax.graph.volume.cost_bound`);
  ``+inf`` without a runner-up. Without an optimiser it is ``(second - cost) / B``; with one,
  the semi-global sums carry the path penalties, which alone make a minimum stand out where
  the matching cost has none (a blank pair: the border's cost carried along every path), so
  it comes from a fold of its own over the stored volume (in the graphs that return the
  confidence only).

A pixel whose ``margin`` is at most :data:`AMBIGUITY_TOLERANCE` has no distinct cost minimum
(:func:`ambiguous`: a blank, saturated or flat-gradient region, a pattern repeated within the
range): every measure's value there is scaled by :data:`AMBIGUOUS_SCALE` (1/256), and
:func:`validity_mask` sets bit 4.

The measures (:data:`MEASURES`) turn them into a confidence in [0, 1]:

==============  ===================================================================================
``ratio``       ``1 - c1 / c2``: the peak-ratio (PKRN, Hu & Mordohai 2012) mapped to [0, 1]; 0 for
                two equal valleys, near 1 for a single sharp one (and 1 for any ``c2 > 0`` when
                ``c1 = 0``: a blank pair's winner; hence the ``margin`` above)
``lr``          ``1 / (1 + lr_distance)``: 1 when both views agree, 0 without a match
``agreement``   ``1 / (1 + |d - initial|)``: how much filling and the median moved the winner
``combined``    the product of the three (the default, the best of the sparsification curves
                in ``benchmarks/sparsification.py``: ``docs/confidence.md``)
==============  ===================================================================================

Validity bits (:func:`validity_mask`; 0 = valid):

- bit 0 (``LR_FAILED`` = 1): the pixel failed the left-right check and holds a filled value;
- bit 1 (``LEFT_BAND`` = 2): ``x - d < 0`` for the final disparity ``d`` in the image's own
  column frame: the matching right pixel would lie left of the right image (or, with a
  negative disparity range, ``x - d > W - 1``: right of it);
- bit 2 (``LOW_CONFIDENCE`` = 4): confidence below the threshold given;
- bit 3 (``OUTSIDE_VIEW`` = 8): outside the rectified view, set by :mod:`sswjax.api.rectify`
  (not by :func:`validity_mask`): rectification filled the pixel, or its match, from outside
  the raw image;
- bit 4 (``AMBIGUOUS`` = 16): no distinct cost minimum (:func:`ambiguous`; its confidence is at
  most 1/256, so bit 2 comes with it at any threshold above that).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from sswjax._checks import check_floating, check_rank, check_same_shape

LR_FAILED = 1
"""Validity bit 0: failed the left-right check, the value was filled."""
LEFT_BAND = 2
"""Validity bit 1: ``x - d < 0`` (or ``x - d > W - 1``), no match inside the right image."""
LOW_CONFIDENCE = 4
"""Validity bit 2: confidence below the threshold."""
OUTSIDE_VIEW = 8
"""Validity bit 3: outside the rectified view (the pixel or its match lies outside the raw view)."""
AMBIGUOUS = 16
"""Validity bit 4: no distinct cost minimum (:func:`ambiguous`)."""

AMBIGUITY_TOLERANCE = 0.005
"""The largest ``margin`` cue (runner-up minus winner of the matching cost, as a fraction of its
bound) at which the minimum does not stand out: below one uint8 level of the stored cost
(``2 / 255`` of the bound), and a small share of textured pixels (``docs/confidence.md``)."""

AMBIGUOUS_SCALE = 1 / 256
"""What an ambiguous pixel's confidence is multiplied by: below one 8-bit level, so below every
useful threshold, while such pixels keep their measure's order among themselves. On six trainingQ
scenes (``accurate``) the flagged pixels erred 2-3x as often as the average, yet the semi-global
paths got most of them right, and the measure still ranks them: setting them to 0 instead raised
the mean sparsification area from 3.73 to 4.00, scaling them by 1/256 to 3.89
(``docs/confidence.md``)."""

DEFAULT_MEASURE = "combined"
DEFAULT_THRESHOLD = 0.05
"""Default low-confidence threshold (bit 2): see ``docs/confidence.md``."""


class ConfidenceCues(NamedTuple):
    """What the confidence measures read, all ``(H, W)``: see the module docstring.

    ``margin`` may be None (cues built by hand): then no pixel is judged ambiguous."""

    cost: jax.Array
    second: jax.Array
    lr_distance: jax.Array
    initial: jax.Array
    lr_failed: jax.Array
    margin: jax.Array | None = None


def ambiguous(cues: ConfidenceCues) -> jax.Array:
    """Where the matching cost has no distinct minimum: ``margin <= AMBIGUITY_TOLERANCE``.

    Parameters
    ----------
    cues : ConfidenceCues

    Returns
    -------
    bool (H, W); all False when ``cues.margin`` is None.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> one = jnp.ones((1, 3))
    >>> margin = jnp.array([[0.0, 0.004, 0.2]])
    >>> ambiguous(ConfidenceCues(0 * one, margin, one, one, one > 2, margin)).tolist()
    [[True, True, False]]
    """
    if cues.margin is None:
        return jnp.zeros(jnp.shape(cues.cost), bool)
    return cues.margin <= AMBIGUITY_TOLERANCE


def ratio_confidence(cost: jax.Array, second: jax.Array) -> jax.Array:
    """``1 - c1 / c2`` in [0, 1]: 1 without a runner-up (``c2 = inf``), 0 when ``c2 <= c1``.

    Parameters
    ----------
    cost, second : float32 (H, W), ``cost >= 0``

    Returns
    -------
    float32 (H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> ratio_confidence(jnp.array([1.0, 1.0, 0.0, 2.0]), jnp.array([4.0, jnp.inf, 0.0, 2.0])).tolist()
    [0.75, 1.0, 0.0, 0.0]
    """
    margin = jnp.where(second > cost, second - cost, 0.0)
    ratio = jnp.where(jnp.isinf(second), 1.0, margin / jnp.where(second > 0, second, 1.0))
    return jnp.clip(jnp.where(jnp.isnan(ratio), 0.0, ratio), 0.0, 1.0).astype(jnp.float32)


def _ratio(cues: ConfidenceCues, disparity: jax.Array) -> jax.Array:
    return ratio_confidence(cues.cost, cues.second)


def _lr(cues: ConfidenceCues, disparity: jax.Array) -> jax.Array:
    return 1.0 / (1.0 + cues.lr_distance)


def _agreement(cues: ConfidenceCues, disparity: jax.Array) -> jax.Array:
    return 1.0 / (1.0 + jnp.abs(disparity - cues.initial))


def _combined(cues: ConfidenceCues, disparity: jax.Array) -> jax.Array:
    return _ratio(cues, disparity) * _lr(cues, disparity) * _agreement(cues, disparity)


MEASURES = {"ratio": _ratio, "lr": _lr, "agreement": _agreement, "combined": _combined}
"""Confidence measures by name: ``fn(cues, disparity) -> float32 (H, W)`` in [0, 1]."""


def confidence(cues: ConfidenceCues, disparity: jax.Array, *, measure: str = DEFAULT_MEASURE) -> jax.Array:
    """Confidence of each pixel of the final disparity map.

    Parameters
    ----------
    cues : ConfidenceCues
        Each float32 (H, W) (``lr_failed`` bool).
    disparity : float32 (H, W)
        The final map (after filling and the median).
    measure : str
        A key of :data:`MEASURES`.

    Returns
    -------
    float32 (H, W) in [0, 1], higher = more reliable; at most :data:`AMBIGUOUS_SCALE` wherever
    :func:`ambiguous`.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> one = jnp.ones((1, 2))
    >>> cues = ConfidenceCues(one, 4 * one, jnp.array([[0.0, 1.0]]), 2 * one, one > 2)
    >>> confidence(cues, 2 * one).tolist()
    [[0.75, 0.375]]
    >>> confidence(cues._replace(margin=jnp.array([[0.0, 0.5]])), 2 * one).tolist()
    [[0.0029296875, 0.375]]
    """
    if measure not in MEASURES:
        raise ValueError(f"unknown confidence measure {measure!r}; choose from {', '.join(MEASURES)}")
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    for name, cue in zip(cues._fields, cues):
        if cue is not None:
            check_same_shape("disparity", disparity, name, cue)
    value = MEASURES[measure](cues, disparity)
    value = jnp.where(ambiguous(cues), AMBIGUOUS_SCALE * value, value)
    return jnp.clip(value, 0.0, 1.0).astype(jnp.float32)


def validity_mask(disparity, confidence, lr_failed, *, threshold, ambiguous=None) -> jax.Array:
    """The validity bits of each pixel (0 = valid; module docstring for the bits).

    The left band is judged from ``disparity`` as given, in the image's own columns: pass the
    final map in the frame of the original image (after any offset of the range).

    Parameters
    ----------
    disparity : float32 (H, W), pixels
    confidence : float32 (H, W) in [0, 1]
    lr_failed : bool (H, W)
    threshold : float in [0, 1]
        Confidence strictly below it sets bit 2 (0 never sets it).
    ambiguous : bool (H, W), optional
        Where the cost has no distinct minimum (:func:`ambiguous`): sets bit 4.

    Returns
    -------
    uint8 (H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.array([[2.0, 1.0, 1.0, 1.0]])
    >>> c = jnp.array([[0.9, 0.9, 0.05, 0.9]])
    >>> f = jnp.array([[False, False, False, True]])
    >>> validity_mask(d, c, f, threshold=0.1).tolist()
    [[2, 0, 4, 1]]
    >>> validity_mask(d, 0 * c, f, threshold=0.1, ambiguous=c < 0.5).tolist()
    [[6, 4, 20, 5]]
    """
    check_rank("disparity", disparity, 2)
    check_same_shape("disparity", disparity, "confidence", confidence)
    check_same_shape("disparity", disparity, "lr_failed", lr_failed)
    if ambiguous is not None:
        check_same_shape("disparity", disparity, "ambiguous", ambiguous)
    if not 0.0 <= float(threshold) <= 1.0:
        raise ValueError(f"low-confidence threshold must be in [0, 1], got {threshold}")
    columns = jnp.arange(disparity.shape[1], dtype=jnp.float32)[None, :]
    # Negative ranges (sswjax.api.ranges) can point right of the right image too.
    band = (columns - disparity < 0) | (columns - disparity > disparity.shape[1] - 1)
    bits = (jnp.where(lr_failed, LR_FAILED, 0) | jnp.where(band, LEFT_BAND, 0)
            | jnp.where(confidence < threshold, LOW_CONFIDENCE, 0))
    if ambiguous is not None:
        bits |= jnp.where(ambiguous, AMBIGUOUS, 0)
    return bits.astype(jnp.uint8)
