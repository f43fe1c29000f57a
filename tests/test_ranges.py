"""Disparity ranges ``min_disp .. min_disp + ndisp - 1``, negative ones included."""

import numpy as np
import pytest

import sswjax
from sswjax.api.ranges import check_disparity_range, from_range_frame, range_frame

NDISP = 12


@pytest.fixture(scope="module")
def scene():
    """Views cut from one wide texture: ``left(x) = right(x - 3)``, a square at disparity 7, and
    the right view moved by ``m`` columns (``right_m(y) = right(y + m)``: disparities + m)."""
    base = np.random.default_rng(5).random((48, 100, 3), dtype=np.float32)
    base[:, 20:25] = base[:, 25:26]  # the right view's first 5 columns alike (see test_positive)
    left = base[:, 17:77].copy()
    left[16:32, 20:40] = base[16:32, 33:53]  # left(x) = base(x + 13) = right(x - 7)

    def right(m=0):
        return base[:, 20 + m:80 + m]

    return left, right


def test_negative_range_finds_negative_disparities(scene):
    left, right = scene
    disparity = sswjax.match(left, right(-8), NDISP, min_disp=-8)   # searches -8 .. 3
    assert disparity.shape == left.shape[:2] and disparity.dtype == np.float32
    assert disparity.min() >= -8 and disparity.max() <= 3
    background = np.ones(disparity.shape, bool)
    background[14:34, 18:42] = False
    assert np.mean(np.abs(disparity[background] + 5) < 0.5) > 0.97
    assert np.median(disparity[18:30, 24:36]) == pytest.approx(-1, abs=0.05)
    # The first columns match the right view's first columns (x - d = x + 5 >= 0): a plain
    # shift of the right view, without widening, would forbid them (x - d < 8 in its frame).
    assert np.mean(np.abs(disparity[:, :3] + 5) < 0.5) > 0.9
    # Against the pair at 0 .. 11 moved by -8: only the widened left border may differ.
    plain = sswjax.match(left, right(), NDISP)
    assert np.mean(np.abs(disparity - (plain - 8)) > 0.5) < 0.02


def test_positive_range_is_the_plain_run_shifted(scene):
    # right(5) moved back by 5 columns is right() (its first 5 columns are alike, so the
    # replicated edge is the same): the graph sees the same pair, the result is + 5 exactly.
    left, right = scene
    plain = sswjax.match(left, right(), NDISP)
    ranged = sswjax.match(left, right(5), NDISP, min_disp=5)      # searches 5 .. 16
    np.testing.assert_array_equal(ranged, plain + np.float32(5))
    assert np.median(ranged[18:30, 24:36]) == pytest.approx(12, abs=0.05)
    assert np.median(ranged[:, 45:]) == pytest.approx(8, abs=0.05)


def test_ranges_with_buckets_strips_and_chunks(scene, tiny):
    """How the call runs (buckets, strips, chunks) moves no range: conftest's ``tiny``
    configuration, as the plan is what is tested (the default's ranges are tested above)."""
    left, right = scene
    buckets = sswjax.ShapeBuckets(size_step=32, ndisp_step=16)
    params = tiny.params
    plan = sswjax.ExecutionPlan(strip_rows=16, strip_overlap=8, disparity_chunk=5, buckets=buckets)
    plain = sswjax.match(left, right(), NDISP, params=params, plan=plan)
    ranged = sswjax.match(left, right(5), NDISP, min_disp=5, params=params, plan=plan)
    np.testing.assert_array_equal(ranged, plain + np.float32(5))
    negative = sswjax.match(left, right(-8), NDISP, min_disp=-8, params=params, plan=plan)
    assert negative.shape == left.shape[:2]
    assert negative.min() >= -8 and negative.max() <= 3
    assert np.mean(np.abs(negative[:, 45:] + 5) < 0.5) > 0.95


