"""The error maps and the comparison figure, on synthetic scenes (no data sets)."""

from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.data.layouts import StereoScene
from sswjax.evaluation.figures import comparison_figure, error_map
from sswjax.evaluation.runner import SceneResult

RED, GREY, BLACK = [220, 30, 30], [150, 150, 150], [0, 0, 0]


def test_error_map_colours_right_wrong_and_unknown():
    gt = np.array([[4.0, 4.0, np.inf, 4.0]], np.float32)
    disparity = np.array([[5.5, 6.5, 0.0, np.nan]], np.float32)
    assert error_map(disparity, gt).tolist() == [[GREY, RED, BLACK, RED]]
    assert error_map(disparity, gt, threshold=3.0)[0, 1].tolist() == GREY


def test_error_map_dilation_grows_sparse_dots_red_over_grey():
    gt = np.full((9, 9), np.inf, np.float32)
    gt[2, 2], gt[6, 6] = 3.0, 3.0
    disparity = np.full((9, 9), 3.0, np.float32)
    disparity[6, 6] = 9.0  # the second dot is wrong
    image = error_map(disparity, gt, dilate=1)
    assert (image[1:4, 1:4] == GREY).all() and (image[5:8, 5:8] == RED).all()
    assert (image[0] == BLACK).all() and image[4, 4].tolist() == BLACK
    assert (image == RED).all(axis=-1).sum() == 9


@pytest.mark.parametrize("disparity, gt, dilate, message", [
    (np.zeros((2, 3)), np.zeros((3, 2)), 0, "one shape"),
    (np.zeros(3), np.zeros(3), 0, "one shape"),
    (np.zeros((2, 2)), np.zeros((2, 2)), -1, "dilate"),
    (np.zeros((2, 2)), np.zeros((2, 2)), 1.5, "dilate"),
])
def test_error_map_refuses_bad_input(disparity, gt, dilate, message):
    with pytest.raises(ValueError, match=message):
        error_map(disparity, gt, dilate=dilate)


def _scene(name, shape, *, sparse):
    rng = np.random.default_rng(len(name))
    gt = np.tile(np.linspace(2, 12, shape[1], dtype=np.float32), (shape[0], 1))
    if sparse:
        gt[rng.random(shape) > 0.2] = np.inf
    left = (rng.random(shape + (3,)) * 255).astype(np.uint8)
    return StereoScene(name, left, left, 16, gt, None, Path(name))


def _results(scenes, methods, offset):
    return {m: [SceneResult(s.name, np.where(np.isfinite(s.ground_truth), s.ground_truth,
                                             0).astype(np.float32) + k * offset,
                            {"all": {"bad2.0": 10.0 * k}}, 0.0) for s in scenes[::-1]]
            for k, m in enumerate(methods)}


def test_comparison_figure_stacked_mixed_shapes_and_sparse_truth(tmp_path):
    pytest.importorskip("matplotlib")
    scenes = [_scene("dense", (40, 60), sparse=False), _scene("kitti", (20, 80), sparse=True)]
    results = _results(scenes, ["a", "b", "c"], 3.0)  # results in another order: found by name
    row, stacked = tmp_path / "row.png", tmp_path / "stacked.png"
    comparison_figure(row, scenes, results)
    comparison_figure(stacked, scenes, results, stacked=True, sparse_dilate=2,
                      labels=["set/dense", "set/kitti"])
    row_image, stacked_image = iio.imread(row), iio.imread(stacked)
    # 2 + 2 * 3 panels a row against 2 + 3 stacked: the stacked figure is narrower and taller
    assert stacked_image.shape[1] < 0.75 * row_image.shape[1]
    assert stacked_image.shape[0] > 1.5 * row_image.shape[0]
    red = (stacked_image[..., 0] > 200) & (stacked_image[..., 1] < 60)
    assert red.any()  # methods b and c are 3 and 6 px off: their error maps are red
    palette = tmp_path / "palette.png"
    comparison_figure(palette, scenes, results, stacked=True, colors=16)
    from PIL import Image

    with Image.open(palette) as image:
        assert image.mode == "P" and len(image.getcolors()) <= 16
    assert iio.imread(palette).shape[:2] == stacked_image.shape[:2]


def test_comparison_figure_refuses_missing_results_and_labels(tmp_path):
    pytest.importorskip("matplotlib")
    scenes = [_scene("one", (20, 30), sparse=False)]
    results = _results([_scene("other", (20, 30), sparse=False)], ["a"], 0.0)
    with pytest.raises(ValueError, match="no result for scene 'one'"):
        comparison_figure(tmp_path / "x.png", scenes, results)
    with pytest.raises(ValueError, match="colors"):
        comparison_figure(tmp_path / "x.png", scenes, _results(scenes, ["a"], 0.0), colors=1)
    with pytest.raises(ValueError, match="labels"):
        comparison_figure(tmp_path / "x.png", scenes, _results(scenes, ["a"], 0.0),
                          labels=["a", "b"])
    assert not list(tmp_path.iterdir())
