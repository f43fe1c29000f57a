"""Comparison figure of evaluated methods (needs matplotlib, extra ``[bench]``).

Conventions: scenes are :class:`sswjax.data.layouts.StereoScene`; results map a method name to its
per-scene :class:`sswjax.evaluation.SceneResult` in the same scene order.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from PIL import Image

from sswjax._files import atomic_output
from sswjax.data.io import disparity_to_rgb
from sswjax.data.layouts import StereoScene
from sswjax.evaluation.runner import SceneResult

def check_matplotlib(*, what: str = "the figure") -> None:
    """Check, before the work whose figure it is, that matplotlib imports.

    Raises ``ValueError`` (one line: ``WHAT needs matplotlib: pip install 'sswjax[bench]'``)
    when it does not.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise ValueError(f"{what} needs matplotlib: pip install 'sswjax[bench]'") from None


SPARSE_FRACTION = 0.5
"""Ground truths known on fewer pixels than this fraction are *sparse*: :func:`comparison_figure`
draws them (and the error maps against them) grown by ``sparse_dilate`` pixels."""


def _grow(values: np.ndarray, radius: int, fill) -> np.ndarray:
    """Maximum of ``values`` over the (2 radius + 1)^2 square around each pixel (``fill`` outside)."""
    if radius <= 0:
        return values
    padded = np.pad(values, radius, constant_values=fill)
    size = 2 * radius + 1
    return np.lib.stride_tricks.sliding_window_view(padded, (size, size)).max(axis=(-2, -1))


def error_map(
    disparity: np.ndarray, ground_truth: np.ndarray, *, threshold: float = 2.0, dilate: int = 0
) -> np.ndarray:
    """Colour each pixel by whether its disparity is within ``threshold`` of the ground truth.

    Parameters
    ----------
    disparity, ground_truth : (H, W) float arrays
        Disparities in pixels; non-finite ground truth means unknown.
    threshold : float
        Error (pixels) above which a pixel is bad, as in the bad-t metrics.
    dilate : int
        Grow the known pixels (and, over them, the bad ones) by this many pixels, so that a
        sparse ground truth (KITTI) stays visible when the map is shrunk; 0 draws pixels as they are.

    Returns
    -------
    uint8 (H, W, 3)
        Bad pixels (error > ``threshold``, or a non-finite disparity) red, good ones gray,
        unknown ground truth black.

    Examples
    --------
    >>> gt = np.array([[1.0, 1.0, np.inf]], np.float32)
    >>> error_map(np.array([[1.0, 9.0, 0.0]], np.float32), gt)[0].tolist()
    [[150, 150, 150], [220, 30, 30], [0, 0, 0]]
    """
    disparity, ground_truth = np.asarray(disparity), np.asarray(ground_truth)
    if disparity.ndim != 2 or disparity.shape != ground_truth.shape:
        raise ValueError(f"disparity and ground truth must be (H, W) arrays of one shape, got "
                         f"{disparity.shape} and {ground_truth.shape}")
    if int(dilate) != dilate or dilate < 0:
        raise ValueError(f"dilate must be a whole number >= 0, got {dilate!r}")
    known = np.isfinite(ground_truth)
    bad = known & ~(np.abs(disparity - np.where(known, ground_truth, 0)) <= threshold)
    known, bad = _grow(known, int(dilate), False), _grow(bad, int(dilate), False)
    out = np.zeros(disparity.shape + (3,), np.uint8)
    out[known] = (150, 150, 150)
    out[bad] = (220, 30, 30)
    return out


def _panel_rows(scene: StereoScene, results, methods, *, threshold: float, stacked: bool,
                dilate: int) -> list[list[tuple[np.ndarray | None, str]]]:
    """The (image, title) panels of one scene: one row, or with ``stacked`` the disparities above
    their error maps (an image ``None`` is an empty cell)."""
    gt = scene.ground_truth
    known = np.isfinite(gt)
    if known.mean() >= SPARSE_FRACTION:
        dilate = 0
    vmax = float(gt[known].max())
    shown_gt = np.where(known, gt, -np.inf)
    shown_gt = _grow(shown_gt, dilate, -np.inf)
    shown_gt[np.isneginf(shown_gt)] = np.inf
    head = [(scene.left, "left"), (disparity_to_rgb(shown_gt, vmin=0, vmax=vmax), "ground truth")]
    disparities, errors = [], []
    for m, rows in ((m, results[m]) for m in methods):
        result = rows[_scene_index(rows, scene)]
        d, bad = result.disparity, result.metrics["all"][f"bad{float(threshold)}"]
        disparities.append((disparity_to_rgb(d, vmin=0, vmax=vmax), m))
        errors.append((error_map(d, gt, threshold=threshold, dilate=dilate),
                       f"{m}: {bad:.1f} %" if stacked else f"{m} bad {bad:.1f}%"))
    if stacked:
        return [head + disparities, [(None, ""), (None, "")] + errors]
    return [head + [p for pair in zip(disparities, errors) for p in pair]]