def test_range_frame_round_trip():
    image = np.arange(2 * 6 * 1, dtype=np.float32).reshape(2, 6, 1)
    for m in (-3, 0, 2):
        left, right = range_frame(image, image, min_disp=m)
        assert left.shape == right.shape == (2, 6 + max(-m, 0), 1)
        pad = max(-m, 0)
        np.testing.assert_array_equal(left[:, pad:], image)           # left unchanged
        x = np.arange(left.shape[1])
        inside = (x - pad - m >= 0) & (x - pad - m < 6)
        np.testing.assert_array_equal(right[:, inside], image[:, (x - pad - m)[inside]])
        frame = np.zeros((2, 6 + pad), np.float32)
        back = from_range_frame(frame, min_disp=m, width=6)
        assert back.shape == (2, 6) and (back == m).all()


@pytest.mark.parametrize("min_disp, message", [
    (60, "disparity range 60..71 leaves no valid disparity for an image 60 pixels wide: it must "
         "meet -59..59"),
    (-71, "disparity range -71..-60 leaves no valid disparity"),
    (2.0, "min_disp must be an integer, got 2.0"),
    (True, "min_disp must be an integer, got True"),
])
def test_range_without_valid_disparity_is_refused(scene, min_disp, message):
    left, right = scene
    with pytest.raises(ValueError, match=message):
        sswjax.match(left, right(), NDISP, min_disp=min_disp)


def test_the_widest_valid_ranges_are_accepted():
    check_disparity_range(60, 12, 59)      # 59 .. 70: the last column can match the first
    check_disparity_range(60, 12, -70)     # -70 .. -59


# ----------------------------------------------------------------------------- command line

def test_cli_min_disp_is_the_api(small_pair, tmp_path, run_cli, tiny):
    import imageio.v3 as iio

    from sswjax.data.io import read_pfm

    folder = small_pair.folder
    code, _, stderr = run_cli(["match", folder / "left.png", folder / "right.png", "--ndisp", 8,
                               "--min-disp", -2, "-o", tmp_path / "d.pfm",
                               "--png", tmp_path / "d.png", *tiny.args])
    assert code == 0, stderr
    disparity = read_pfm(tmp_path / "d.pfm")
    left, right = (iio.imread(folder / name) for name in ("left.png", "right.png"))
    np.testing.assert_array_equal(disparity, sswjax.match(left, right, 8, min_disp=-2,
                                                          params=tiny.params))
    assert disparity.min() >= -2 and disparity.max() <= 5
    assert np.median(disparity) == pytest.approx(small_pair.shift, abs=0.05)


@pytest.mark.parametrize("min_disp, message", [
    ("40", "disparity range 40..47 leaves no valid disparity for an image 40 pixels wide: it must "
           "meet -39..39"),
    ("-47", "disparity range -47..-40 leaves no valid disparity for an image 40 pixels wide: it "
            "must meet -39..39"),
    ("1.5", "argument --min-disp: invalid int value: '1.5'"),
], ids=["beyond-width", "below-minus-width", "not-an-integer"])
def test_cli_range_bad_input(small_pair, tmp_path, run_cli, min_disp, message):
    folder = small_pair.folder
    code, _, stderr = run_cli(["match", folder / "left.png", folder / "right.png", "--ndisp", 8,
                               f"--min-disp={min_disp}", "-o", tmp_path / "d.pfm"])
    assert (code, stderr) == (2, f"sswjax: error: {message}\n")
    assert list(tmp_path.iterdir()) == []


def test_validity_band_on_both_sides_for_negative_disparities():
    # x - d < 0 (left of the right image) and x - d > W - 1 (right of it) are both the band.
    from sswjax.stages.confidence import LEFT_BAND, validity_mask

    disparity = np.array([[1.5, -2.0, 0.0, -1.0, -0.5]], np.float32)   # x - d: -1.5 3 2 4 4.5
    bits = validity_mask(disparity, np.ones_like(disparity), np.zeros(disparity.shape, bool),
                         threshold=0.0)
    assert (np.asarray(bits) & LEFT_BAND).tolist() == [[2, 0, 0, 0, 2]]
