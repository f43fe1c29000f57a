"""Semi-global optimisation of a cost volume (Hirschmuller, "Stereo Processing by Semiglobal
Matching and Mutual Information", IEEE TPAMI 30(2), 2008).

Array conventions (whole module): cost volumes are float32 ``(D, H, W)``, disparity first,
lower is better; the guide is the left image, float32 ``(H, W, C)`` in [0, 1]; superpixel labels
are int32 ``(H, W)``; penalty maps are float32 ``(H, W)``: the penalty for the step that reaches
pixel ``p`` from its predecessor ``p - r`` on a path of direction ``r``.

Each path ``r`` accumulates, in scan order,

``L_r(p, d) = C(p, d) + min(L_r(p-r, d), L_r(p-r, d +- 1) + P1, min_k L_r(p-r, k) + P2)
- min_k L_r(p-r, k)``

(Eq. 13 of the paper), and the result is the sum over 4 paths (the two horizontal and the two
vertical directions) or 8 (and the four diagonals). A path starts fresh at the image border
(``L_r = C`` there). Penalties adapt to the guide as the paper suggests (Sec. 3.3): P2 falls
where the guide's intensity changes between ``p - r`` and ``p``, ``P2(p) = max(P1, P2 / (1 +
|I(p) - I(p - r)| / sigma))``; and, as CNES Pandora's segmentation-aware SGM does, both
penalties are scaled by ``segment_factor`` where ``p - r`` and ``p`` lie in different
superpixels, so that a disparity jump is cheaper across an object boundary than inside it.

Paths of one axis run in two ``lax.scan`` over that axis, forward then backward (the backward
scan adds its paths into the forward scan's output): over rows for the vertical and diagonal
paths, over columns for the horizontal ones, each on the volume transposed so that the scanned
axis leads.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_floating, check_rank
from sswjax.stages.pyramid import double_volume, halve_image, halve_volume

__all__ = ["PATH_COUNTS", "half_resolution_semi_global", "path_penalties", "semi_global"]

PATH_COUNTS = (4, 8)
"""Supported numbers of paths."""


def _shift(image: jax.Array, dy: int, dx: int) -> jax.Array:
    """``out[y, x] = image[y - dy, x - dx]`` on the last two axes, edge-replicated."""
    height, width = image.shape[-2:]
    pad = [(0, 0)] * (image.ndim - 2) + [(1, 1), (1, 1)]
    padded = jnp.pad(image, pad, mode="edge")
    return padded[..., 1 - dy : 1 - dy + height, 1 - dx : 1 - dx + width]


def path_penalties(
    guide: jax.Array,
    direction: tuple[int, int],
    *,
    p1,
    p2,
    sigma,
    labels: jax.Array | None = None,
    segment_factor=1.0,
) -> tuple[jax.Array, jax.Array]:
    """P1 and P2 for the step from ``p - r`` to ``p`` of every pixel, for one path direction.

    Parameters
    ----------
    guide : float32 (H, W, C)
        Left image in [0, 1]; the intensity change is the channel mean of absolute differences.
    direction : (int, int)
        ``r = (dy, dx)``, each in {-1, 0, 1}.
    p1, p2 : float or scalar array
        Penalties for a change of one disparity and of more than one.
    sigma : float or scalar array, > 0
        Intensity change (in [0, 1] units) that halves P2.
    labels : int32 (H, W), optional
        Superpixels; where ``p - r`` and ``p`` differ in label both penalties are multiplied by
        ``segment_factor``.
    segment_factor : float or scalar array, in [0, 1]

    Returns
    -------
    (float32 (H, W), float32 (H, W))
        P1 and P2 maps, ``P2 >= P1`` everywhere.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> guide = jnp.zeros((2, 3, 1)).at[:, 2:].set(1.0)      # a vertical edge
    >>> _, p2 = path_penalties(guide, (0, 1), p1=0.1, p2=1.0, sigma=1.0)
    >>> [round(float(v), 2) for v in p2[0]]                     # halved where it is crossed
    [1.0, 1.0, 0.5]
    """
    check_rank("guide", guide, 3)
    check_floating("guide", guide)
    dy, dx = direction
    change = jnp.abs(guide - jnp.moveaxis(_shift(jnp.moveaxis(guide, -1, 0), dy, dx), 0, -1))
    change = change.mean(axis=-1)
    p1_map = jnp.full(change.shape, p1, jnp.float32)
    p2_map = jnp.maximum(p1_map, p2 / (1.0 + change / sigma))
    if labels is not None:
        crossing = labels != _shift(labels, dy, dx)
        p1_map = jnp.where(crossing, p1_map * segment_factor, p1_map)
        p2_map = jnp.where(crossing, p2_map * segment_factor, p2_map)
    return p1_map, p2_map


def _path_step(previous, cost, p1, p2):
    """One step of Eq. 13 for a line of pixels: ``previous``, ``cost`` (D, N); ``p1``, ``p2`` (N,)."""
    lowest = previous.min(axis=0)
    inf = jnp.full_like(previous[:1], jnp.inf)
    neighbours = jnp.minimum(
        jnp.concatenate([previous[1:], inf]), jnp.concatenate([inf, previous[:-1]])
    )
    best = jnp.minimum(jnp.minimum(previous, neighbours + p1), lowest + p2)
    return cost + best - lowest


def _shift_line(line: jax.Array, dx: int) -> jax.Array:
    """``out[:, x] = line[:, x - dx]`` with zeros shifted in (a path starting at the border)."""
    if dx == 0:
        return line
    zeros = jnp.zeros_like(line[:, :1])
    if dx > 0:
        return jnp.concatenate([zeros, line[:, :-1]], axis=1)
    return jnp.concatenate([line[:, 1:], zeros], axis=1)


def _scan_axis(cost: jax.Array, penalties: dict, shifts: tuple[int, ...]) -> jax.Array:
    """Sum of the paths along axis 0 of ``cost`` (S, D, N), forward then backward.

    ``shifts`` are the per-step shifts along N of the paths (0 straight, +-1 diagonal);
    ``penalties[(forward, shift)]`` are their (P1, P2) maps, (S, N) each. The backward scan
    adds its paths to the forward one's output, which it reads and writes slice by slice, so
    the sum needs no second volume.
    """

    def run(reverse):
        def step(carry, inputs):
            line_cost, pens, partial = inputs
            new = []
            for k, shift in enumerate(shifts):
                p1, p2 = pens[shift]
                line = _path_step(_shift_line(carry[k], -shift if reverse else shift),
                                  line_cost, p1, p2)
                new.append(line)
                partial = partial + line
            return tuple(new), partial

        pens = {shift: penalties[(not reverse, shift)] for shift in shifts}
        start = tuple(jnp.zeros_like(cost[0]) for _ in shifts)
        return step, start, pens

    step, start, pens = run(False)
    nothing = jnp.zeros((cost.shape[0],), cost.dtype)  # the forward paths start the sum
    _, forward = lax.scan(step, start, (cost, pens, nothing))
    step, start, pens = run(True)
    _, total = lax.scan(step, start, (cost, pens, forward), reverse=True)
    return total


def semi_global(
    cost: jax.Array,
    guide: jax.Array,
    *,
    p1,
    p2,
    sigma=0.05,
    paths: int = 8,
    labels: jax.Array | None = None,
    segment_factor=1.0,
) -> jax.Array:
    """Semi-global aggregation of a cost volume: the sum of ``paths`` path costs (Eq. 13-14).

    Parameters
    ----------
    cost : float32 (D, H, W)
    guide : float32 (H, W, C)
        Left image in [0, 1], for the adaptive P2.
    p1, p2 : float or scalar array, >= 0
        Penalties (in the units of ``cost``) for a disparity change of one and of more.
    sigma : float or scalar array, > 0
        Intensity change that halves P2 (see :func:`path_penalties`).
    paths : {4, 8}
        Horizontal and vertical directions, and with 8 the diagonals too.
    labels : int32 (H, W), optional
        Superpixels: penalties scaled by ``segment_factor`` across their boundaries.
    segment_factor : float or scalar array, in [0, 1]

    Returns
    -------
    float32 (D, H, W), lower is better; ``paths`` times the scale of ``cost``.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> cost = jnp.ones((3, 4, 5)).at[1].set(0.0)
    >>> s = semi_global(cost, jnp.zeros((4, 5, 1)), p1=0.1, p2=0.5, paths=4)
    >>> s.shape, int(s.argmin(axis=0).max())
    ((3, 4, 5), 1)
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    check_rank("guide", guide, 3)
    if tuple(guide.shape[:2]) != tuple(cost.shape[1:]):
        raise ValueError(f"guide size {tuple(guide.shape[:2])} differs from cost size "
                         f"{tuple(cost.shape[1:])}")
    if paths not in PATH_COUNTS:
        raise ValueError(f"paths must be one of {PATH_COUNTS}, got {paths!r}")

    def penalties(direction, transpose):
        maps = path_penalties(guide, direction, p1=p1, p2=p2, sigma=sigma, labels=labels,
                              segment_factor=segment_factor)
        return tuple(m.T if transpose else m for m in maps)

    # Along rows (axis H): vertical and diagonal paths, carried as (D, W) lines; the transpose
    # to (H, D, W) moves whole rows, cheaply.
    shifts = (0,) if paths == 4 else (0, 1, -1)
    pens = {}
    for shift in shifts:
        pens[(True, shift)] = penalties((1, shift), False)
        pens[(False, shift)] = penalties((-1, -shift), False)
    total = _scan_axis(jnp.transpose(cost, (1, 0, 2)), pens, shifts).transpose(1, 0, 2)
    # Along columns (axis W): the horizontal paths, carried as (D, H) lines.
    pens = {(True, 0): penalties((0, 1), True), (False, 0): penalties((0, -1), True)}
    return total + _scan_axis(jnp.transpose(cost, (2, 0, 1)), pens, (0,)).transpose(1, 2, 0)


