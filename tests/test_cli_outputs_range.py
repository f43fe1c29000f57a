"""Outputs that cannot hold the searched range are refused before any matching (issue 72, 3).

KITTI's 16-bit PNG (``-o d.png``, ``--kitti-png``) stores ``round(d * 256)`` with 0 = invalid:
disparities 0 to 255.99 only, so a negative ``--min-disp`` (or a range past 255) would write
zeros where the map has values, and exit 0. Depth ``baseline * f / (d + doffs)`` is unknown
where ``d + doffs <= 0``: a range entirely there gives no depth and no point. Each is one line,
exit status 2, nothing written; the colour ``--png`` (its colours span the searched range) and
the float formats take any range. The inputs are conftest's ``small_pair`` (24x40).
"""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.data.io import read_pfm

NDISP = 8


def _one_line_error(code, err, message):
    assert code == 2, err
    assert err.startswith("sswjax: error: ") and err.count("\n") == 1, err
    assert message in err, err


@pytest.mark.parametrize(
    "outputs, range_, message",
    [
        (["-o", "neg.png"], ["--min-disp", "-12"],
         "-o {d}/neg.png: a 16-bit PNG holds disparities 0 to 255.99 (round(d * 256), "
         "0 = invalid), and this run searches -12..-5: write the map as .pfm, .npy or .tif "
         "(float32), which hold any disparity"),
        (["-o", "part.png"], ["--min-disp", "-4"],
         "-o {d}/part.png: a 16-bit PNG holds disparities 0 to 255.99 (round(d * 256), "
         "0 = invalid), and this run searches -4..3: write"),
        (["-o", "d.pfm", "--kitti-png", "k.png"], ["--min-disp", "-12"],
         "--kitti-png {d}/k.png: a 16-bit PNG holds disparities 0 to 255.99 (round(d * 256), "
         "0 = invalid), and this run searches -12..-5: write the map with -o OUT.pfm (.npy, "
         ".tif) instead"),
        (["-o", "d.pfm", "--depth", "z.pfm", "--focal", "100", "--baseline", "0.1"],
         ["--min-disp", "-12"],
         "--depth {d}/z.pfm: this run searches disparities -12..-5, and depth baseline * f / "
         "(d + doffs) needs d + doffs > 0 (doffs 0): no pixel would have a depth"),
        (["-o", "d.pfm", "--ply", "c.ply", "--focal", "100", "--baseline", "0.1",
          "--doffs", "2"], ["--min-disp", "-12"],
         "--ply {d}/c.ply: this run searches disparities -12..-5, and depth baseline * f / "
         "(d + doffs) needs d + doffs > 0 (doffs 2): no pixel would have a depth"),
    ],
    ids=["png-negative", "png-partly-negative", "kitti-png-negative", "depth-negative",
         "ply-negative"],
)
def test_outputs_that_cannot_hold_the_range_are_refused(small_pair, tmp_path, run_cli,
                                                         outputs, range_, message):
    files = small_pair.folder
    argv = ["match", files / "left.png", files / "right.png", "--ndisp", NDISP, *range_]
    argv += [tmp_path / word if word.endswith((".png", ".pfm", ".ply")) else word
             for word in outputs]
    code, out, err = run_cli(argv)
    _one_line_error(code, err, message.format(d=tmp_path))
    assert out == "" and list(tmp_path.iterdir()) == []


def test_png_beyond_255_is_refused(texture, tmp_path, run_cli):
    """A range past 255.99 px would write 0 (invalid) for the far end: refused too."""
    right = texture(5, (24, 300, 3))
    iio.imwrite(tmp_path / "l.png", np.roll(right, 3, axis=1))
    iio.imwrite(tmp_path / "r.png", right)
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = run_cli(["match", tmp_path / "l.png", tmp_path / "r.png", "--ndisp", "270",
                            "-o", out / "d.png"])
    _one_line_error(code, err, f"-o {out}/d.png: a 16-bit PNG holds disparities 0 to 255.99 "
                               "(round(d * 256), 0 = invalid), and this run searches 0..269")
    assert list(out.iterdir()) == []


def test_a_negative_range_goes_to_float_maps_colour_png_and_depth_with_doffs(small_pair, tmp_path,
                                                                              run_cli, tiny):
    """What can hold a negative range is written: the float map (negative values kept), the
    colour PNG, and depth where ``doffs`` makes ``d + doffs`` positive; an existing 16-bit PNG
    map of the user survives the refusal of the same run with ``-o`` PNG."""
    files = small_pair.folder
    earlier = tmp_path / "earlier.png"
    iio.imwrite(earlier, np.full((2, 3), 77, np.uint16))
    base = ["match", files / "left.png", files / "right.png", "--ndisp", NDISP, "--min-disp",
            "-12", *tiny.args]
    code, _, err = run_cli([*base, "-o", earlier])
    assert code == 2 and "a 16-bit PNG holds disparities 0 to 255.99" in err
    assert (iio.imread(earlier) == 77).all()
    code, out, err = run_cli([*base, "-o", tmp_path / "d.pfm", "--png", tmp_path / "c.png",
                              "--depth", tmp_path / "z.npy", "--focal", "100", "--baseline",
                              "0.1", "--doffs", "20"])
    assert code == 0, err
    disparity = read_pfm(tmp_path / "d.pfm")
    assert disparity.shape == (24, 40) and (disparity < 0).all()
    assert iio.imread(tmp_path / "c.png").shape == (24, 40, 3)
    depth = np.load(tmp_path / "z.npy")
    assert np.isfinite(depth).all() and (depth > 0).all()


def test_folder_runs_write_pfm_whatever_the_range(small_pair, tmp_path, run_cli):
    """Folder runs write ``<name>.pfm`` maps (any range) and refuse the single-file outputs:
    nothing there can hold less than the range, so nothing is refused for it."""
    left, right = tmp_path / "L", tmp_path / "R"
    left.mkdir()
    right.mkdir()
    (left / "a.png").write_bytes((small_pair.folder / "left.png").read_bytes())
    (right / "a.png").write_bytes((small_pair.folder / "right.png").read_bytes())
    code, _, err = run_cli(["match", left, right, "--ndisp", NDISP, "--min-disp", "-12",
                            "--kitti-png", tmp_path / "k.png", "-o", tmp_path / "out"])
    _one_line_error(code, err, "--kitti-png names one file: with folders only -o OUT_DIR is "
                               "written")

