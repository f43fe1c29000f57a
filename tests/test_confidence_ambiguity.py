"""Where the matching cost has no minimum that stands out (issue 72, item 1): blank, saturated
and flat-gradient pairs and regions, and repeated patterns, through
``sswjax.match_with_confidence`` and ``sswjax match --confidence/--validity``.

Confidence there must be low (near 0) and validity bit 4 (``AMBIGUOUS``) set, while textured
pixels keep theirs and every disparity map stays as it was. One image shape (60 x 90 gray,
16 disparities) throughout, so each preset compiles once.
"""

import imageio.v3 as iio
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sswjax
from sswjax.data.io import read_pfm
from sswjax.stages.confidence import AMBIGUOUS, DEFAULT_THRESHOLD, LOW_CONFIDENCE

HEIGHT, WIDTH, NDISP, SHIFT = 60, 90, 16, 3


def _flat(kind: str) -> np.ndarray:
    """A uint8 (60, 90) image without texture along its rows."""
    if kind == "blank":
        return np.full((HEIGHT, WIDTH), 128, np.uint8)
    if kind == "saturated":
        return np.full((HEIGHT, WIDTH), 255, np.uint8)
    # A vertical ramp: each row one value, so every disparity matches equally well (a ramp
    # along the rows would be matchable).
    ramp = np.linspace(20, 230, HEIGHT).round().astype(np.uint8)
    return np.repeat(ramp[:, None], WIDTH, axis=1)


def _textured(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A random uint8 (60, 90) pair with disparity 3."""
    right = np.random.default_rng(seed).integers(0, 256, (HEIGHT, WIDTH), dtype=np.uint8)
    return np.roll(right, SHIFT, axis=1), right


def _with_region(pair, region: np.ndarray, rows: slice, cols: slice):
    """The pair with ``region`` pasted at the same place in both views."""
    left, right = (image.copy() for image in pair)
    left[rows, cols] = region
    right[rows, cols] = region
    return left, right


# Columns x >= 4: at x = 0 and 1 only disparities 0 and 1 land inside the right image, so the
# curve's other disparities cost the border's value and the winner does stand out (x < 4 at
# full resolution for fast, whose cues are those of its halved pair).
INSIDE = (slice(None), slice(4, None))


@pytest.mark.parametrize("kind", ["blank", "saturated", "ramp"])
def test_a_pair_without_texture_is_ambiguous_not_certain(kind):
    image = _flat(kind)
    out = sswjax.match_with_confidence(image, image.copy(), ndisp=NDISP)
    np.testing.assert_array_equal(out.disparity, sswjax.match(image, image.copy(), ndisp=NDISP))
    assert out.confidence[INSIDE].max() < 0.01, out.confidence.max()
    assert (out.validity[INSIDE] & AMBIGUOUS).all()
    assert (out.validity[INSIDE] & LOW_CONFIDENCE).all()


# Each way the cues are made: accurate (the default, above) the paths' sums with a fold of the
# stored cost; paper the aggregated cost's own fold; fast the halved pair's, doubled; balanced
# the band's (finest is accurate's way with other options).
@pytest.mark.parametrize("name", ["paper", "fast", "balanced"])
def test_every_way_to_the_cues_rates_a_blank_pair_ambiguous(name):
    image = _flat("blank")
    params = sswjax.preset(name)
    out = sswjax.match_with_confidence(image, image.copy(), ndisp=NDISP, params=params)
    assert out.confidence[INSIDE].max() < 0.01, (name, out.confidence.max())
    assert (out.validity[INSIDE] & AMBIGUOUS).all(), name


def test_flat_regions_of_a_textured_pair_are_ambiguous_and_texture_is_not():
    rows, cols = slice(20, 44), slice(30, 80)
    left, right = _with_region(_textured(5), _flat("saturated")[rows, cols], rows, cols)
    out = sswjax.match_with_confidence(left, right, ndisp=NDISP)
    inner = (slice(26, 38), slice(40, 70))  # away from the region's edges (the windows)
    assert (out.validity[inner] & AMBIGUOUS).all()
    assert out.confidence[inner].max() < 0.01
    textured = np.ones((HEIGHT, WIDTH), bool)
    textured[12:52, 22:88] = False
    textured[:, :NDISP] = False  # the left band
    assert (out.validity[textured] & AMBIGUOUS).mean() < 0.02
    assert np.median(out.confidence[textured]) > 0.5


def test_command_line_writes_the_low_confidence_and_the_bit(run_cli, tmp_path):
    image = _flat("blank")
    iio.imwrite(tmp_path / "left.png", image)
    iio.imwrite(tmp_path / "right.png", image)
    code, _, err = run_cli(["match", tmp_path / "left.png", tmp_path / "right.png",
                            "--ndisp", NDISP, "-o", tmp_path / "d.pfm",
                            "--confidence", tmp_path / "c.pfm",
                            "--validity", tmp_path / "v.png"])
    assert code == 0, err
    confidence = read_pfm(tmp_path / "c.pfm")
    validity = iio.imread(tmp_path / "v.png")
    assert confidence.shape == validity.shape == (HEIGHT, WIDTH)
    assert confidence[INSIDE].max() < 0.01
    assert (validity[INSIDE] & AMBIGUOUS).all()
    assert (validity[INSIDE] & LOW_CONFIDENCE).all()
    assert DEFAULT_THRESHOLD > 0.01


def _region(kind: str, level: int, period: int, seed: int, shape) -> np.ndarray:
    if kind == "textureless":
        return np.full(shape, level, np.uint8)
    if kind == "saturated":
        return np.full(shape, 255, np.uint8)
    # Vertical stripes of a random profile repeating every `period` columns: disparities
    # `period` apart match it equally well.
    profile = np.random.default_rng(seed).integers(0, 256, period, dtype=np.uint8)
    return np.broadcast_to(np.resize(profile, shape[1])[None, :], shape).copy()


@settings(max_examples=8, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(["textureless", "saturated", "repeated"]),
       level=st.integers(0, 255), period=st.integers(2, 5), seed=st.integers(0, 2 ** 16),
       top=st.integers(18, 30), left_col=st.integers(24, 36))
def test_regions_without_a_distinct_minimum_are_less_confident_than_texture(
        kind, level, period, seed, top, left_col):
    rows, cols = slice(top, top + 24), slice(left_col, left_col + 44)
    region = _region(kind, level, period, seed, (24, 44))
    left, right = _with_region(_textured(seed), region, rows, cols)
    out = sswjax.match_with_confidence(left, right, ndisp=NDISP)
    inner = (slice(top + 6, top + 18), slice(left_col + 8, left_col + 36))
    textured = np.ones((HEIGHT, WIDTH), bool)
    textured[top - 8:top + 32, left_col - 8:left_col + 52] = False
    textured[:, :NDISP] = False
    assert out.confidence[inner].mean() < out.confidence[textured].mean() - 0.3, kind
    assert (out.validity[inner] & AMBIGUOUS).mean() > 0.9, kind
