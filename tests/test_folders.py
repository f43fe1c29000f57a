"""``sswjax match LEFT_DIR RIGHT_DIR -o OUT_DIR``: pairs by name, grouped by shape, atomic
outputs, ``--resume``, Ctrl-C, and the bad folders."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest

import sswjax
from sswjax.data.io import read_pfm, write_pfm
from sswjax.cli import folders as cli_folders
from sswjax.cli.folders import folder_pairs, image_size

SIZES = {"b.png": (24, 40), "a.png": (30, 48), "c.png": (24, 40)}  # two shapes
SHIFT = 3


@pytest.fixture()
def folders(tmp_path, texture):
    """``L/`` and ``R/`` with the pairs of ``SIZES`` (disparity 3), a stray text file, and an
    image only in ``L/``."""
    left, right = tmp_path / "L", tmp_path / "R"
    left.mkdir()
    right.mkdir()
    for seed, (name, (height, width)) in enumerate(SIZES.items()):
        image = texture(seed, (height, width, 3))
        iio.imwrite(left / name, np.roll(image, SHIFT, axis=1))
        iio.imwrite(right / name, image)
    (left / "notes.txt").write_text("not an image")
    iio.imwrite(left / "only-left.png", texture(9, (24, 40, 3)))
    return left, right


@pytest.fixture()
def fake_match(monkeypatch):
    """The folder command's ``match`` replaced by a recorder returning the pair's width as
    disparity; the call ``fail_at`` (if set) raises KeyboardInterrupt."""
    calls = []

    def match(left, right, ndisp, **kwargs):
        calls.append((left.shape[:2], kwargs["plan"].buckets))
        if len(calls) == fake.fail_at:
            raise KeyboardInterrupt
        return np.full(left.shape[:2], float(left.shape[1]), np.float32)

    class Fake:
        fail_at = None

    fake = Fake()
    fake.calls = calls
    monkeypatch.setattr(cli_folders, "match", match)
    return fake


def test_pairs_by_name_sorted_by_shape_then_resume(folders, tmp_path, run_cli, fake_match):
    left, right = folders
    out = tmp_path / "out"
    code, stdout, stderr = run_cli(["match", left, right, "--ndisp", 8, "-o", out])
    assert code == 0, stderr
    # b and c (24x40) run together, then a (30x48): one compilation per shape
    assert [shape for shape, _ in fake_match.calls] == [(24, 40), (24, 40), (30, 48)]
    assert sorted(p.name for p in out.iterdir()) == [".sswjax-run.json", "a.pfm", "b.pfm",
                                                     "c.pfm"]
    assert read_pfm(out / "a.pfm").shape == (30, 48) and read_pfm(out / "a.pfm")[0, 0] == 48
    assert "wrote 3 disparity maps to" in stdout and "(2 shapes" in stdout and "pairs" in stderr
    write_pfm(out / "c.pfm", np.zeros((2, 2), np.float32))  # damaged: wrong size
    fake_match.calls.clear()
    code, stdout, _ = run_cli(["match", left, right, "--ndisp", 8, "-o", out, "--resume"])
    assert code == 0 and [shape for shape, _ in fake_match.calls] == [(24, 40)]
    assert read_pfm(out / "c.pfm").shape == (24, 40) and "2 kept from before" in stdout


def test_bucket_groups_by_bucketed_shape(folders, tmp_path, run_cli, fake_match):
    left, right = folders
    assert run_cli(["match", left, right, "--ndisp", 8, "-o", tmp_path / "o", "--bucket"])[0] == 0
    assert all(buckets == sswjax.ShapeBuckets() for _, buckets in fake_match.calls)
    assert [shape for shape, _ in fake_match.calls] == [(30, 48), (24, 40), (24, 40)]  # by name


def test_ctrl_c_keeps_finished_maps_and_says_how_to_resume(folders, tmp_path, run_cli, fake_match):
    left, right = folders
    out = tmp_path / "out"
    fake_match.fail_at = 2
    code, _, stderr = run_cli(["match", left, right, "--ndisp", 8, "-o", out])
    assert code == 130
    # finished, nothing half-written; the record lists the finished map
    assert sorted(p.name for p in out.iterdir()) == [".sswjax-run.json", "b.pfm"]
    message = stderr.strip().splitlines()[-1]
    assert message.startswith(f"sswjax: interrupted; 1 of 3 disparity maps are saved in {out}")
    assert message.endswith(f"-o {out} --resume")


def test_resume_refuses_other_settings_and_keeps_only_its_own_maps(folders, tmp_path, run_cli,
                                                                 fake_match):
    left, right = folders
    out = tmp_path / "out"
    fake_match.fail_at = 2
    assert run_cli(["match", left, right, "--ndisp", 8, "-o", out])[0] == 130
    for extra, changed in [(["--ndisp", 16], "ndisp 16 (was 8)"),
                           (["--ndisp", 8, "--preset", "fast"], "params.coarse {...} (was null)"),
                           (["--ndisp", 8, "--set", "optimizer.p2=1.3"],
                            "params.optimizer.p2 1.3 (was 2.4)"),
                           (["--ndisp", 8, "--bucket"], "buckets [256, 96] (was null)")]:
        code, _, stderr = run_cli(["match", left, right, "-o", out, "--resume", *extra])
        assert code == 2 and stderr.count("\n") == 1, stderr
        assert f"cannot --resume {out} with other settings than it was made with" in stderr
        assert changed in stderr, stderr
    # a map of another run in the folder is not the run's: recomputed
    write_pfm(out / "c.pfm", np.zeros((24, 40), np.float32))
    fake_match.fail_at, fake_match.calls[:] = None, []
    code, stdout, _ = run_cli(["match", left, right, "--ndisp", 8, "-o", out, "--resume"])
    assert code == 0 and "1 kept from before" in stdout and len(fake_match.calls) == 2
    assert read_pfm(out / "c.pfm")[0, 0] == 40
    # a folder with no record cannot be resumed
    (out / ".sswjax-run.json").unlink()
    code, _, stderr = run_cli(["match", left, right, "--ndisp", 8, "-o", out, "--resume"])
    assert code == 2 and "holds no record of the settings it was made with" in stderr


def test_many_sizes_are_bucketed_unless_told(tmp_path, run_cli, fake_match, texture):
    left, right = tmp_path / "left", tmp_path / "right"
    left.mkdir(), right.mkdir()
    for i in range(9):  # nine sizes: over the eight of AUTO_BUCKETS
        iio.imwrite(left / f"{i}.png", texture(i, (24, 40 + i, 3)))
        iio.imwrite(right / f"{i}.png", texture(i, (24, 40 + i, 3)))
    code, _, stderr = run_cli(["match", left, right, "--ndisp", 8, "-o", tmp_path / "a"])
    assert code == 0 and "9 image sizes: padding them to shape buckets" in stderr
    assert all(buckets == sswjax.ShapeBuckets() for _, buckets in fake_match.calls)
    fake_match.calls.clear()
    assert run_cli(["match", left, right, "--ndisp", 8, "-o", tmp_path / "b",
                    "--no-bucket"])[0] == 0
    assert all(buckets is None for _, buckets in fake_match.calls)


def test_real_matching_equals_the_single_pair_command(folders, tmp_path, run_cli, tiny):
    left, right = folders
    out = tmp_path / "out"
    assert run_cli(["match", left, right, "--ndisp", 8, "-o", out, *tiny.args])[0] == 0
    single = tmp_path / "b.pfm"
    assert run_cli(["match", left / "b.png", right / "b.png", "--ndisp", 8, "-o", single,
                    *tiny.args])[0] == 0
    assert read_pfm(out / "b.pfm").tobytes() == read_pfm(single).tobytes()
    assert np.median(read_pfm(out / "a.pfm")[:, 8:]) == pytest.approx(SHIFT, abs=0.05)


@pytest.mark.parametrize("case", ["file-and-folder", "folder-and-file", "no-common-names",
                                  "sizes-differ", "stem-clash", "ndisp-too-large", "output-is-file",
                                  "png-with-folders", "memory", "output-is-left",
                                  "output-is-right-by-link"])
def test_bad_folders_one_line_exit_2_nothing_written(folders, tmp_path, run_cli, texture, case):
    left, right = folders
    out = tmp_path / "out"
    argv = ["match", left, right, "--ndisp", 8, "-o", out]
    expected = {
        "file-and-folder": f"LEFT and RIGHT must be two image files or two folders: {right} is a "
                           f"folder, {left / 'a.png'} is not",
        "folder-and-file": f"LEFT and RIGHT must be two image files or two folders: {left} is a "
                           f"folder, {right / 'a.png'} is not",
        "no-common-names": "no image file names in common between",
        "sizes-differ": "pair c.png: left 40x24 and right 41x24 differ in size",
        "stem-clash": f"images c.jpg, c.png in {left} would write the same c.pfm: rename one",
        "ndisp-too-large": "ndisp must be in [1, 39] for the narrowest pair b.png, got 40",
        "output-is-file": f"output {out} is a file: with folders -o names a folder",
        "png-with-folders": "--png names one file: with folders only -o OUT_DIR is written",
        "memory": "needs about",
        "output-is-left": f"-o {left} is the same folder as LEFT_DIR {left}: the maps go to a "
                          "folder of their own",
        "output-is-right-by-link": f"-o {out} is the same folder as RIGHT_DIR {right}",
    }[case]
    before = {p: p.read_bytes() for folder in folders for p in folder.iterdir()}
    if case == "file-and-folder":
        argv[1] = left / "a.png"
    elif case == "folder-and-file":
        argv[2] = right / "a.png"
    elif case == "no-common-names":
        for path in right.iterdir():
            path.rename(right / f"x-{path.name}")
    elif case == "sizes-differ":  # a bad pair refuses the run with --strict only
        iio.imwrite(right / "c.png", texture(5, (24, 41, 3)))  # (tests/test_folder_runs.py)
        argv.append("--strict")
    elif case == "stem-clash":
        for folder in (left, right):
            iio.imwrite(folder / "c.jpg", texture(5, (24, 40, 3)))
    elif case == "ndisp-too-large":
        argv[4] = 40
    elif case == "output-is-file":
        out.write_text("a file")
    elif case == "png-with-folders":
        argv += ["--png", tmp_path / "x.png"]
    elif case == "memory":
        argv += ["--max-memory", "0.1"]
    elif case == "output-is-left":
        argv[-1] = out = left
    elif case == "output-is-right-by-link":
        out.symlink_to(right)
    code, stdout, stderr = run_cli(argv)
    assert code == 2 and stdout == ""
    assert stderr.count("\n") == 1 and stderr.startswith("sswjax: error: ") and expected in stderr
    if case.startswith("output-is-"):
        assert {p: p.read_bytes() for folder in folders for p in folder.iterdir()} == before
    else:
        assert not out.is_dir() or not any(out.iterdir())


def test_image_size_reads_headers(folders, tmp_path, texture):
    left, _ = folders
    assert image_size(left / "a.png") == (30, 48, 3)
    iio.imwrite(tmp_path / "g.png", texture(1, (5, 7)))
    assert image_size(tmp_path / "g.png") == (5, 7, 1)
    assert [p.name for p in folder_pairs(*folders)] == ["a.png", "b.png", "c.png"]


def test_resume_is_for_folders(folders, tmp_path, run_cli):
    left, right = folders
    out = tmp_path / "one.pfm"
    code, _, stderr = run_cli(["match", left / "a.png", right / "a.png", "--ndisp", 8, "-o", out,
                               "--resume"])
    assert code == 2 and not out.exists()
    assert stderr == ("sswjax: error: --resume is for folders "
                      "(sswjax match LEFT_DIR RIGHT_DIR -o OUT_DIR)\n")
