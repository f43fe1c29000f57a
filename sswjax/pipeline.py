"""The SSW pipeline: cost, segment-side-window aggregation, selection and refinement composed.

Array conventions (whole module): the pure functions take images float32 ``(H, W, C)`` with
C in {1, 3} and values in [0, 1], a :class:`~sswjax.params.Params` pytree and a static
``ndisp``; they return float32 ``(H, W)`` disparities in pixels, dense, in [0, ndisp - 1].
:func:`match` is the NumPy front door: it accepts uint8, uint16 or float images, gray or colour,
validates them and returns a NumPy array.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from sswjax._checks import check_floating, check_positive_int, check_rank, check_same_shape
from sswjax.aggregation import aggregate_cost
from sswjax.cost import MatchingFeatures, matching_cost, matching_features
from sswjax.filters import side_window_median_filter
from sswjax.params import Params
from sswjax.refinement import fill_invalid, left_right_consistency
from sswjax.segments import slic, slic_grid_shape
from sswjax.selection import Winners, fold_winners, no_winners, parabola_refine


STAGES = ("cost", "superpixels", "aggregation", "selection", "refinement")
"""Named scopes (``jax.named_scope``) of the stages in the compiled graph: profiler traces
attribute each operation to one of them (``benchmarks/speed.py``)."""


def _check_pair(left, right, ndisp: int) -> None:
    check_rank("left", left, 3)
    check_floating("left", left)
    check_same_shape("left", left, "right", right)
    if left.shape[-1] not in (1, 3):
        raise ValueError(f"images must have 1 or 3 channels, got shape {tuple(left.shape)}")
    check_positive_int("ndisp", ndisp)
    if ndisp >= left.shape[1]:
        raise ValueError(f"ndisp must be smaller than the image width {left.shape[1]}, got {ndisp}")


def superpixels(left: jax.Array, params: Params) -> tuple[jax.Array, int]:
    """SLIC labels of the left image and their static count (0 when no segment term is used).

    Parameters
    ----------
    left : float32 (H, W, C)
    params : Params

    Returns
    -------
    (int32 (H, W), int)
    """
    static = params.static
    if static.n_segments == 0 or static.aggregation != "ssw":
        return jnp.zeros(left.shape[:2], jnp.int32), 0
    height, width = left.shape[:2]
    ny, nx = slic_grid_shape(height, width, static.n_segments)
    image = left if left.shape[-1] == 3 else jnp.repeat(left, 3, axis=-1)
    labels = slic(
        image,
        n_segments=static.n_segments,
        compactness=params.dynamic.slic_compactness,
        iterations=static.slic_iterations,
    )
    return labels, ny * nx


def _aggregate_slices(
    features: MatchingFeatures,
    left: jax.Array,
    labels: jax.Array,
    num_segments: int,
    first,
    count: int,
    params: Params,
) -> jax.Array:
    """Eq. (5) and (7) for disparities ``first .. first + count - 1``: cost, then aggregation.

    Every aggregator acts on each disparity slice independently (the guide and superpixels are
    shared), so slices computed in chunks equal those of the whole volume.
    """
    static, dynamic = params.static, params.dynamic
    with jax.named_scope(STAGES[0]):
        cost = matching_cost(
            features,
            first,
            count,
            tad_weight=dynamic.tad_weight,
            gradient_weight=dynamic.gradient_weight,
            census_weight=dynamic.census_weight,
            tad_truncation=dynamic.tad_truncation,
            gradient_truncation=dynamic.gradient_truncation,
        )
    with jax.named_scope(STAGES[2]):
        return aggregate_cost(
            cost,
            left,
            radius=static.aggregation_radius,
            iterations=static.aggregation_iterations,
            window_selection=static.window_selection,
            method=static.aggregation,
            labels=labels,
            num_segments=num_segments,
            segment_weight=dynamic.segment_weight,
        )


def _features(left, right, params: Params):
    static = params.static
    with jax.named_scope(STAGES[0]):
        features = matching_features(
            left, right, census_height=static.census_height, census_width=static.census_width
        )
    with jax.named_scope(STAGES[1]):
        labels, num_segments = superpixels(left, params)
    return features, labels, num_segments


def aggregated_cost(left: jax.Array, right: jax.Array, params: Params, *, ndisp: int) -> jax.Array:
    """Eq. (5)-(7): matching cost, superpixels and segment-side-window aggregation.

    The whole volume at once: what the differentiable parameter search and analyses use.

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    params : Params
    ndisp : int, 1 <= ndisp < W

    Returns
    -------
    float32 (ndisp, H, W), lower is better.
    """
    _check_pair(left, right, ndisp)
    features, labels, num_segments = _features(left, right, params)
    return _aggregate_slices(features, left, labels, num_segments, 0, ndisp, params)


def _refine(winners: Winners, params: Params, ndisp) -> jax.Array:
    """Eq. (8)-(9) after the winners are known: parabola, LR check, filling, side-window median."""
    static = params.static
    with jax.named_scope(STAGES[3]):
        if static.subpixel:
            disparity = parabola_refine(
                winners.disparity, winners.before, winners.cost, winners.after, ndisp=ndisp
            )
        else:
            disparity = winners.disparity.astype(jnp.float32)
    with jax.named_scope(STAGES[4]):
        if static.lr_check:
            valid = left_right_consistency(
                winners.disparity, winners.right_disparity, tolerance=params.dynamic.lr_tolerance
            )
            disparity = fill_invalid(disparity, valid, radius=static.fill_radius)
        if static.refine_radius > 0 and static.refine_iterations > 0:
            disparity = side_window_median_filter(
                disparity, radius=static.refine_radius, iterations=static.refine_iterations
            )
        return jnp.clip(disparity, 0, ndisp - 1)


def _fold(state: Winners, slices, first, limit) -> Winners:
    with jax.named_scope(STAGES[3]):
        return fold_winners(state, slices, first, limit=limit)


def _with_halo(cost: jax.Array) -> list[jax.Array]:
    """The D planes of a volume between two halo planes (masked to +inf by the fold); a list,
    so no copy of the volume is made."""
    return [cost[0], *(cost[d] for d in range(cost.shape[0])), cost[-1]]


def select_and_refine(cost: jax.Array, params: Params) -> jax.Array:
    """Eq. (8)-(9): WTA (+ parabola), left-right check, filling, side-window median.

    Parameters
    ----------
    cost : float32 (D, H, W)
        Aggregated cost of the left view.
    params : Params

    Returns
    -------
    float32 (H, W), dense, in [0, D - 1].
    """
    check_rank("cost", cost, 3)
    check_floating("cost", cost)
    ndisp = cost.shape[0]
    winners = _fold(no_winners(cost.shape[1:]), _with_halo(cost), 0, ndisp)
    return _refine(winners, params, ndisp)


@functools.partial(jax.jit, static_argnames=("ndisp",))
def ssw_disparity(
    left: jax.Array, right: jax.Array, params: Params, *, ndisp: int, valid_ndisp=None
) -> jax.Array:
    """The whole SSW method as one jitted pure function.

    ``params.static`` is pytree metadata, so changing it (or the image size, or ``ndisp``)
    recompiles; ``params.dynamic`` is traced. ``jax.vmap`` batches it over pairs of one size:
    ``jax.vmap(lambda l, r: ssw_disparity(l, r, params, ndisp=n))(lefts, rights)``.

    With ``params.static.disparity_chunk = K > 0`` (the default) the disparities are processed
    K at a time (``lax.scan`` with a running minimum for both views), so memory holds a few
    ``(K, H, W)`` blocks instead of ``(ndisp, H, W)`` volumes; the result is the same as with
    ``K = 0`` (the whole volume at once).

    Parameters
    ----------
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    params : Params
    ndisp : int, 1 <= ndisp < W
        Size of the disparity volume (static: a new value recompiles).
    valid_ndisp : int32 scalar, optional
        Traced search range ``0 .. valid_ndisp - 1`` within the volume (default ``ndisp``):
        shape bucketing runs a padded ``ndisp`` and passes the true one here.

    Returns
    -------
    float32 (H, W), dense disparities of the left view in pixels, in [0, valid_ndisp - 1].
    """
    _check_pair(left, right, ndisp)
    limit = ndisp if valid_ndisp is None else valid_ndisp
    features, labels, num_segments = _features(left, right, params)
    chunk = params.static.disparity_chunk
    if chunk == 0 or chunk >= ndisp:
        cost = _aggregate_slices(features, left, labels, num_segments, 0, ndisp, params)
        winners = _fold(no_winners(cost.shape[1:]), _with_halo(cost), 0, limit)
        return _refine(winners, params, limit)

    # Each step aggregates a block of K slices and folds the block of the previous step, which
    # the loop carries: every slice is computed once, and the fold reads a materialised block
    # (XLA would otherwise recompute the last filtering pass inside each of its consumers).
    # The first step folds an empty block (disparities -K .. -1, all +inf).
    height, width = left.shape[:2]
    inf_plane = jnp.full((height, width), jnp.inf, jnp.float32)
    firsts = jnp.arange(0, ndisp, chunk)

    def fold(state, block, before, after, first):
        planes = [before, *(block[k] for k in range(chunk)), after]
        return _fold(state, planes, first, limit)

    def step(carry, first):
        state, previous, before = carry
        # The last block may run past ndisp: those slices are computed but masked by the fold.
        block = _aggregate_slices(features, left, labels, num_segments, first, chunk, params)
        state = fold(state, previous, before, block[0], first - chunk)
        return (state, block, previous[-1]), None

    empty = jnp.full((chunk, height, width), jnp.inf, jnp.float32)
    start = (no_winners((height, width)), empty, inf_plane)
    (winners, last, before), _ = jax.lax.scan(step, start, firsts)
    winners = fold(winners, last, before, inf_plane, firsts[-1])
    return _refine(winners, params, limit)


class ShapeBuckets(NamedTuple):
    """Round image sizes and disparity counts up so that many pairs share one compiled graph.

    Height and width are padded (edge-replicated, bottom and right) to multiples of
    ``size_step`` and the volume to a multiple of ``ndisp_step`` disparities (the extra ones are
    never chosen); results are cropped back. The defaults put the 15 MiddEval3 trainingQ pairs
    into three shapes (512x512x96, 512x768x96, 512x768x192).
    """

    size_step: int = 256
    ndisp_step: int = 96


def bucket_shape(height: int, width: int, ndisp: int, buckets: ShapeBuckets) -> tuple[int, int, int]:
    """Padded ``(height, width, ndisp)`` of a pair under ``buckets`` (``ndisp`` < width kept).

    Examples
    --------
    >>> bucket_shape(375, 450, 64, ShapeBuckets())
    (512, 512, 96)
    """

    def up(value, step):
        return -(-value // step) * step

    padded_ndisp = up(ndisp, buckets.ndisp_step)
    padded_width = max(up(width, buckets.size_step), up(padded_ndisp + 1, buckets.size_step))
    return up(height, buckets.size_step), padded_width, padded_ndisp


def prepare_pair(left, right) -> tuple[np.ndarray, np.ndarray]:
    """Validate a user's pair and convert it to float32 ``(H, W, C)`` in [0, 1].

    Gray ``(H, W)`` or ``(H, W, 1)``, RGB ``(H, W, 3)`` and RGBA ``(H, W, 4)`` (alpha dropped)
    are accepted, as uint8, uint16 or floating arrays (floats must be finite; they are used as
    given, assumed in [0, 1]). If one image is gray and the other colour, both are used as gray.

    Returns
    -------
    (float32 (H, W, C), float32 (H, W, C)) with C in {1, 3}
    """
    from sswjax.color import rgb_to_gray

    def convert(name, image):
        image = np.asarray(image)
        if image.ndim == 2:
            image = image[..., None]
        if image.ndim != 3 or image.shape[-1] not in (1, 3, 4):
            raise ValueError(
                f"{name} image must be HxW, HxWx1, HxWx3 or HxWx4, got shape {image.shape}"
            )
        if image.shape[0] == 0 or image.shape[1] == 0:
            raise ValueError(f"{name} image is empty, got shape {image.shape}")
        image = image[..., :3]
        if image.dtype == np.uint8:
            image = image.astype(np.float32) / 255
        elif image.dtype == np.uint16:
            image = image.astype(np.float32) / 65535
        elif np.issubdtype(image.dtype, np.floating):
            image = image.astype(np.float32)
            if not np.isfinite(image).all():
                raise ValueError(f"{name} image contains NaN or infinite values")
        else:
            raise ValueError(f"{name} image must be uint8, uint16 or float, got {image.dtype}")
        return image

    left, right = convert("left", left), convert("right", right)
    if left.shape[:2] != right.shape[:2]:
        raise ValueError(
            f"left and right images differ in size: {left.shape[1]}x{left.shape[0]} "
            f"and {right.shape[1]}x{right.shape[0]}"
        )
    if left.shape[-1] != right.shape[-1]:
        left, right = (
            np.asarray(rgb_to_gray(im))[..., None] if im.shape[-1] == 3 else im
            for im in (left, right)
        )
    return left, right


def checked_pair(left, right, ndisp, params: Params) -> tuple[np.ndarray, np.ndarray]:
    """:func:`prepare_pair` plus the checks of :func:`match` on ``ndisp`` and on the image size.

    Returns
    -------
    (float32 (H, W, C), float32 (H, W, C)) with C in {1, 3}
    """
    if isinstance(ndisp, bool) or not isinstance(ndisp, (int, np.integer)):
        raise ValueError(f"ndisp must be an integer, got {ndisp!r}")
    left, right = prepare_pair(left, right)
    if not 1 <= ndisp < left.shape[1]:
        raise ValueError(f"ndisp must be in [1, {left.shape[1] - 1}] for this width, got {ndisp}")
    census = (params.static.census_width, params.static.census_height)
    if min(left.shape[:2]) < max(census):
        raise ValueError(
            f"images of {left.shape[1]}x{left.shape[0]} are smaller than the census window "
            f"{census[0]}x{census[1]}: both sides must be at least {max(census)} pixels"
        )
    return left, right


def pad_to_bucket(left, right, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Edge-replicate a pair ``(H, W, C)`` at the bottom and right up to ``height x width``."""
    pad = ((0, height - left.shape[0]), (0, width - left.shape[1]), (0, 0))
    return tuple(np.pad(image, pad, mode="edge") for image in (left, right))


