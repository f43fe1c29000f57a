"""The ``sswjax`` command line: outputs, exit codes and one-line errors."""

from __future__ import annotations

import subprocess
import sys

import imageio.v3 as iio
import numpy as np
import pytest

import sswjax
from sswjax.cli import main
from sswjax.data.io import read_image, read_pfm, write_pfm

NDISP = 12


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A textured 40x64 pair with a constant disparity of 4, written as PNGs."""
    folder = tmp_path_factory.mktemp("pair")
    rng = np.random.default_rng(3)
    right = (rng.random((40, 64, 3)) * 255).astype(np.uint8)
    left = np.roll(right, 4, axis=1)
    iio.imwrite(folder / "im0.png", left)
    iio.imwrite(folder / "im1.png", right)
    iio.imwrite(folder / "small.png", right[:20, :30])
    iio.imwrite(folder / "gray.png", right[..., 0])
    return folder


def test_match_writes_pfm_and_png(pair, tmp_path, capsys):
    out = tmp_path / "d.pfm"
    code = main(["match", str(pair / "im0.png"), str(pair / "im1.png"), "--ndisp", str(NDISP),
                 "-o", str(out), "--png", str(tmp_path / "d.png")])
    assert code == 0
    disparity = read_pfm(out)
    assert disparity.shape == (40, 64) and disparity.dtype == np.float32
    assert np.median(disparity[:, 12:]) == pytest.approx(4, abs=0.01)
    assert iio.imread(tmp_path / "d.png").shape == (40, 64, 3)
    assert "wrote" in capsys.readouterr().out


def test_match_gray_colour_mix(pair, tmp_path):
    out = tmp_path / "d.pfm"
    code = main(["match", str(pair / "im0.png"), str(pair / "gray.png"), "--ndisp", "8", "-o", str(out)])
    assert code == 0 and read_pfm(out).shape == (40, 64)


@pytest.mark.parametrize(
    "args, message",
    [
        (["missing.png", "im1.png", "--ndisp", "8"], "not found"),
        (["im0.png", "small.png", "--ndisp", "8"], "differ in size"),
        (["im0.png", "im1.png", "--ndisp", "0"], "ndisp"),
        (["im0.png", "im1.png", "--ndisp", "64"], "ndisp"),
        (["im0.png", "im1.png", "--ndisp", "8", "--params", "missing.json"], "parameter file"),
    ],
)
def test_match_bad_input_one_line_exit_2(pair, tmp_path, capsys, args, message):
    out = tmp_path / "d.pfm"
    write_pfm(out, np.full((2, 3), 7, np.float32))  # an existing result the user had
    argv = ["match"] + [str(pair / a) if a.endswith((".png", ".json")) else a for a in args]
    code = main(argv + ["-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("sswjax: error:") and message in err
    assert (read_pfm(out) == 7).all()  # untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.pfm"]  # no temporary debris


def test_bad_params_json(pair, tmp_path, capsys):
    params = tmp_path / "p.json"
    params.write_text('{"static": {"aggregation_radius": 2.5}}')
    code = main(["match", str(pair / "im0.png"), str(pair / "im1.png"), "--ndisp", "8",
                 "-o", str(tmp_path / "d.pfm"), "--params", str(params)])
    err = capsys.readouterr().err
    assert code == 2 and "aggregation_radius" in err and err.count("\n") == 1


def test_missing_output_folder(pair, tmp_path, capsys):
    code = main(["match", str(pair / "im0.png"), str(pair / "im1.png"), "--ndisp", "8",
                 "-o", str(tmp_path / "nowhere" / "d.pfm")])
    assert code == 2 and "does not exist" in capsys.readouterr().err


def test_console_script_usage_error_has_no_traceback():
    result = subprocess.run(
        [sys.executable, "-m", "sswjax.cli", "match", "a.png"], capture_output=True, text=True
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr and "error" in result.stderr


def test_demo_meets_paper_motorcycle_figure(tmp_path, capsys):
    """The scikit-image Motorcycle demo: bad 2.0 over known pixels <= 13.6 % (paper, Table 1)."""
    assert main(["demo", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    bad2 = float(out.split("bad 2.0:")[1].split("%")[0])
    assert bad2 <= 13.6
    assert read_pfm(tmp_path / "disp0SSW.pfm").shape == (500, 741)
    assert (tmp_path / "disp0SSW.png").stat().st_size > 0


# ----------------------------------------------------------------------------- inputs that must work
# conftest's small_pair: 24x40, disparity 3, as colour, gray, 16-bit gray and RGBA PNGs.


def _match_cli(files, tmp_path, left, right, ndisp=8):  # small_pair.ndisp
    out = tmp_path / "d.pfm"
    assert main(["match", str(files / left), str(files / right), "--ndisp", str(ndisp), "-o", str(out)]) == 0
    return read_pfm(out)


def test_cli_inputs_that_must_work(small_pair, tmp_path, capsys):
    """Colour, gray, 16-bit, RGBA and colour/gray pairs, from files, agree with the API."""
    files, shift, ndisp = small_pair.folder, small_pair.shift, small_pair.ndisp
    colour = _match_cli(files, tmp_path, "left.png", "right.png")
    assert np.median(colour[:, 12:]) == pytest.approx(shift, abs=0.05)
    # RGBA: the alpha channel is dropped, the result is bit-identical
    np.testing.assert_array_equal(_match_cli(files, tmp_path, "left_rgba.png", "right_rgba.png"), colour)
    # gray pairs, 8 and 16 bits (v * 257 / 65535 == v / 255 exactly in float32)
    gray = _match_cli(files, tmp_path, "left_gray.png", "right_gray.png")
    assert np.median(gray[:, 12:]) == pytest.approx(shift, abs=0.05)
    assert read_image(files / "left_gray16.png").dtype == np.uint16
    np.testing.assert_array_equal(_match_cli(files, tmp_path, "left_gray16.png", "right_gray16.png"), gray)
    # colour + gray (either side): both used as gray, the colour one by BT.601 luma, like the API
    mixed = _match_cli(files, tmp_path, "left.png", "right_gray.png")
    assert np.median(mixed[:, 12:]) == pytest.approx(shift, abs=0.05)
    api = sswjax.match(read_image(files / "left.png"), read_image(files / "right_gray.png"), ndisp)
    np.testing.assert_array_equal(mixed, api)
    mixed_other_way = _match_cli(files, tmp_path, "left_gray16.png", "right.png")
    api = sswjax.match(read_image(files / "left_gray16.png"), read_image(files / "right.png"), ndisp)
    np.testing.assert_array_equal(mixed_other_way, api)
    assert "wrote" in capsys.readouterr().out


def test_cli_16bit_colour_png(small_pair, tmp_path):
    """16-bit colour PNGs: all 16 bits read (with OpenCV), and matched like their 8-bit twins."""
    files, height, width = small_pair.folder, small_pair.height, small_pair.width
    cv2 = pytest.importorskip("cv2")
    left8, right8 = read_image(files / "left.png"), read_image(files / "right.png")
    rng = np.random.default_rng(4)
    for name, image in (("left48.png", left8), ("right48.png", right8)):
        # v * 257 plus low-byte noise that only a 16-bit reader sees
        wide = image.astype(np.uint16) * 257 + rng.integers(0, 2, image.shape, dtype=np.uint16)
        assert cv2.imwrite(str(tmp_path / name), wide[..., ::-1])
        np.testing.assert_array_equal(read_image(tmp_path / name), wide)
    rgba = np.concatenate([left8.astype(np.uint16) * 257, np.full((height, width, 1), 65535, np.uint16)], -1)
    assert cv2.imwrite(str(tmp_path / "rgba64.png"), rgba[..., [2, 1, 0, 3]])
    np.testing.assert_array_equal(read_image(tmp_path / "rgba64.png"), rgba[..., :3])
    disparity = _match_cli(tmp_path, tmp_path, "left48.png", "right48.png")
    assert np.median(disparity[:, 12:]) == pytest.approx(small_pair.shift, abs=0.05)


@pytest.mark.parametrize("preset", sorted(sswjax.PRESETS))
def test_match_preset(pair, tmp_path, preset):
    out = tmp_path / "d.pfm"
    code = main(["match", str(pair / "im0.png"), str(pair / "im1.png"), "--ndisp", str(NDISP),
                 "-o", str(out), "--preset", preset])
    assert code == 0
    expected = sswjax.match(read_image(pair / "im0.png"), read_image(pair / "im1.png"), NDISP,
                            params=sswjax.preset(preset))
    np.testing.assert_array_equal(read_pfm(out), expected)


@pytest.mark.parametrize("args, message", [
    (["--preset", "nope"], "argument --preset: invalid choice: 'nope'"),
    (["--preset", "paper", "--params", "p.json"], "argument --params: not allowed with argument --preset"),
])
def test_match_bad_preset_one_line_exit_2(pair, tmp_path, capsys, args, message):
    out = tmp_path / "d.pfm"
    with pytest.raises(SystemExit) as exit_:
        main(["match", str(pair / "im0.png"), str(pair / "im1.png"), "--ndisp", str(NDISP),
              "-o", str(out), *args])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert not out.exists()
