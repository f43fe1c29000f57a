import math

import numpy as np
import pytest

from sswjax.evaluation.metrics import MIDDEVAL3_TRAINING_WEIGHTS, evaluate_disparity, weighted_average

INF = np.inf


def f32(rows):
    return np.array(rows, np.float32)


def test_strict_threshold_and_keys():
    gt = f32([[10, 10, 10, 10]])
    d = f32([[10, 12, 12.5, 6]])  # errors 0, 2, 2.5, 4
    m = evaluate_disparity(d, gt, ndisp=64)
    assert set(m) == {"all"}
    keys = ["bad0.5", "bad1.0", "bad2.0", "bad4.0", "invalid", "avgerr", "rms", "a90"]
    assert list(m["all"]) == keys
    assert m["all"]["bad0.5"] == 75.0
    assert m["all"]["bad1.0"] == 75.0
    assert m["all"]["bad2.0"] == 50.0  # an error of exactly 2.0 is not bad (2.5 and 4 are)
    assert m["all"]["bad4.0"] == 0.0  # nor is exactly 4.0
    assert all(type(v) is float for v in m["all"].values())
    assert m["all"]["invalid"] == 0.0
    assert m["all"]["avgerr"] == pytest.approx(8.5 / 4)
    assert m["all"]["rms"] == pytest.approx(math.sqrt((0 + 4 + 6.25 + 16) / 4))
    assert m["all"]["a90"] == 4.0  # ceil(0.9 * 4) = 4th smallest error


def test_unknown_ground_truth_is_skipped():
    gt = f32([[1, INF, 3, INF]])
    d = f32([[1, 50, 6, INF]])
    m = evaluate_disparity(d, gt, ndisp=64)["all"]
    assert m["bad2.0"] == 50.0 and m["invalid"] == 0.0
    assert m["avgerr"] == 1.5


def test_invalid_prediction():
    gt = f32([[1, 2, 3, 4]])
    d = f32([[1, 3, INF, np.nan]])  # errors 0, 1, invalid, invalid
    m = evaluate_disparity(d, gt, ndisp=64)["all"]
    assert m["invalid"] == 50.0
    assert m["bad0.5"] == 75.0  # the 1.0 error plus both invalid pixels
    assert m["bad4.0"] == 50.0  # invalid pixels are bad at every threshold
    assert m["avgerr"] == 0.5 and m["rms"] == pytest.approx(math.sqrt(0.5))
    assert m["a90"] == INF


def test_prediction_clipped_to_ndisp():
    gt = f32([[0, 10, 10]])
    d = f32([[-3, 25, 10]])  # clipped to 0, 10, 10 -> all exact
    m = evaluate_disparity(d, gt, ndisp=10)["all"]
    assert m["bad0.5"] == 0.0 and m["avgerr"] == 0.0
    m = evaluate_disparity(d, gt, ndisp=12)["all"]  # 25 -> 12, error 2
    assert m["avgerr"] == pytest.approx(2 / 3) and m["bad1.0"] == pytest.approx(100 / 3)


def test_nonocc_vs_all():
    gt = f32([[5, 5, 5, 5], [5, 5, 5, INF]])
    d = f32([[5, 9, 5, 9], [5, 5, INF, 9]])
    mask = np.array([[255, 255, 128, 128], [255, 0, 255, 255]], np.uint8)
    m = evaluate_disparity(d, gt, mask=mask, ndisp=16)
    assert set(m) == {"all", "nonocc"}
    # all: 7 known pixels, 2 bad + 1 invalid
    assert m["all"]["bad2.0"] == pytest.approx(300 / 7)
    assert m["all"]["invalid"] == pytest.approx(100 / 7)
    # nonocc: pixels (0,0) (0,1) (1,0) (1,2); (1,3) has unknown GT -> 1 bad + 1 invalid of 4
    assert m["nonocc"]["bad2.0"] == 50.0
    assert m["nonocc"]["invalid"] == 25.0
    assert m["nonocc"]["avgerr"] == pytest.approx(4 / 3)


def test_empty_region_is_nan():
    gt = f32([[INF, INF]])
    m = evaluate_disparity(f32([[1, 2]]), gt, ndisp=4)["all"]
    assert all(math.isnan(v) for v in m.values())


def test_custom_thresholds():
    m = evaluate_disparity(f32([[0, 3]]), f32([[0, 0]]), ndisp=4, thresholds=[1, 3])["all"]
    assert m["bad1.0"] == 50.0 and m["bad3.0"] == 0.0


def test_argument_checks():
    d = np.zeros((2, 3), np.float32)
    with pytest.raises(ValueError, match="same shape"):
        evaluate_disparity(d, np.zeros((3, 2), np.float32), ndisp=4)
    with pytest.raises(ValueError, match="rank"):
        evaluate_disparity(np.zeros(6, np.float32), np.zeros(6, np.float32), ndisp=4)
    with pytest.raises(TypeError, match="disparity"):
        evaluate_disparity(d.astype(np.int32), d, ndisp=4)
    with pytest.raises(ValueError, match="ndisp"):
        evaluate_disparity(d, d, ndisp=0)
    with pytest.raises(ValueError, match="mask"):
        evaluate_disparity(d, d, mask=np.zeros((2, 2), np.uint8), ndisp=4)
    with pytest.raises(ValueError, match="thresholds"):
        evaluate_disparity(d, d, ndisp=4, thresholds=())
    with pytest.raises(TypeError):
        evaluate_disparity(d, d, None, 4)  # options are keyword-only


SCENES = [
    "Adirondack", "ArtL", "Jadeplant", "Motorcycle", "MotorcycleE", "Piano", "PianoL", "Pipes",
    "Playroom", "Playtable", "PlaytableP", "Recycle", "Shelves", "Teddy", "Vintage",
]  # fmt: skip
SSW_ALL = [14.2, 23.6, 54.8, 13.6, 13.1, 16.3, 25.9, 22.6, 29.6, 25.3, 15.6, 12.8, 17.1, 14.6, 44.3]
SSW_NONOCC = [9.7, 8.71, 34.5, 6.6, 6.08, 11.9, 22.3, 9.97, 14, 19.2, 9.23, 8.93, 14.7, 5.95, 39.2]


def test_training_weights():
    assert sorted(MIDDEVAL3_TRAINING_WEIGHTS) == sorted(SCENES)
    assert sum(MIDDEVAL3_TRAINING_WEIGHTS.values()) == pytest.approx(1.0)
    assert MIDDEVAL3_TRAINING_WEIGHTS["Jadeplant"] == 0.08
    assert MIDDEVAL3_TRAINING_WEIGHTS["Vintage"] == 0.04


def test_weighted_average_matches_paper():
    assert weighted_average(dict(zip(SCENES, SSW_ALL))) == pytest.approx(21.78, abs=0.01)
    assert weighted_average(dict(zip(SCENES, SSW_NONOCC))) == pytest.approx(13.30, abs=0.01)


def test_weighted_average_subset_and_errors():
    assert weighted_average({"Teddy": 10.0, "Vintage": 40.0}) == pytest.approx(20.0)
    assert weighted_average({"a": 1.0, "b": 4.0}, weights={"a": 3, "b": 1}) == pytest.approx(1.75)
    with pytest.raises(ValueError, match="Kitchen"):
        weighted_average({"Teddy": 1.0, "Kitchen": 2.0})
    with pytest.raises(ValueError):
        weighted_average({})
