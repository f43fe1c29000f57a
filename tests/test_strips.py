"""Matching in horizontal strips (``ExecutionPlan.strip_rows``): memory follows the strip, results
the image."""

import imageio.v3 as iio
import numpy as np
import pytest

import sswjax
from sswjax import ExecutionPlan
from sswjax.data.io import read_image, read_pfm


@pytest.fixture(scope="module")
def pair(square_pair):
    return square_pair


def test_local_method_in_strips_equals_the_whole_image(pair):
    # Without superpixels and SGM every stage sees a few rows around a pixel (census, side
    # windows, medians): strips with a wide enough overlap reproduce the whole image exactly.
    params = sswjax.preset("paper").replace(segments=None)
    whole = sswjax.match(*pair, 12, params=params)
    strips = sswjax.match(*pair, 12, params=params,
                          plan=ExecutionPlan(strip_rows=20, strip_overlap=24))
    np.testing.assert_array_equal(strips, whole)


def test_sgm_in_strips_stays_close_to_the_whole_image(pair):
    params = sswjax.preset("accurate").replace(alignment=None)
    whole = sswjax.match(*pair, 12, params=params)
    strips = sswjax.match(*pair, 12, params=params,
                          plan=ExecutionPlan(strip_rows=30, strip_overlap=16, carry_paths=False))
    assert strips.shape == whole.shape
    assert np.mean(np.abs(strips - whole) > 0.5) < 0.02   # vertical paths restart at the seams
    assert np.median(strips[35:55, 30:40]) == pytest.approx(7, abs=0.05)


def test_strips_with_buckets(pair):
    params = sswjax.preset("paper").replace(segments=None)
    plan = ExecutionPlan(strip_rows=40, strip_overlap=24, buckets=sswjax.ShapeBuckets(32, 16))
    bucketed = sswjax.match(*pair, 12, params=params, plan=plan)
    # the buckets given beside the plan are the plan's buckets
    np.testing.assert_array_equal(sswjax.match(*pair, 12, params=params, buckets=plan.buckets,
                                               plan=plan._replace(buckets=None)), bucketed)
    with pytest.raises(ValueError, match="buckets and plan.buckets differ"):
        sswjax.match(*pair, 12, params=params, plan=plan, buckets=sswjax.ShapeBuckets(64, 16))
    with pytest.raises(ValueError, match="plan.strip_rows must be an integer"):
        sswjax.match(*pair, 12, params=params, plan=ExecutionPlan(strip_rows=-1))
    assert bucketed.shape == (90, 60) and np.isfinite(bucketed).all()


NO_ALIGNMENT = sswjax.preset("accurate").replace(alignment=None)


@pytest.fixture(scope="module")
def striped_pair():
    """A 160x64 pair at disparity 7: texture on the bottom 60 rows, above them vertical
    stripes of period 4 (every fourth disparity matches alike), so that the semi-global paths
    along the rows decide the upper part."""
    rng = np.random.default_rng(5)
    right = rng.random((160, 64, 3), dtype=np.float32)
    right[:100] = np.array([0.2, 0.8, 0.4, 0.6], np.float32)[np.arange(64) % 4][None, :, None]
    return np.roll(right, 7, axis=1), right


def test_carried_paths_give_the_whole_images_map_in_strips(striped_pair):
    # Strips of 16 rows see 40 more on either side: without the paths carried from strip to
    # strip, those of the stripes restart in each window and 30 % of the pixels change.
    # (Without the vertical alignment, whose first pass would compile for nothing here:
    # tests/test_alignment.py tests it in strips.)
    params = NO_ALIGNMENT
    whole = sswjax.match(*striped_pair, 16, params=params)
    plan = ExecutionPlan(strip_rows=16, strip_overlap=40)
    np.testing.assert_array_equal(sswjax.match(*striped_pair, 16, params=params, plan=plan),
                                  whole)
    restarted = sswjax.match(*striped_pair, 16, params=params,
                             plan=plan._replace(carry_paths=False))
    assert np.mean(restarted != whole) > 0.1
    with pytest.raises(ValueError, match="plan.carry_paths must be True or False"):
        sswjax.match(*striped_pair, 16, params=params, plan=plan._replace(carry_paths=1))


def test_the_command_line_carries_the_paths_unless_told_not_to(striped_pair, tmp_path, run_cli):
    # The command line runs the stored graphs (persistent cache on): the seeds go in and out
    # of their serialized form too. The method is the test above's (accurate without the
    # alignment): the API's maps here are the graphs it compiled.
    for name, image in zip(("l.png", "r.png"), striped_pair):
        iio.imwrite(tmp_path / name, np.round(image * 255).astype(np.uint8))
    left, right = read_image(tmp_path / "l.png"), read_image(tmp_path / "r.png")
    for carry, flag in ((True, []), (False, ["--no-carry-paths"])):
        code, _, stderr = run_cli(["match", tmp_path / "l.png", tmp_path / "r.png", "--ndisp", 16,
                                   "--set", "alignment=none", "--strip-rows", 16,
                                   "--strip-overlap", 40, *flag, "-o", tmp_path / f"{carry}.pfm"])
        assert code == 0, stderr
        plan = ExecutionPlan(strip_rows=16, strip_overlap=40, carry_paths=carry)
        np.testing.assert_array_equal(read_pfm(tmp_path / f"{carry}.pfm"),
                                      sswjax.match(left, right, 16, params=NO_ALIGNMENT,
                                                   plan=plan))
