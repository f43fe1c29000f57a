"""The NumPy front door: validate a user's pair, convert it, pick a shape, run the jitted graph.

Array conventions (whole module): user images are NumPy-like ``(H, W)`` or ``(H, W, 1|3|4)``
arrays of uint8, uint16 or floats in [0, 1]; they are converted to float32 ``(H, W, C)`` in
[0, 1], C in {1, 3}, for :func:`sswjax.pipeline.ssw_disparity`; results come back as NumPy
float32 ``(H, W)`` disparities in pixels.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from sswjax.params import Params
from sswjax.pipeline import ssw_disparity, ssw_outputs
from sswjax.stages.confidence import DEFAULT_MEASURE, DEFAULT_THRESHOLD, MEASURES
from sswjax.ranges import check_disparity_range, from_range_frame, range_frame


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


def to_float_image(image, *, name: str = "image") -> np.ndarray:
    """The one conversion of a user's image to the pipeline's float32 ``(H, W, C)`` in [0, 1].

    Parameters
    ----------
    image : array_like (H, W) or (H, W, 1|3|4)
        uint8 (divided by 255), uint16 (divided by 65535) or floating (used as given, assumed in
        [0, 1], must be finite in float32). Alpha is dropped.
    name : str
        How error messages call the image (``"left"``, ``"right"``).

    Returns
    -------
    numpy.ndarray float32 (H, W, C), C in {1, 3} (a new array)

    Raises
    ------
    ValueError
        On a bad shape, an empty image, another dtype (bool, int32, ...) or non-finite values.

    Examples
    --------
    >>> to_float_image(np.array([[0, 255]], dtype=np.uint8))[..., 0]
    array([[0., 1.]], dtype=float32)
    """
    image = np.asarray(image)
    if image.ndim == 2:
        image = image[..., None]
    if image.ndim != 3 or image.shape[-1] not in (1, 3, 4):
        raise ValueError(f"{name} image must be HxW, HxWx1, HxWx3 or HxWx4, got shape {image.shape}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"{name} image is empty, got shape {image.shape}")
    image = image[..., :3]
    if image.dtype == np.uint8:
        return image.astype(np.float32) / np.float32(255)
    if image.dtype == np.uint16:
        return image.astype(np.float32) / np.float32(65535)
    if not np.issubdtype(image.dtype, np.floating):
        raise ValueError(f"{name} image must be uint8, uint16 or float, got {image.dtype}")
    with np.errstate(over="ignore", invalid="ignore"):
        image = image.astype(np.float32)
    if not np.isfinite(image).all():
        raise ValueError(f"{name} image contains NaN or infinite values")
    return image


def prepare_pair(left, right) -> tuple[np.ndarray, np.ndarray]:
    """Validate a user's pair and convert it to float32 ``(H, W, C)`` in [0, 1].

    Each image goes through :func:`to_float_image`. If one image is gray and the other colour,
    both are used as gray (BT.601 luma of the colour one).

    Returns
    -------
    (float32 (H, W, C), float32 (H, W, C)) with C in {1, 3}
    """
    from sswjax.stages.color import rgb_to_gray

    left, right = to_float_image(left, name="left"), to_float_image(right, name="right")
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
    left, right, ndisp: int, *, min_disp: int = 0, params: Params | None = None,
    buckets: ShapeBuckets | None = None, check_memory: bool = True
) -> np.ndarray:
    """Dense disparity map of a rectified stereo pair with the SSW method.

    Parameters
    ----------
    left, right : array_like (H, W) or (H, W, 1|3|4), uint8, uint16 or float in [0, 1]
        Rectified pair; the left image is the reference view.
    ndisp : int
        Disparities searched: 0 .. ndisp - 1 (Middlebury ``calib.txt`` ``ndisp``); 1 <= ndisp < W.
    min_disp : int, optional
        First disparity searched (default 0; may be negative): the range is ``min_disp ..
        min_disp + ndisp - 1`` and must meet ``-(W - 1) .. W - 1`` (see :mod:`sswjax.ranges`).
    params : Params, optional
        Defaults to the ``accurate`` preset (:func:`sswjax.params.default_params`; the paper's
        method is ``sswjax.preset("paper")``, which is ``Params()``); see
        :func:`sswjax.load_params`.
    buckets : ShapeBuckets, optional
        Pad the pair to a bucketed shape so that pairs of nearby sizes reuse one compilation
        (results near the bottom and right borders can change slightly); default: exact shape.
    check_memory : bool
        Before running, compare the estimated peak memory of the call
        (:func:`sswjax.memory.estimate_peak_bytes`) with the available memory and raise
        :class:`sswjax.memory.MemoryEstimateError` (a ``MemoryError``) if it does not fit
        (default); ``False`` runs without the check.

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
    return _match_maps(left, right, ndisp, min_disp=min_disp, params=params, buckets=buckets,
                       check_memory=check_memory, graph=ssw_disparity)


