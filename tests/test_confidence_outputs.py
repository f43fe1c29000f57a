"""Confidence and validity through the front door: ``sswjax.match_with_confidence`` and
``sswjax match --confidence/--validity/--invalid-as-inf``."""

import imageio.v3 as iio
import numpy as np
import pytest

import sswjax
from sswjax.data.io import read_pfm
from sswjax.stages.confidence import LEFT_BAND, LOW_CONFIDENCE, LR_FAILED

# The paper's method without superpixels: its side windows keep the left band and the
# occlusion left of the square as the first test reads them (conftest's 3 x 3 box does not:
# a pixel of the band finds disparity 0). The other tests take conftest's tiny configuration.
PARAMS = sswjax.preset("paper").replace(segments=None)


@pytest.fixture(scope="module")
def pair(square_pair):
    return square_pair


def test_match_with_confidence_is_match_with_more(pair):
    out = sswjax.match_with_confidence(*pair, 12, params=PARAMS)
    assert isinstance(out, sswjax.Matched)
    np.testing.assert_array_equal(out.disparity, sswjax.match(*pair, 12, params=PARAMS))
    assert out.confidence.dtype == np.float32 and out.confidence.shape == (90, 60)
    assert out.validity.dtype == np.uint8 and out.validity.shape == (90, 60)
    assert 0 <= out.confidence.min() and out.confidence.max() <= 1
    # The left band: x - d < 0 for the first columns (disparity 3).
    assert (out.validity[:, :2] & LEFT_BAND).all()
    assert not (out.validity[:, 12:] & LEFT_BAND).any()
    # Left of the square (x = 16..19, here 18 and 19) the background is hidden in the right view: the check fails.
    occluded = out.validity[32:58, 18:20]
    assert (occluded & LR_FAILED).mean() > 0.7
    assert np.median(out.confidence[:, 12:]) > 3 * np.median(out.confidence[32:58, 18:20])
    # The threshold only moves bit 2.
    none = sswjax.match_with_confidence(*pair, 12, params=PARAMS, low_confidence=0.0)
    assert not (none.validity & LOW_CONFIDENCE).any()
    np.testing.assert_array_equal(none.validity, out.validity & ~np.uint8(LOW_CONFIDENCE))
    everything = sswjax.match_with_confidence(*pair, 12, params=PARAMS, low_confidence=1.0)
    assert (everything.validity & LOW_CONFIDENCE).mean() > 0.99


def test_strips_and_buckets_stitch_every_output(pair, tiny):
    whole = sswjax.match_with_confidence(*pair, 12, params=tiny.params)
    # Without superpixels every stage sees a few rows around a pixel: exact strips.
    strips = sswjax.match_with_confidence(*pair, 12, params=tiny.params, plan=sswjax.ExecutionPlan(
        strip_rows=20, strip_overlap=24))
    for name in sswjax.Matched._fields:
        np.testing.assert_array_equal(getattr(strips, name), getattr(whole, name), err_msg=name)
    bucketed = sswjax.match_with_confidence(*pair, 12, params=tiny.params,
                                            buckets=sswjax.ShapeBuckets(32, 16))
    assert all(getattr(bucketed, name).shape == (90, 60) for name in sswjax.Matched._fields)
    np.testing.assert_array_equal(bucketed.disparity, sswjax.match(
        *pair, 12, params=tiny.params, buckets=sswjax.ShapeBuckets(32, 16)))
    # Padding the right border (4 columns, edge-replicated) changes the right view's winners
    # near it, so the last columns differ; elsewhere a pixel here and there.
    inner = (slice(None), slice(0, 54))
    assert np.mean(np.abs(bucketed.confidence - whole.confidence)[inner] > 0.01) < 0.01
    assert np.mean((bucketed.validity != whole.validity)[inner]) < 0.01


def test_sgm_outputs_and_min_disp(pair, tiny):
    params, plan = sswjax.preset("accurate"), sswjax.ExecutionPlan(strip_rows=40, strip_overlap=16)
    out = sswjax.match_with_confidence(*pair, 12, params=params, plan=plan)
    np.testing.assert_array_equal(out.disparity, sswjax.match(*pair, 12, params=params, plan=plan))
    assert np.median(out.confidence[35:55, 30:40]) > 0.2
    # A range starting at 2: the band is judged on the final disparity (x - d < 0).
    shifted = sswjax.match_with_confidence(*pair, 10, min_disp=2, params=tiny.params)
    band = np.arange(60)[None, :] - shifted.disparity < 0
    np.testing.assert_array_equal((shifted.validity & LEFT_BAND) > 0, band)