def _scene_index(rows: Sequence[SceneResult], scene: StereoScene) -> int:
    """Index of ``scene``'s result in one method's ``rows`` (matched by scene name)."""
    names = [r.scene for r in rows]
    if scene.name not in names:
        raise ValueError(f"no result for scene {scene.name!r} (results hold {names})")
    return names.index(scene.name)


def comparison_figure(
    path: str | Path,
    scenes: Sequence[StereoScene],
    results: Mapping[str, Sequence[SceneResult]],
    *,
    threshold: float = 2.0,
    thumb_inches: float = 1.6,
    stacked: bool = False,
    sparse_dilate: int = 0,
    labels: Sequence[str] | None = None,
    dpi: int = 80,
    colors: int | None = None,
) -> None:
    """Write a PNG grid: per scene, left image, ground truth, each method's disparity and errors.

    Parameters
    ----------
    path : str or Path
        PNG written (atomically).
    scenes : sequence of StereoScene
        Scenes with ground truth, one grid row each (two with ``stacked``); they may differ in
        size, each row is as tall as its scene's aspect asks.
    results : {method: sequence of SceneResult}
        Each method's results on (at least) ``scenes``, found by scene name; their metrics must
        hold ``"all"`` / ``f"bad{threshold}"``, shown in the error panels' titles.
    threshold : float
        Bad-pixel threshold of the error maps and of the titles' figures.
    thumb_inches : float
        Width of one panel; titles scale with it.
    stacked : bool
        ``False``: one row per scene, each method's disparity beside its error map. ``True``:
        the disparities in one row and, under each, its error map (half as many columns, so
        larger panels at the same width).
    sparse_dilate : int
        Ground truths known on fewer than :data:`SPARSE_FRACTION` of the pixels (KITTI) and
        their error maps are drawn grown by this many pixels (see :func:`error_map`).
    labels : sequence of str, optional
        Row label of each scene (default its name).
    dpi : int
        Pixels per inch of the PNG.
    colors : int, optional
        Store the PNG with a palette of this many colours (2 to 256; a third of the size for
        photographs at 256); default full RGB(A).

    Examples
    --------
    >>> comparison_figure("fig.png", scenes, {"paper": rows}, stacked=True)  # doctest: +SKIP
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ValueError("the figure needs matplotlib: pip install 'sswjax[bench]'") from error
    scenes = list(scenes)
    labels = [s.name for s in scenes] if labels is None else list(labels)
    if len(labels) != len(scenes):
        raise ValueError(f"{len(labels)} labels for {len(scenes)} scenes")
    if colors is not None and not 2 <= colors <= 256:
        raise ValueError(f"colors must be between 2 and 256, got {colors}")
    methods = list(results)
    grid, heights = [], []
    for scene, label in zip(scenes, labels):
        rows = _panel_rows(scene, results, methods, threshold=threshold, stacked=stacked,
                           dilate=sparse_dilate)
        grid += [(label if k == 0 else None, row) for k, row in enumerate(rows)]
        heights += [scene.left.shape[0] / scene.left.shape[1]] * len(rows)
    columns = len(grid[0][1])
    fontsize = 4 * thumb_inches
    title_inches = fontsize / 72 * 1.6  # room for one line of title above each row
    fig, axes = plt.subplots(len(grid), columns, squeeze=False, gridspec_kw={
        "height_ratios": [h * thumb_inches + title_inches for h in heights]},
        figsize=(columns * thumb_inches, sum(h * thumb_inches + title_inches for h in heights)))
    for r, (label, panels) in enumerate(grid):
        for col, (image, title) in enumerate(panels):
            ax = axes[r, col]
            ax.set_xticks([])
            ax.set_yticks([])
            if image is None:
                ax.axis("off")
                continue
            ax.imshow(image, cmap="gray" if image.ndim == 2 else None)
            if stacked or r == 0 or "bad" in title:
                ax.set_title(title, fontsize=fontsize)
        if label is not None:
            axes[r, 0].set_ylabel(label, fontsize=fontsize * 1.1)
        if stacked and r == 1:
            axes[r, 0].text(0, 0.5, f"error > {threshold:g} px: red\n"
                            f"error <= {threshold:g} px: grey\nno ground truth: black", fontsize=fontsize, va="center",
                            transform=axes[r, 0].transAxes)
    fig.tight_layout(pad=0.4)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
        if colors is not None:
            with Image.open(tmp) as image:
                palette = image.convert("RGB").quantize(colors)
            palette.save(tmp, format="PNG", optimize=True)
    plt.close(fig)