class Matched(NamedTuple):
    """What :func:`match_with_confidence` returns, all NumPy ``(H, W)``.

    Attributes
    ----------
    disparity : float32
        The dense map of :func:`match` (filled values included).
    confidence : float32 in [0, 1]
        Higher = more reliable (:mod:`sswjax.stages.confidence`).
    validity : uint8
        Bit mask, 0 = valid: bit 0 (1) failed the left-right check and filled, bit 1 (2) left
        band (``x - d < 0``: no match in the right image), bit 2 (4) confidence below the
        threshold.
    """

    disparity: np.ndarray
    confidence: np.ndarray
    validity: np.ndarray


def match_with_confidence(
    left, right, ndisp: int, *, min_disp: int = 0, params: Params | None = None,
    buckets: ShapeBuckets | None = None, check_memory: bool = True,
    low_confidence: float = DEFAULT_THRESHOLD, measure: str = DEFAULT_MEASURE,
) -> Matched:
    """:func:`match` with the confidence and the validity bits of every pixel.

    One run of the jitted graph (:func:`sswjax.pipeline.ssw_outputs`); the disparity is
    bit-identical to :func:`match`'s with the same options.

    Parameters
    ----------
    left, right, ndisp, min_disp, params, buckets, check_memory
        As for :func:`match`.
    low_confidence : float in [0, 1]
        Confidence below it sets validity bit 2 (default
        :data:`sswjax.stages.confidence.DEFAULT_THRESHOLD`; 0 never sets it).
    measure : str
        Confidence measure, a key of :data:`sswjax.stages.confidence.MEASURES`.

    Returns
    -------
    Matched
        disparity float32 (H, W), confidence float32 (H, W), validity uint8 (H, W).

    Examples
    --------
    >>> import numpy as np, sswjax
    >>> rng = np.random.default_rng(0)
    >>> right = rng.random((40, 64, 3), dtype=np.float32)
    >>> left = np.roll(right, 5, axis=1)
    >>> out = sswjax.match_with_confidence(left, right, ndisp=16)
    >>> round(float(np.median(out.disparity[:, 16:])), 2)
    5.0
    >>> float(((out.validity[:, :4] & 2) > 0).mean()) > 0.9   # bit 1: no match left of x = d
    True
    """
    from sswjax.stages.confidence import validity_mask

    if measure not in MEASURES:
        raise ValueError(f"unknown confidence measure {measure!r}; choose from {', '.join(MEASURES)}")
    if isinstance(low_confidence, bool) or not isinstance(low_confidence, (int, float, np.floating)) \
            or not 0.0 <= float(low_confidence) <= 1.0:
        raise ValueError(f"low_confidence must be a number in [0, 1], got {low_confidence!r}")
    outputs = _match_maps(left, right, ndisp, min_disp=min_disp, params=params, buckets=buckets,
                          check_memory=check_memory,
                          graph=functools.partial(ssw_outputs, measure=measure))
    validity = validity_mask(outputs.disparity, outputs.confidence, outputs.lr_failed,
                             threshold=float(low_confidence))
    return Matched(outputs.disparity, outputs.confidence, np.asarray(validity))