def test_api_rejects_bad_options(pair):
    with pytest.raises(ValueError, match="low_confidence must be a number in"):
        sswjax.match_with_confidence(*pair, 12, low_confidence=1.5)
    with pytest.raises(ValueError, match="unknown confidence measure"):
        sswjax.match_with_confidence(*pair, 12, measure="peak")


def test_cli_confidence_by_its_extension(small_pair, run_cli, tmp_path, tiny):
    left, right = small_pair.folder / "left.png", small_pair.folder / "right.png"
    maps = [tmp_path / name for name in ("c.pfm", "c.npy", "c.tif")]
    for path in maps:
        code, _, err = run_cli(["match", left, right, "--ndisp", 8, "-o", tmp_path / "d.pfm",
                                "--confidence", path, *tiny.args])
        assert code == 0, err
    confidence = read_pfm(maps[0])
    assert confidence.shape == (small_pair.height, small_pair.width)
    np.testing.assert_array_equal(np.load(maps[1]), confidence)
    np.testing.assert_array_equal(iio.imread(maps[2]), confidence)


def test_cli_confidence_validity_and_inf(small_pair, run_cli, tmp_path, tiny):
    left, right = small_pair.folder / "left.png", small_pair.folder / "right.png"
    plain, inf = tmp_path / "plain.pfm", tmp_path / "inf.pfm"
    conf, valid = tmp_path / "conf.pfm", tmp_path / "valid.png"
    code, _, err = run_cli(["match", left, right, "--ndisp", 8, "-o", plain, *tiny.args])
    assert code == 0, err
    code, _, err = run_cli(["match", left, right, "--ndisp", 8, "-o", inf, "--confidence", conf,
                            "--validity", valid, "--invalid-as-inf", *tiny.args])
    assert code == 0, err
    dense, sparse = read_pfm(plain), read_pfm(inf)
    confidence, validity = read_pfm(conf), iio.imread(valid)
    assert validity.dtype == np.uint8 and validity.shape == dense.shape
    assert confidence.dtype == np.float32 and 0 <= confidence.min() and confidence.max() <= 1
    assert (validity[:, :small_pair.shift - 1] & LEFT_BAND).all()
    np.testing.assert_array_equal(np.isinf(sparse), validity != 0)
    np.testing.assert_array_equal(sparse[validity == 0], dense[validity == 0])
    # Without --invalid-as-inf the -o map is the dense one.
    code, _, err = run_cli(["match", left, right, "--ndisp", 8, "-o", inf, "--validity", valid,
                            *tiny.args])
    assert code == 0, err
    np.testing.assert_array_equal(read_pfm(inf), dense)


@pytest.mark.parametrize("case", ["validity-missing-folder", "confidence-missing-folder",
                                  "validity-is-a-folder", "threshold-out-of-range", "folders",
                                  "confidence-as-png", "validity-as-pfm", "validity-is-left"])
def test_cli_confidence_bad_input(case, small_pair, run_cli, tmp_path):
    left, right = small_pair.folder / "left.png", small_pair.folder / "right.png"
    out = tmp_path / "d.pfm"
    extra, message = {
        "validity-missing-folder": (["--validity", tmp_path / "nope" / "v.png"],
                                    "output folder does not exist"),
        "confidence-missing-folder": (["--confidence", tmp_path / "nope" / "c.pfm"],
                                      "output folder does not exist"),
        "validity-is-a-folder": (["--validity", tmp_path], "is a folder, expected a file name"),
        "threshold-out-of-range": (["--validity", tmp_path / "v.png", "--low-confidence", "2"],
                                   "argument --low-confidence: expected a number in [0, 1], got '2'"),
        "folders": (["--invalid-as-inf"], "take one pair, not folders"),
        "confidence-as-png": (["--confidence", tmp_path / "c.png"],
                              "unsupported extension '.png'; --confidence writes .pfm, .npy"),
        "validity-as-pfm": (["--validity", tmp_path / "v.pfm"],
                            "unsupported extension '.pfm'; --validity writes .png (8-bit)"),
        "validity-is-left": (["--validity", left],
                             f"--validity {left} is the same file as the input LEFT {left}"),
    }[case]
    if case == "folders":
        left = right = small_pair.folder
    code, stdout, err = run_cli(["match", left, right, "--ndisp", 8, "-o", out, *extra])
    assert code == 2
    assert err.startswith("sswjax: error: ") and err.count("\n") == 1 and message in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []     # nothing written, no debris
