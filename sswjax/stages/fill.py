"""Guided fills of the pixels the left-right check rejects: a weighted median and a vote.

Eq. (9) of the paper fills a rejected pixel with "the median of valid neighbours"; our reading
(:func:`sswjax.stages.background.fill_invalid`) takes the background disparity of the row and
then a plain median over a square. Here the median is *weighted* by the left image instead, as
in the post-processing of Rhemann, Hosni, Bleyer, Rother & Gelautz, "Fast Cost-Volume Filtering
for Visual Correspondence and Beyond" (CVPR 2011): the neighbours that share the pixel's colour
(so probably its surface) decide, across depth edges the other side does not.

The weighted median is computed as in Ma, He, Wei, Sun & Wu, "Constant Time Weighted Median
Filtering for Stereo Matching and Beyond" (ICCV 2013): disparities are cut into integer bins,
each bin's indicator map is smoothed by the guided filter (He, Sun & Tang, TPAMI 2013: box
sums, O(1) per pixel and bin), and each pixel takes the first bin where the running sum of the
smoothed indicators over increasing disparities reaches ``quantile`` times their total,
refined to sub-pixel by where in that bin the total is reached.

:func:`vote_fill` is the cheap relative: each rejected pixel chooses among three candidates
only (the median fill and the nearest valid disparities left and right on its row), by the
intensity-weighted count of sampled neighbours that agree with each.

Array conventions (whole module): disparity maps float32 ``(H, W)`` in pixels, validity bool
``(H, W)``, guide images float32 ``(H, W, C)`` (C in {1, 3}) or ``(H, W)`` in [0, 1].
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_floating, check_rank, check_same_shape
from sswjax._checks import check_guide, check_positive
from sswjax.stages.baselines import box_mean
from sswjax.stages.guided import guided_filter_fn
from sswjax.stages.background import fill_background, fill_invalid, nearest_valid

SOURCES = ("filled", "valid")
"""What the histogram counts: every pixel of the background-filled map, or the valid ones."""


def weighted_median_fill(
    disparity: jax.Array,
    valid: jax.Array,
    *,
    radius: int,
    guide: jax.Array | None = None,
    eps=1e-3,
    quantile=0.5,
    source: str = "filled",
    left_band: bool = True,
    band_fit: int = 0,
) -> jax.Array:
    """Fill the invalid pixels with a guided weighted median of their neighbours' disparities.

    First the background fill (:func:`~sswjax.stages.background.fill_background`, the row's
    nearer-background valid disparity, with the left-band rule when ``left_band``) gives every
    pixel a disparity; then each invalid pixel takes the weighted ``quantile`` of the integer
    disparities ``round(d)`` in its ``(2r+1)^2`` window, weighted by the guided filter's kernel
    on ``guide`` (a plain box, so an unweighted quantile, without a guide). Valid pixels keep
    their disparity. Where the weights of the counted neighbours sum to less than 0.05 (no
    valid neighbour near, with ``source="valid"``) the background fill stays.

    Cost: one guided filter (``2C + 2`` box means) per integer disparity up to the map's
    maximum, in a ``lax.fori_loop`` (constant memory in the number of bins).

    Parameters
    ----------
    disparity : float32 (H, W)
        Disparities in pixels, >= 0.
    valid : bool (H, W)
        True where the disparity passed the left-right check.
    radius : int >= 1, keyword-only
        Window radius of the weights (the guided filter's ``r``).
    guide : float32 (H, W, C) or (H, W), C in {1, 3}, values in [0, 1], optional
        The left image; ``None`` for box weights.
    eps : float > 0
        Guided-filter regularisation: colour edges with variance well above ``eps`` separate
        the weights.
    quantile : float in (0, 1]
        0.5 the weighted median; below it leans towards smaller (background) disparities.
    source : {"filled", "valid"}
        The histogram counts every pixel of the background-filled map (``"filled"``) or only
        the valid ones (``"valid"``).
    left_band, band_fit : bool, int
        Passed to :func:`~sswjax.stages.background.fill_background`.

    Returns
    -------
    float32 (H, W), dense; equal to ``disparity`` where ``valid``. An invalid pixel gets the
    chosen bin ``k`` plus ``s - 1/2``, ``s`` in [0, 1] the share of the bin's weight needed to
    reach the quantile; or its background fill where that rounds to ``k`` (keeping its own
    sub-pixel part) or where the weights are unusable.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.array([[1., 1., 1., 0., 5., 5.]] * 3)
    >>> v = jnp.array([[True, True, True, False, True, True]] * 3)
    >>> weighted_median_fill(d, v, radius=1, left_band=False)[1].tolist()
    [1.0, 1.0, 1.0, 1.0, 5.0, 5.0]
    >>> weighted_median_fill(d, v, radius=1)[1].tolist()  # left band: x = 3 < d = 5
    [1.0, 1.0, 1.0, 5.0, 5.0, 5.0]
    """
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    check_same_shape("disparity", disparity, "valid", valid)
    if isinstance(radius, bool) or not isinstance(radius, int) or radius < 1:
        raise ValueError(f"radius must be an integer >= 1, got {radius!r}")
    if source not in SOURCES:
        raise ValueError(f"source must be one of {SOURCES}, got {source!r}")
    check_positive("eps", eps)
    if isinstance(quantile, (int, float)) and not 0 < quantile <= 1:
        raise ValueError(f"quantile must be in (0, 1], got {quantile!r}")
    if guide is None:
        def smooth(p):
            return box_mean(p, radius)
    else:
        check_guide(guide, disparity, channels=(1, 3))
        smooth = guided_filter_fn(guide, radius, eps)

    filled = fill_background(disparity.astype(jnp.float32), valid, left_band=left_band,
                             band_fit=band_fit)
    bins = jnp.maximum(jnp.round(filled), 0).astype(jnp.int32)
    counted = jnp.ones(filled.shape, jnp.float32) if source == "filled" else valid.astype(jnp.float32)
    total = smooth(counted)
    target = quantile * total

    def add_bin(k, state):
        running, chosen, offset = state
        previous = running
        running = running + smooth(jnp.where(bins == k, counted, 0.0))
        crossing = (chosen < 0) & (running >= target)
        # Where in the bin [k - 1/2, k + 1/2) the target falls, the bin's weight spread evenly
        # over it (the grouped-data median): a sub-pixel value at no extra filtering.
        share = (target - previous) / jnp.maximum(running - previous, 1e-6)
        offset = jnp.where(crossing, jnp.clip(share, 0.0, 1.0) - 0.5, offset)
        chosen = jnp.where(crossing, k, chosen)
        return running, chosen, offset

    start = (jnp.zeros(filled.shape, jnp.float32), jnp.full(filled.shape, -1, jnp.int32),
             jnp.zeros(filled.shape, jnp.float32))
    _, chosen, offset = lax.fori_loop(0, jnp.max(bins) + 1, add_bin, start)
    # Guided-filter weights can be negative, so the running sum may never reach the target
    # (chosen < 0), and the total is near 0 where no counted pixel is near: keep the fill there.
    usable = (chosen >= 0) & (total >= 0.05)
    # Where the pixel's own background-filled disparity lies in the chosen bin, it is kept: it
    # has the sub-pixel precision that the bin lacks.
    median = jnp.where(chosen == bins, filled, chosen.astype(jnp.float32) + offset)
    return jnp.where(valid | ~usable, filled, median)


def vote_fill(
    disparity: jax.Array,
    valid: jax.Array,
    *,
    guide: jax.Array,
    median_radius: int,
    radius: int = 8,
    step: int = 4,
    sigma=0.2,
    tolerance=2.0,
    median: str = "separable",
    band_fit: int = 0,
) -> jax.Array:
    """Fill the invalid pixels by an intensity-weighted vote among three candidates.

    The candidates of an invalid pixel are its value in the left-band median fill
    (:func:`~sswjax.stages.background.fill_invalid` with ``left_band=True``), and the nearest
    valid disparities to its left and to its right on its row (the two surfaces an occlusion
    lies between; the median fill where a side has none). Each candidate's support is the sum,
    over the samples ``(y + i step, x + j step)`` of the ``(2r+1)^2`` window
    (``|i step|, |j step| <= r``), of the weight ``1 / (1 + 3 |I(q) - I(p)| / sigma)`` of the
    samples ``q`` whose median-filled disparity is within ``tolerance`` of it, ``I`` the
    guide's channel mean; the best-supported candidate wins (the median fill on ties). Valid
    pixels keep their disparity. A cheap stand-in for the weighted median of
    :func:`weighted_median_fill` (Rhemann et al. 2011): the same idea, that neighbours of the
    pixel's colour tell which surface it belongs to, at three candidates instead of every
    disparity. Cost: ``(2 floor(r / step) + 1)^2`` shifted planes, each compared with the
    three candidates, in one fused pass.

    Parameters
    ----------
    disparity : float32 (H, W)
        Disparities in pixels, >= 0.
    valid : bool (H, W)
        True where the disparity passed the left-right check.
    guide : float32 (H, W, C) or (H, W), C in {1, 3}, values in [0, 1], keyword-only
        The left image.
    median_radius : int >= 0, keyword-only
        Radius of the median fill that makes the first candidate and the votes.
    radius, step : int >= 1
        The sampled window: offsets that are multiples of ``step`` up to ``radius``.
    sigma : float > 0
        Intensity difference (in [0, 1] units) at which a sample's weight falls to 1/4.
    tolerance : float >= 0
        How close (pixels) a sample's disparity must be to a candidate to vote for it.
    median : {"square", "separable"}
        The median of the median fill.
    band_fit : int >= 0
        The left band's line fit (:func:`~sswjax.stages.background.fill_background`).

    Returns
    -------
    float32 (H, W), dense; equal to ``disparity`` where ``valid``.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> d = jnp.array([[1., 1., 1., 0., 0., 5., 5., 5.]] * 5)
    >>> v = d > 0
    >>> guide = jnp.array([[0., 0., 0., 0., 1., 1., 1., 1.]] * 5)  # x = 3 looks like the left
    >>> vote_fill(d, v, guide=guide, median_radius=0, radius=2, step=1)[2].tolist()
    [1.0, 1.0, 1.0, 1.0, 5.0, 5.0, 5.0, 5.0]
    """
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    check_same_shape("disparity", disparity, "valid", valid)
    check_guide(guide, disparity, channels=(1, 3))
    for name, value in (("radius", radius), ("step", step)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    check_positive("sigma", sigma)
    if isinstance(tolerance, (int, float)) and tolerance < 0:
        raise ValueError(f"tolerance must be >= 0, got {tolerance!r}")
    disparity = disparity.astype(jnp.float32)
    filled = fill_invalid(disparity, valid, radius=median_radius, left_band=True, median=median,
                          band_fit=band_fit)
    candidates = [filled, *(jnp.where(jnp.isfinite(side), side, filled)
                             for side in nearest_valid(disparity, valid))]
    intensity = guide.mean(axis=-1) if guide.ndim == 3 else guide
    reach = (radius // step) * step
    height, width = disparity.shape
    padded_d = jnp.pad(filled, reach, mode="edge")
    padded_i = jnp.pad(intensity, reach, mode="edge")
    support = [jnp.zeros((height, width), jnp.float32) for _ in candidates]
    scale = 3.0 / sigma
    for dy in range(-reach, reach + 1, step):
        for dx in range(-reach, reach + 1, step):
            window = (slice(reach + dy, reach + dy + height), slice(reach + dx, reach + dx + width))
            weight = 1.0 / (1.0 + jnp.abs(padded_i[window] - intensity) * scale)
            sample = padded_d[window]
            support = [total + jnp.where(jnp.abs(sample - candidate) <= tolerance, weight, 0.0)
                       for total, candidate in zip(support, candidates)]
    best, best_support = candidates[0], support[0]
    for candidate, total in zip(candidates[1:], support[1:]):
        better = total > best_support
        best = jnp.where(better, candidate, best)
        best_support = jnp.where(better, total, best_support)
    return jnp.where(valid, disparity, best)