def match(
    left, right, ndisp: int, params: Params | None = None, *, buckets: ShapeBuckets | None = None
) -> np.ndarray:
    """Dense disparity map of a rectified stereo pair with the SSW method.

    Parameters
    ----------
    left, right : array_like (H, W) or (H, W, 1|3|4), uint8, uint16 or float in [0, 1]
        Rectified pair; the left image is the reference view.
    ndisp : int
        Disparities searched: 0 .. ndisp - 1 (Middlebury ``calib.txt`` ``ndisp``); 1 <= ndisp < W.
    params : Params, optional
        Defaults to ``Params()``; see :func:`sswjax.load_params`.
    buckets : ShapeBuckets, optional
        Pad the pair to a bucketed shape so that pairs of nearby sizes reuse one compilation
        (results near the bottom and right borders can change slightly); default: exact shape.

    Returns
    -------
    numpy.ndarray, float32 (H, W)
        Disparity of every left pixel in pixels (dense, no invalid values).

    Examples
    --------
    >>> import numpy as np, sswjax
    >>> rng = np.random.default_rng(0)
    >>> right = rng.random((40, 64, 3), dtype=np.float32)
    >>> left = np.roll(right, 5, axis=1)          # the scene moved 5 px: disparity 5
    >>> d = sswjax.match(left, right, ndisp=16)
    >>> round(float(np.median(d[:, 16:])), 2)
    5.0
    """
    from sswjax.params import check_params

    params = Params() if params is None else check_params(params)
    left, right = checked_pair(left, right, ndisp, params)
    if buckets is None:
        return np.asarray(ssw_disparity(jnp.asarray(left), jnp.asarray(right), params, ndisp=int(ndisp)))
    height, width = left.shape[:2]
    padded_h, padded_w, padded_ndisp = bucket_shape(height, width, int(ndisp), buckets)
    left, right = pad_to_bucket(left, right, padded_h, padded_w)
    disparity = ssw_disparity(jnp.asarray(left), jnp.asarray(right), params, ndisp=padded_ndisp,
                              valid_ndisp=jnp.int32(ndisp))
    return np.asarray(disparity)[:height, :width]
