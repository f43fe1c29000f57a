"""The checks that must fire first: a pair too small for the census window is refused as such
(not with an empty ndisp range "[1, 0]"), and an ndisp beyond the width is refused as such
before any memory is estimated (not with a memory estimate of thousands of GB).

Issue 72, item 8. Nothing here matches a pair: every case is refused before the graph runs, so
the file compiles nothing. Images are conftest's ``texture`` (24x40) and cuts of it.
"""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest

import sswjax
from sswjax.data.io import read_pfm, write_pfm

CENSUS = "are smaller than the census window 9x7: both sides must be at least 9 pixels"


def _assert_one_line_error(code, err, message):
    assert code == 2, err
    assert err.startswith("sswjax: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert message in err, err


@pytest.fixture(scope="module")
def images(tmp_path_factory, texture):
    """A 24x40 pair, a 24x1 one (1 pixel wide) and, as folders, each of them."""
    folder = tmp_path_factory.mktemp("early")
    right = texture(0)
    left = np.roll(right, 3, axis=1)
    for name, (l, r) in {"pair": (left, right), "thin": (left[:, :1], right[:, :1])}.items():
        iio.imwrite(folder / f"{name}_l.png", l)
        iio.imwrite(folder / f"{name}_r.png", r)
        for side, image in (("L", l), ("R", r)):
            (folder / f"{name}_{side}").mkdir()
            iio.imwrite(folder / f"{name}_{side}" / "a.png", image)
    return folder


@pytest.mark.parametrize("ndisp", [8, None], ids=["ndisp-8", "ndisp-estimated"])
@pytest.mark.parametrize("function", ["match", "match_with_confidence"])
def test_api_one_pixel_wide_pair_is_below_the_census_window(texture, function, ndisp):
    right = texture(0)[:, :1]
    with pytest.raises(ValueError) as error:
        getattr(sswjax, function)(right, right, ndisp)
    assert str(error.value) == f"images of 1x24 {CENSUS}"


def test_api_huge_ndisp_is_refused_against_the_width(texture):
    right = texture(0)
    with pytest.raises(ValueError) as error:
        sswjax.match(right, right, 10**9, min_disp=-2)
    assert str(error.value) == "ndisp must be in [1, 39] for this width, got 1000000000"


@pytest.mark.parametrize("extra", [["--ndisp", "8"], ["--ndisp", "auto"]], ids=["ndisp-8", "auto"])
@pytest.mark.parametrize("form", ["files", "folders"])
def test_cli_one_pixel_wide_pair_is_below_the_census_window(images, tmp_path, run_cli, form,
                                                              extra):
    if form == "folders" and extra[1] == "auto":
        pytest.skip("--ndisp auto takes one pair")
    pair = ([images / "thin_l.png", images / "thin_r.png"] if form == "files"
            else [images / "thin_L", images / "thin_R"])
    out = tmp_path / ("d.pfm" if form == "files" else "out")
    code, _, err = run_cli(["match", *pair, *extra, "-o", out])
    where = "" if form == "files" else "pair a.png: "
    _assert_one_line_error(code, err, f"{where}images of 1x24 {CENSUS}")
    assert "[1, 0]" not in err and "None" not in err
    assert not out.exists()


@pytest.mark.parametrize("min_disp", [[], ["--min-disp", "-2"]], ids=["from-0", "from-minus-2"])
@pytest.mark.parametrize("form", ["files", "folders"])
def test_cli_huge_ndisp_is_refused_before_the_memory_estimate(images, tmp_path, run_cli, form,
                                                               min_disp):
    pair = ([images / "pair_l.png", images / "pair_r.png"] if form == "files"
            else [images / "pair_L", images / "pair_R"])
    out = tmp_path / ("d.pfm" if form == "files" else "out")
    if form == "files":
        write_pfm(out, np.full((2, 3), 7, np.float32))  # the user's earlier result
    code, _, err = run_cli(["match", *pair, "--ndisp", "1000000000", *min_disp, "-o", out])
    message = ("ndisp must be in [1, 39] for this width, got 1000000000" if form == "files"
               else "ndisp must be in [1, 39] for the narrowest pair a.png, got 1000000000")
    _assert_one_line_error(code, err, message)
    assert "GB" not in err
    if form == "files":
        assert (read_pfm(out) == 7).all()
        assert [p.name for p in tmp_path.iterdir()] == ["d.pfm"]
    else:
        assert not out.exists()
