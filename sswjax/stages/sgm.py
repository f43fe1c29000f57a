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

Paths of one axis run in two loops over that axis, forward then backward, each adding its
paths line by line into one loop-carried sum updated in place: over columns for the horizontal
paths first, on the volume's planes transposed, then over rows for the vertical and diagonal
ones into that sum, on the volume as it is. A line is a (D, N) slice, D contiguous runs. By
default (``cost_bound`` given, ``SemiGlobal.dtype = "int16"``) the paths run on the cost
quantised to int16, as OpenCV's SGBM does. :func:`semi_global_sums` returns the sum as the
scans leave it (:class:`PathSums`, int16), which the selection reads plane by plane, converting
as it goes; :func:`semi_global` returns it as a float32 volume. How the cost is stored for
them is :mod:`sswjax.stages.quantisation`.
"""

from __future__ import annotations


import jax
import jax.numpy as jnp
from jax import lax

from sswjax._checks import check_floating, check_integer, check_rank, check_same_shape
from sswjax.stages.paths import Seeds, scan_axis, scan_band_axis, seeded_scan_axis
from sswjax.stages.quantisation import PathSums, as_volume, quantisation, quantise, quantise_cost

__all__ = ["PATH_COUNTS", "path_penalties", "semi_global", "semi_global_sums", "vertical_shifts"]

PATH_COUNTS = (4, 8)
"""Supported numbers of paths."""


def vertical_shifts(paths: int) -> tuple[int, ...]:
    """The per-row column shifts of the paths scanned along the rows: the vertical one, and
    with 8 paths the two diagonals (one :class:`~sswjax.stages.paths.Seeds` line each)."""
    return (0,) if paths == 4 else (0, 1, -1)


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
    # The channels added one by one, not reduced: XLA CPU hands a reduction to its XNNPACK
    # fusion, whose own threads made whole runs up to 2x slower on 2 cores (docs/notes/speed.md).
    change = sum(change[..., c] for c in range(change.shape[-1])) / change.shape[-1]
    p1_map = jnp.full(change.shape, p1, jnp.float32)
    p2_map = jnp.maximum(p1_map, p2 / (1.0 + change / sigma))
    if labels is not None:
        crossing = labels != _shift(labels, dy, dx)
        p1_map = jnp.where(crossing, p1_map * segment_factor, p1_map)
        p2_map = jnp.where(crossing, p2_map * segment_factor, p2_map)
    return p1_map, p2_map


def semi_global(cost: jax.Array, guide: jax.Array, **options) -> jax.Array:
    """Semi-global aggregation of a cost volume: the sum of ``paths`` path costs (Eq. 13-14).

    Parameters
    ----------
    cost : float32 (D, H, W)
    guide : float32 (H, W, C)
    **options
        Keyword-only, those of :func:`semi_global_sums` (``p1``, ``p2``, ``sigma``, ``paths``,
        ``labels``, ``segment_factor``, ``cost_bound``).

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
    return as_volume(semi_global_sums(cost, guide, **options))