def half_resolution_semi_global(
    cost: jax.Array, guide: jax.Array, *, p1, p2, sigma=0.05, paths: int = 4, detail_weight=1.0
) -> jax.Array:
    """Semi-global optimisation at half resolution, added back to the full-resolution cost.

    The volume is halved in space and disparity (:func:`sswjax.stages.pyramid.halve_volume`),
    optimised by :func:`semi_global` with the halved guide, doubled back, and the
    full-resolution cost weighted by ``detail_weight`` is added: the coarse paths carry the
    evidence across weakly textured areas for an eighth of the work, and the fine cost decides
    between the two disparities and the four pixels that each coarse cell stands for. This is
    cross-scale aggregation in the sense of Zhang et al. (CVPR 2014), with SGM as the coarse
    scale's aggregator. A coarse disparity step is two fine ones, so ``p1`` acts on steps of 2.

    Parameters
    ----------
    cost : float32 (D, H, W)
    guide : float32 (H, W, C)
    p1, p2, sigma, paths
        As in :func:`semi_global`.
    detail_weight : float or scalar array, >= 0
        Weight of the full-resolution cost in the sum.

    Returns
    -------
    float32 (D, H, W), lower is better.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> cost = jnp.ones((6, 8, 10)).at[3].set(0.0)
    >>> out = half_resolution_semi_global(cost, jnp.zeros((8, 10, 1)), p1=0.1, p2=0.5)
    >>> out.shape, int(out.argmin(axis=0).min()), int(out.argmin(axis=0).max())
    ((6, 8, 10), 3, 3)
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    coarse = semi_global(halve_volume(cost), halve_image(guide), p1=p1, p2=p2, sigma=sigma,
                         paths=paths)
    return detail_weight * cost + double_volume(coarse, shape=cost.shape)
