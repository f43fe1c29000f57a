"""What the search trains on: the loss's pixels, random fixed-size crops, and the folds.

Array conventions (NumPy): images float32 ``(H, W, C)`` in [0, 1] once prepared
(:func:`prepare_scene`); ground truth float32 ``(H, W)`` in pixels, non-finite = unknown;
masks uint8 ``(H, W)``, 255 = non-occluded (MiddEval3's ``mask0nocc``), or None. Scenes are
:class:`sswjax.data.layouts.StereoScene`.
"""

from __future__ import annotations

import numpy as np

from sswjax.api.images import prepare_pair
from sswjax.data.layouts import StereoScene

__all__ = ["MAX_CROP_TRIES", "crop_segments", "dataset_folds", "prepare_scene", "random_crops",
           "valid_mask"]

MAX_CROP_TRIES = 50
"""Draws of a crop position before :func:`random_crops` takes the last one drawn."""


def valid_mask(ground_truth, mask, *, ndisp: int) -> np.ndarray:
    """The pixels the loss uses: known ground truth, non-occluded (every known pixel when
    ``mask`` is None), ``0 <= gt <= ndisp - 1``, and a match ``x - gt`` inside the image (the
    crop).

    Parameters
    ----------
    ground_truth : float32 (H, W)
        Non-finite = unknown.
    mask : uint8 (H, W) or None
        255 = non-occluded.
    ndisp : int

    Returns
    -------
    bool (H, W)

    Examples
    --------
    >>> valid_mask(np.array([[0.0, 2.0, -1.0, np.inf, 9.0]]), None, ndisp=8).tolist()
    [[True, False, False, False, False]]
    """
    gt = np.asarray(ground_truth)
    finite = np.isfinite(gt)
    safe = np.where(finite, gt, 0.0)
    columns = np.arange(gt.shape[1])[None, :]
    nonocc = True if mask is None else np.asarray(mask) == 255
    return finite & nonocc & (safe >= 0) & (safe <= ndisp - 1) & (columns - safe >= 0)


def random_crops(scenes, rng: np.random.Generator, *, batch: int, height: int, width: int,
                 min_valid: float = 0.0):
    """A batch of fixed-size random crops ``(lefts, rights, gts, valids, scene_ndisps)``.

    ``scenes`` are :class:`~sswjax.data.layouts.StereoScene` with float32 images of one
    channel count (see :func:`prepare_scene`) and ground truth. Crops are drawn uniformly over
    scenes, then positions. ``min_valid`` > 0 (for sparse ground truth such as KITTI's) redraws
    the position until at least that share of the crop's pixels are valid
    (:func:`valid_mask` with the scene's ``ndisp``; at most :data:`MAX_CROP_TRIES` draws); 0
    draws once (the same random stream as before the option existed).

    Returns
    -------
    float32 (B, h, w, C), float32 (B, h, w, C), float32 (B, h, w) (unknown = 0),
    bool (B, h, w), int32 (B,)

    Examples
    --------
    >>> image = np.zeros((30, 60, 1), np.float32)
    >>> gt = np.full((30, 60), np.nan, np.float32); gt[20:] = 2.0    # known at the bottom only
    >>> scene = StereoScene(name="s", left=image, right=image, ndisp=8, ground_truth=gt,
    ...                     mask=None, path=None)
    >>> crops = random_crops([scene], np.random.default_rng(0), batch=4, height=10, width=20,
    ...                      min_valid=0.5)
    >>> bool(crops[3].mean(axis=(1, 2)).min() >= 0.5)
    True
    """
    out = [[], [], [], [], []]
    for _ in range(batch):
        s = scenes[rng.integers(len(scenes))]
        h, w = s.left.shape[:2]
        for _ in range(MAX_CROP_TRIES if min_valid > 0 else 1):
            y = int(rng.integers(0, h - height + 1))
            x = int(rng.integers(0, w - width + 1))
            sl = (slice(y, y + height), slice(x, x + width))
            valid = valid_mask(s.ground_truth[sl], None if s.mask is None else s.mask[sl],
                               ndisp=s.ndisp)
            if valid.mean() >= min_valid:
                break
        gt = s.ground_truth[sl]
        out[0].append(s.left[sl])
        out[1].append(s.right[sl])
        out[2].append(np.where(np.isfinite(gt), gt, 0.0).astype(np.float32))
        out[3].append(valid)
        out[4].append(s.ndisp)
    return tuple(np.stack(a) for a in out[:4]) + (np.asarray(out[4], np.int32),)


def prepare_scene(scene: StereoScene, *, channels: int | None = None) -> StereoScene:
    """A scene with float32 ``[0, 1]`` images ``(H, W, C)``, as the graph takes them
    (:func:`sswjax.api.images.prepare_pair`).

    ``channels=3`` repeats a gray pair into three equal channels, so that gray and colour
    scenes share a compiled step: every stage of the cost and of the optimiser reads the
    channel mean or the BT.601 luma, which are the gray value again (up to rounding).
    """
    left, right = prepare_pair(scene.left, scene.right)
    if channels is not None and left.shape[-1] != channels:
        if (left.shape[-1], channels) != (1, 3):
            raise ValueError(f"channels: cannot turn {left.shape[-1]} channels into {channels}")
        left, right = np.repeat(left, 3, axis=-1), np.repeat(right, 3, axis=-1)
    return scene._replace(left=left, right=right)


def crop_segments(n_segments: int, crop_area: int, image_area: float) -> int:
    """Superpixel count giving a crop the superpixel size of the full image (0 stays 0).

    >>> crop_segments(2000, 64 * 128, 640 * 480)
    53
    """
    if n_segments == 0:
        return 0
    return max(1, int(round(n_segments * crop_area / image_area)))


def dataset_folds(names) -> list[tuple[str, list[str]]]:
    """Leave-one-dataset-out folds: ``[(held_out, [the others]), ...]``, one per data set.

    The search of each fold sees crops of the other sets only; its held-out set is then scored
    with the full pipeline (the earlier driver's ``--folds datasets``; ``sswjax search
    --held-out datasets`` builds its folds with :func:`sswjax.search.held_out.folds`).

    Parameters
    ----------
    names : sequence of str
        At least two distinct data set names.

    Returns
    -------
    list of (str, list of str), in the order of ``names``.

    Examples
    --------
    >>> dataset_folds(["MiddEval3", "KITTI2012", "Middlebury2001"])[1]
    ('KITTI2012', ['MiddEval3', 'Middlebury2001'])
    """
    names = list(names)
    if len(names) < 2 or len(set(names)) != len(names):
        raise ValueError(f"names: need at least two distinct data sets, got {names}")
    return [(held, [n for n in names if n != held]) for held in names]