def _match_maps(left, right, ndisp, *, min_disp: int, params: Params | None,
                buckets: ShapeBuckets | None, check_memory: bool, graph):
    """The one body of :func:`match` and :func:`match_with_confidence`: check the pair, move it
    to the range's frame, pad it to its bucket, run ``graph`` in strips, crop and map back.

    ``graph(left, right, params=, ndisp=[, valid_ndisp=])`` is a jitted function of the
    pipeline returning the disparity float32 ``(H', W')`` or a NamedTuple of ``(H', W')`` maps
    whose first is the disparity; the result has the same structure, every map ``(H, W)`` in
    the pair's frame (only the disparity is shifted by ``min_disp``).
    """
    from sswjax.params import check_params, default_params

    params = default_params() if params is None else check_params(params)
    left, right = checked_pair(left, right, ndisp, params)
    check_disparity_range(left.shape[1], ndisp, min_disp)
    true_width = left.shape[1]
    left, right = range_frame(left, right, min_disp=min_disp)
    height, width = left.shape[:2]
    if check_memory:
        from sswjax.memory import fit_in_memory

        params = fit_in_memory(height, width, int(ndisp), params=params, channels=left.shape[-1],
                               buckets=buckets)
    if buckets is None:
        run = functools.partial(graph, params=params, ndisp=int(ndisp))
    else:
        padded_h, padded_w, padded_ndisp = bucket_shape(height, width, int(ndisp), buckets)
        left, right = pad_to_bucket(left, right, padded_h, padded_w)
        run = functools.partial(graph, params=params, ndisp=padded_ndisp,
                                valid_ndisp=jnp.int32(ndisp))
    maps = in_strips(run, left, right, rows=params.static.strip_rows,
                     overlap=params.static.strip_overlap)
    if not isinstance(maps, tuple):
        return from_range_frame(maps[:height, :width], min_disp=min_disp, width=true_width)
    # The range's frame widens the pair by P = max(-min_disp, 0) columns on the left.
    pad = max(-int(min_disp), 0)
    return type(maps)(
        from_range_frame(maps[0][:height, :width], min_disp=min_disp, width=true_width),
        *(m[:height, pad:pad + true_width] for m in maps[1:]))


def in_strips(run, left: np.ndarray, right: np.ndarray, *, rows: int, overlap: int) -> np.ndarray:
    """``run(left, right)`` on overlapping horizontal strips of the pair, stitched.

    Each call sees ``rows + 2 * overlap`` image rows (one shape, so one compilation) and gives
    its ``rows`` central rows; strips at the top and bottom slide inside the image. Memory
    follows the strip's height instead of the image's; what a strip cannot see (the image
    beyond its overlap) is what changes: vertical SGM paths and the superpixels start afresh
    at its edges. ``rows=0`` (or a strip taller than the image) runs the whole pair at once.

    Parameters
    ----------
    run : callable
        ``run(left, right) -> (H', W)`` map of float32 ``(H', W, C)`` images, or a NamedTuple
        of such maps of any dtypes: each is stitched.
    left, right : float32 (H, W, C)
    rows, overlap : int >= 0

    Returns
    -------
    numpy.ndarray (H, W) of the map's dtype, or the same NamedTuple of them

    Examples
    --------
    >>> import numpy as np
    >>> image = np.arange(10.0)[:, None, None] * np.ones((10, 3, 1))
    >>> rows_seen = in_strips(lambda l, r: l[..., 0], image, image, rows=4, overlap=1)
    >>> rows_seen[:, 0].tolist()
    [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]
    """
    height = left.shape[0]
    window = rows + 2 * overlap
    if rows <= 0 or window >= height:
        return _to_numpy(run(jnp.asarray(left), jnp.asarray(right)))
    out = None
    for first in range(0, height, rows):
        last = min(first + rows, height)
        top = min(max(first - overlap, 0), height - window)
        strip = _to_numpy(run(jnp.asarray(left[top:top + window]),
                              jnp.asarray(right[top:top + window])))
        parts = strip if isinstance(strip, tuple) else (strip,)
        if out is None:
            out = [np.empty(left.shape[:2], part.dtype) for part in parts]
        for whole, part in zip(out, parts):
            whole[first:last] = part[first - top:last - top]
    return type(strip)(*out) if isinstance(strip, tuple) else out[0]


def _to_numpy(result):
    """A map, or a (Named)tuple of maps, as NumPy arrays of the same structure."""
    if isinstance(result, tuple):
        return type(result)(*(np.asarray(part) for part in result))
    return np.asarray(result)