def semi_global_sums(
    cost: jax.Array,
    guide: jax.Array,
    *,
    p1,
    p2,
    sigma=0.05,
    paths: int = 8,
    labels: jax.Array | None = None,
    segment_factor=1.0,
    cost_bound=None,
    cost_levels=None,
    starts: jax.Array | None = None,
    seeds: Seeds | None = None,
) -> PathSums:
    """:func:`semi_global` as the scans leave it: int16 sums with ``cost_bound``, unconverted.

    :func:`as_volume` of the result is the float32 (D, H, W) volume; :func:`sum_planes` reads
    planes of it without writing that volume.

    Parameters
    ----------
    cost : float32 (D, H, W)
        Or, with ``cost_bound``, the volume :func:`quantise_cost` stored with the
        :func:`quantisation` of the same options (int16, or uint8 with ``cost_levels``).
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
    cost_bound : float or scalar array, > 0, optional
        Run the paths in int16, as OpenCV's SGBM does, instead of float32: the volume the scans
        read, carry and write is half the bytes, and XLA CPU runs the int16 recursion 3x faster
        (the scans are bound by memory traffic). Costs are clipped to ``[0, 2 * cost_bound]``
        (``cost_bound`` is the largest cost a matching pixel can have: values up to twice it,
        such as out-of-range disparities, stay above every real cost) and stored as
        :func:`quantisation` says (about 3000 int16 steps per cost unit for 4 paths and a bound
        of 1); ``scale`` of the result converts back to cost units. Not differentiable: leave
        it ``None`` (float32) for gradients.
    cost_levels : {None, 255}
        With ``cost_bound``: None stores the cost the scans read in int16; 255 stores it in
        uint8 (the paths and sums stay int16): the volume that the transpose and the four
        scans read is half the bytes again.
    starts : int32 (H, W), optional
        ``cost`` is a band volume (:mod:`sswjax.stages.bands`): plane ``k`` of pixel ``p`` is
        disparity ``starts[p] + k``. The recursion is Eq. 13 in those absolute disparities:
        each step realigns the predecessor's band to the pixel's, and a disparity outside the
        predecessor's band is reached only by the P2 jump (the tSGM of Rothermel et al. 2012).
        With every start 0 it is the full volume's recursion.
    seeds : Seeds, optional
        The vertical and diagonal paths carried in from the windows above and below
        (:mod:`sswjax.stages.paths`; lines (D, W) in the sums' dtype); not with ``starts``.

    Returns
    -------
    PathSums
        ``sums`` (D, H, W), int16 with ``cost_bound``, else float32; with ``seeds``, their
        states captured in ``carried``.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> cost = jnp.ones((3, 4, 5)).at[1].set(0.0)
    >>> s = semi_global_sums(cost, jnp.zeros((4, 5, 1)), p1=0.1, p2=0.5, paths=4, cost_bound=1.0)
    >>> s.sums.shape, s.sums.dtype, int(s.sums.argmin(axis=0).max())
    ((3, 4, 5), dtype('int16'), 1)
    """
    check_rank("cost", cost, 3)
    check_rank("guide", guide, 3)
    if tuple(guide.shape[:2]) != tuple(cost.shape[1:]):
        raise ValueError(f"guide size {tuple(guide.shape[:2])} differs from cost size "
                         f"{tuple(cost.shape[1:])}")
    if paths not in PATH_COUNTS:
        raise ValueError(f"paths must be one of {PATH_COUNTS}, got {paths!r}")
    if starts is not None:
        check_integer("starts", starts)
        check_same_shape("starts", starts, "cost plane", cost[0])
        if seeds is not None:
            raise ValueError("seeds carry the paths of a full volume, not of a band (starts)")

    if cost_bound is None:
        check_floating("cost", cost)
        quant, work = None, cost
    else:
        quant = quantisation(cost_bound=cost_bound, paths=paths, p1=p1, p2=p2,
                             cost_levels=cost_levels)
        stored = jnp.dtype(jnp.int16 if cost_levels is None else jnp.uint8)
        if jnp.issubdtype(cost.dtype, jnp.floating):
            work = quantise_cost(cost, quant)
        elif cost.dtype == stored:
            work = cost
        else:
            raise ValueError(f"cost must be float32, or {stored} as quantise_cost stores it "
                             f"with these options, got {cost.dtype}")
    scale = None if quant is None else quant.scale
    levels_step = None if quant is None else quant.step

    def penalties(direction, transpose):
        maps = path_penalties(guide, direction, p1=p1, p2=p2, sigma=sigma, labels=labels,
                              segment_factor=segment_factor)
        if scale is not None:
            maps = tuple(quantise(m, scale) for m in maps)
        return tuple(m.T if transpose else m for m in maps)

    # Vertical and diagonal paths along H on the volume as it is, (D, N = W) lines; the
    # horizontal ones along W on its planes transposed, (D, W, H), (D, N = H) lines.
    shifts = vertical_shifts(paths)
    pens = {}
    for shift in shifts:
        pens[(True, shift)] = penalties((1, shift), False)
        pens[(False, shift)] = penalties((-1, -shift), False)
    pens_h = {(True, 0): penalties((0, 1), True), (False, 0): penalties((0, -1), True)}
    # The horizontal paths first, into a zero sum, then the others into that sum transposed
    # back. The transposed copy is made before the loops, so the float32 volume is released.
    work, columns = lax.optimization_barrier((work, jnp.transpose(work, (0, 2, 1))))
    sum_dtype = jnp.float32 if scale is None else jnp.int16
    carried = None
    if starts is None:
        total = scan_axis(columns, pens_h, (0,), None, levels_step=levels_step, dtype=sum_dtype)
        if seeds is None:
            total = scan_axis(work, pens, shifts, jnp.transpose(total, (0, 2, 1)),
                              levels_step=levels_step)
        else:
            total, carried = seeded_scan_axis(work, pens, shifts, jnp.transpose(total, (0, 2, 1)),
                                              seeds, levels_step=levels_step)
    else:
        total = scan_band_axis(columns, pens_h, (0,), None, starts.T,
                               levels_step=levels_step, dtype=sum_dtype)
        total = scan_band_axis(work, pens, shifts, jnp.transpose(total, (0, 2, 1)), starts,
                               levels_step=levels_step)
    return PathSums(total, scale, carried)
