"""KITTI's 16-bit disparity PNG, written by ``write_scaled_disparity`` and read back by the
KITTI reader of the benchmark layouts."""

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.data.io import InputError, read_pfm
from sswjax.data.scaled import read_scaled_disparity, write_scaled_disparity


def test_kitti_png_round_trip(tmp_path):
    disparity = np.array([[0.0, 1.5, np.inf, np.nan, -np.inf],
                          [-3.0, 255.99, 256.5, 1 / 1024, 100.12345]], np.float32)
    path = tmp_path / "000000_10.png"
    write_scaled_disparity(path, disparity, scale=256)
    stored = iio.imread(path)
    assert stored.dtype == np.uint16
    # round(d * 256); 0 for invalid: non-finite, <= 0, rounding to 0, beyond 65535 / 256.
    assert stored.tolist() == [[0, 384, 0, 0, 0], [0, 65533, 0, 0, round(100.12345 * 256)]]
    back = read_scaled_disparity(path, scale=256)
    valid = stored > 0
    np.testing.assert_allclose(back[valid], disparity[valid], atol=1 / 512)
    assert np.isinf(back[~valid]).all()


def test_kitti_png_of_random_maps_within_half_a_step(tmp_path):
    disparity = np.random.default_rng(0).uniform(0.01, 255.0, (7, 9)).astype(np.float32)
    write_scaled_disparity(tmp_path / "d.png", disparity)          # scale 256 by default
    back = read_scaled_disparity(tmp_path / "d.png", scale=256)
    assert np.abs(back - disparity).max() <= 1 / 512 + 1e-6


@pytest.mark.parametrize("disparity, scale, error", [
    (np.zeros(4, np.float32), 256, ValueError),
    (np.zeros((2, 2), np.int32), 256, TypeError),
    (np.zeros((2, 2), np.float32), 0, ValueError),
    (np.zeros((2, 2), np.float32), float("inf"), ValueError),
])
def test_kitti_png_bad_arguments(tmp_path, disparity, scale, error):
    with pytest.raises(error):
        write_scaled_disparity(tmp_path / "d.png", disparity, scale=scale)
    assert list(tmp_path.iterdir()) == []


def test_kitti_png_into_a_missing_folder(tmp_path):
    with pytest.raises(InputError, match="cannot write"):
        write_scaled_disparity(tmp_path / "no" / "d.png", np.ones((2, 2), np.float32))


def test_cli_kitti_png(small_pair, tmp_path, run_cli, tiny):
    folder = small_pair.folder
    code, _, stderr = run_cli(["match", folder / "left.png", folder / "right.png", "--ndisp",
                               small_pair.ndisp, "-o", tmp_path / "d.pfm",
                               "--kitti-png", tmp_path / "000000_10.png", *tiny.args])
    assert code == 0, stderr
    disparity = read_pfm(tmp_path / "d.pfm")
    back = read_scaled_disparity(tmp_path / "000000_10.png", scale=256)
    valid = disparity > 0
    np.testing.assert_allclose(back[valid], disparity[valid], atol=1 / 512)
    assert np.isinf(back[~valid]).all()
