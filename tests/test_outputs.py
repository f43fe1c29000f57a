"""Nothing the user has is ever overwritten: the outputs of ``sswjax match`` (and ``demo -o``,
``params -o``) never replace an input or each other, are checked before the run, are written
in the format their extension names, and are written all or nothing.

The pair is conftest's ``small_pair`` (24x40, disparity 3), copied into each test's folder; the
parameters are conftest's ``tiny``, so the graphs compile once for the whole file (one for
``match``, one for ``match_with_confidence``), and are those of the other plumbing tests.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import tempfile
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import sswjax
from sswjax._files import InputError, atomic_outputs, same_file
from sswjax.api.geometry import depth_from_disparity
from sswjax.cli import common as cli_common
from sswjax.cli import demo as cli_demo
from sswjax.cli import match as cli_match
from sswjax.data.io import read_pfm
from sswjax.data.scaled import read_scaled_disparity

NDISP = 8  # conftest's small_pair.ndisp
SHAPE = (24, 40)
OPTIONS = ("-o", "--png", "--depth", "--confidence", "--validity", "--ply", "--kitti-png")
RIG = ["--focal", 100, "--baseline", 0.5]


class Pair:
    """The inputs of a test, in its own folder: ``left``, ``right``, ``params`` (a file of
    ``params``), ``calib`` (a Middlebury calib.txt); ``snapshot()`` is their bytes."""

    def __init__(self, small_pair, folder: Path, params):
        folder.mkdir(parents=True, exist_ok=True)
        self.left, self.right = folder / "left.png", folder / "right.png"
        shutil.copy(small_pair.folder / "left.png", self.left)
        shutil.copy(small_pair.folder / "right.png", self.right)
        self.params, self.calib = folder / "params.json", folder / "calib.txt"
        sswjax.save_params(self.params, params)
        self.calib.write_text("cam0=[100 0 19.5; 0 100 11.5; 0 0 1]\nbaseline=0.5\n")
        self.inputs = {"LEFT": self.left, "RIGHT": self.right, "--params": self.params,
                       "--calib": self.calib}

    def argv(self, *extra, calib=True):
        return ["match", self.left, self.right, "--ndisp", NDISP, "--params", self.params,
                *(["--calib", self.calib] if calib else []), *extra]

    def snapshot(self) -> dict:
        return {path: path.read_bytes() for path in self.inputs.values()}


@pytest.fixture()
def pair(small_pair, tiny, tmp_path) -> Pair:
    return Pair(small_pair, tmp_path / "in", tiny.params)


def _one_line_error(code, err, *parts):
    assert code == 2, err
    assert err.startswith("sswjax: error: ") and err.count("\n") == 1, err
    for part in parts:
        assert str(part) in err, err


def _temporaries(folder: Path) -> list[Path]:
    return [p for p in folder.rglob(".*") if p.name.endswith((".tmp", ".old"))]


@pytest.fixture()
def no_matching(monkeypatch):
    """Reading the images (the first step of the run) fails the test: what is refused must be
    refused before it."""
    def read_oriented(path):
        raise AssertionError(f"the run started: read {path}")

    monkeypatch.setattr(cli_match, "read_oriented", read_oriented)


def _unwritable_folder(tmp_path: Path) -> Path:
    """A folder in which nothing can be created: read-only, or, when this user writes there
    anyway (root), a file standing where the folder should be."""
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o500)
    if os.access(folder, os.W_OK):
        folder.chmod(0o700)
        folder.rmdir()
        folder.write_text("a file, not a folder")
    return folder


def _unlock(tmp_path: Path) -> None:
    locked = tmp_path / "locked"
    if locked.is_dir():
        locked.chmod(0o700)


# ------------------------------------------------------------------------ 1. an input as an output


@pytest.mark.parametrize("option", OPTIONS)
@pytest.mark.parametrize("name", ["LEFT", "RIGHT", "--params", "--calib"])
def test_an_input_named_as_an_output_is_refused(pair, tmp_path, run_cli, no_matching, option,
                                                name):
    before = pair.snapshot()
    target = pair.inputs[name]
    extra = ["-o", tmp_path / "d.pfm"] if option != "-o" else []
    code, out, err = run_cli(pair.argv(option, target, *extra))
    _one_line_error(code, err, f"{option} {target} is the same file as the input {name} {target}")
    assert out == "" and pair.snapshot() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


@pytest.mark.parametrize("spelling", ["dots", "symlink", "hard-link"])
def test_an_input_by_another_name_is_refused(pair, tmp_path, run_cli, no_matching, spelling):
    before = pair.snapshot()
    other = tmp_path / "other.png"
    if spelling == "dots":
        other = tmp_path / "in" / ".." / "in" / "left.png"
    elif spelling == "symlink":
        other.symlink_to(pair.left)
    else:
        os.link(pair.left, other)
    code, _, err = run_cli(pair.argv("-o", tmp_path / "d.pfm", "--kitti-png", other))
    _one_line_error(code, err, f"--kitti-png {other} is the same file as the input LEFT")
    assert pair.snapshot() == before and not (tmp_path / "d.pfm").exists()


# ---------------------------------------------------------------------- 2. two outputs on one path


@pytest.mark.parametrize("first, second", [
    ("-o", "--png"), ("-o", "--depth"), ("-o", "--confidence"), ("--png", "--validity"),
    ("--kitti-png", "--validity"), ("-o", "--ply"), ("--depth", "--confidence")])
@pytest.mark.parametrize("spelling", ["same", "dots", "symlink", "hard-link"])
def test_two_outputs_on_one_path_are_refused(pair, tmp_path, run_cli, no_matching, first, second,
                                             spelling):
    path = tmp_path / "same.pfm"
    path.write_bytes(b"the user's file")
    other = {"same": path, "dots": tmp_path / "in" / ".." / "same.pfm",
             "symlink": tmp_path / "link.pfm", "hard-link": tmp_path / "hard.pfm"}[spelling]
    if spelling == "symlink":
        other.symlink_to(path)
    elif spelling == "hard-link":
        os.link(path, other)
    argv = pair.argv(first, path, second, other)
    if "-o" not in (first, second):
        argv += ["-o", tmp_path / "d.pfm"]
    code, _, err = run_cli(argv)
    _one_line_error(code, err, f"{first} {path} and {second} {other} are the same file")
    assert path.read_bytes() == b"the user's file" and not (tmp_path / "d.pfm").exists()
    assert _temporaries(tmp_path) == []


# ----------------------------------------------------------------------------- 3. a failing output


def test_an_unwritable_output_stops_the_run_before_it_starts(pair, tmp_path, run_cli, no_matching):
    ok = tmp_path / "ok.pfm"
    ok.write_bytes(b"old map")
    locked = _unwritable_folder(tmp_path)
    try:
        code, _, err = run_cli(pair.argv("-o", ok, "--png", locked / "x.png"))
        reason = "is not writable" if locked.is_dir() else "is a file, not a folder"
        _one_line_error(code, err, f"output folder {locked} {reason}")
    finally:
        _unlock(tmp_path)
    assert ok.read_bytes() == b"old map" and _temporaries(tmp_path) == []


def test_a_read_only_output_file_is_not_replaced(pair, tmp_path, run_cli, no_matching):
    kept = tmp_path / "kept.png"
    kept.write_bytes(b"protected")
    kept.chmod(0o444)
    if os.access(kept, os.W_OK):
        pytest.skip("this user writes read-only files (root)")
    code, _, err = run_cli(pair.argv("-o", tmp_path / "d.pfm", "--png", kept))
    _one_line_error(code, err, f"output {kept} is a read-only file: not replaced")
    assert kept.read_bytes() == b"protected" and not (tmp_path / "d.pfm").exists()


@pytest.mark.parametrize("failure", ["disk-full", "ctrl-c"])
def test_a_failing_writer_leaves_every_output_as_it_was(pair, tmp_path, run_cli, monkeypatch,
                                                        failure):
    """The match runs, then the colour PNG's writer fails half-way: no output appears, a file
    that was there keeps its content, no temporary file is left."""
    old, new = tmp_path / "old.pfm", tmp_path / "new.npy"
    old.write_bytes(b"yesterday's map")

    def failing(path, *args, **kwargs):
        Path(path).write_bytes(b"half a PNG")
        if failure == "disk-full":
            raise OSError(errno.ENOSPC, "No space left on device")
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_common, "write_disparity_png", failing)
    code, _, err = run_cli(pair.argv("-o", old, "--depth", new, "--png", tmp_path / "c.png",
                                     "--validity", tmp_path / "v.png"))
    if failure == "disk-full":
        _one_line_error(code, err, f"cannot write {tmp_path / 'c.png'}: No space left on device")
    else:
        assert code == 130 and err == "sswjax: interrupted\n"
    assert old.read_bytes() == b"yesterday's map"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "old.pfm"]


# ------------------------------------------------------------------------- 4. formats by extension


@pytest.mark.parametrize("option, name, written", [
    ("-o", "d.png.jpg", "unsupported extension '.jpg'; -o writes .pfm, .npy, .tif or .tiff "
                        "(float32), or .png (16-bit, round(disparity * 256), 0 = invalid)"),
    ("-o", "disparity", "no extension; -o writes .pfm"),
    ("--depth", "z.png", "unsupported extension '.png'; --depth writes .pfm, .npy, .tif or .tiff"),
    ("--confidence", "c.exr", "unsupported extension '.exr'; --confidence writes .pfm, .npy"),
    ("--png", "c.pfm", "unsupported extension '.pfm'; --png writes .png (colour-mapped, 8-bit)"),
    ("--validity", "v.tif", "unsupported extension '.tif'; --validity writes .png (8-bit)"),
    ("--kitti-png", "k.pfm", "unsupported extension '.pfm'; --kitti-png writes .png"),
    ("--ply", "c.obj", "unsupported extension '.obj'; --ply writes .ply"),
])
def test_an_extension_we_do_not_write_is_refused(pair, tmp_path, run_cli, no_matching, option,
                                                 name, written):
    extra = ["-o", tmp_path / "d.pfm"] if option != "-o" else []
    code, _, err = run_cli(pair.argv(option, tmp_path / name, *extra))
    _one_line_error(code, err, f"{option} {tmp_path / name}: {written}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def _read_map(path: Path) -> np.ndarray:
    suffix = path.suffix.lower()
    if suffix == ".pfm":
        return read_pfm(path)
    if suffix == ".npy":
        return np.load(path)
    return np.asarray(iio.imread(path))


def test_every_format_reads_back_equal_to_the_map(pair, tmp_path, run_cli):
    code, _, err = run_cli(pair.argv("-o", tmp_path / "ref.pfm", "--depth", tmp_path / "z.pfm",
                                     "--confidence", tmp_path / "c.pfm", calib=False) + RIG)
    assert code == 0, err
    disparity, confidence = read_pfm(tmp_path / "ref.pfm"), read_pfm(tmp_path / "c.pfm")
    depth = depth_from_disparity(disparity, focal=100, baseline=0.5)
    assert disparity.shape == SHAPE and np.isfinite(disparity).all()
    for suffix in (".npy", ".tif", ".tiff", ".PFM"):
        out = tmp_path / "formats" / suffix[1:]
        out.mkdir(parents=True)
        code, _, err = run_cli(pair.argv("-o", out / f"d{suffix}", "--depth", out / f"z{suffix}",
                                         "--confidence", out / f"c{suffix}", calib=False) + RIG)
        assert code == 0, err
        for name, expected in (("d", disparity), ("z", depth), ("c", confidence)):
            back = _read_map(out / f"{name}{suffix}")
            assert back.dtype == np.float32, (name, suffix)
            np.testing.assert_array_equal(back, expected, err_msg=f"{name}{suffix}")
        if suffix in (".tif", ".tiff"):
            assert (out / f"d{suffix}").read_bytes()[:4] in (b"II*\x00", b"MM\x00*")
    # -o .png is KITTI's 16-bit PNG, as --kitti-png writes it
    code, _, err = run_cli(pair.argv("-o", tmp_path / "d.png", "--kitti-png", tmp_path / "k.png"))
    assert code == 0, err
    raw = iio.imread(tmp_path / "d.png")
    assert raw.dtype == np.uint16 and raw.shape == SHAPE
    np.testing.assert_array_equal(raw, np.round(disparity * 256).astype(np.uint16))
    assert (tmp_path / "d.png").read_bytes() == (tmp_path / "k.png").read_bytes()
    np.testing.assert_allclose(read_scaled_disparity(tmp_path / "d.png", scale=256), disparity,
                               atol=1 / 512)
    assert _temporaries(tmp_path) == []


def test_match_help_gives_the_scale_of_a_png_disparity(run_cli):
    code, out, _ = run_cli(["match", "--help"])
    assert code == 0 and "round(d * 256), 0 = invalid" in " ".join(out.split())


# ------------------------------------------------------------------------------ demo -o, params -o


def test_params_output_is_not_its_input(pair, tmp_path, run_cli):
    before = pair.params.read_bytes()
    code, _, err = run_cli(["params", "--params", pair.params, "-o", pair.params])
    _one_line_error(code, err, f"-o {pair.params} is the same file as the input --params "
                               f"{pair.params}")
    assert pair.params.read_bytes() == before
    link = tmp_path / "link.json"
    link.symlink_to(pair.params)
    code, _, err = run_cli(["params", "--params", link, "-o", pair.params])
    _one_line_error(code, err, "is the same file as the input --params")


def test_params_dash_output_prints_and_other_outputs_refuse_a_dash(pair, tmp_path, run_cli,
                                                                   monkeypatch, no_matching):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    code, out, err = run_cli(["params", "--preset", "fast", "-o", "-"])
    assert code == 0, err
    assert json.loads(out)["format"] == "sswjax-params/2"
    # The other outputs are files: '-' is refused, not written as a file named '-'.
    code, _, err = run_cli(["match", pair.left, pair.right, "--ndisp", 16, "-o", "d.pfm",
                            "--png", "-"])
    _one_line_error(code, err, "output -: this option writes a file, not standard output")
    assert list(work.iterdir()) == []


def test_demo_refuses_before_running_and_writes_both_maps_or_none(tmp_path, run_cli, monkeypatch,
                                                                  tiny):
    out = tmp_path / "demo"
    out.mkdir()
    params = out / "disp0SSW.pfm"
    sswjax.save_params(params, tiny.params)
    before = params.read_bytes()
    code, _, err = run_cli(["demo", "-o", out, "--params", params])
    _one_line_error(code, err, f"the demo's map {params} is the same file as the input --params")
    assert params.read_bytes() == before
    (tmp_path / "file").write_text("x")
    code, _, err = run_cli(["demo", "-o", tmp_path / "file"])
    _one_line_error(code, err, "is a file: -o names the folder of the demo's maps")

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_demo, "match", interrupted)
    code, _, err = run_cli(["demo", "-o", tmp_path / "new"])
    assert code == 130 and not (tmp_path / "new").exists()  # the folder it made is gone
    monkeypatch.setattr(cli_demo, "match", lambda left, *a, **k: np.full(left.shape[:2], 5.0,
                                                                            np.float32))
    code, _, err = run_cli(["demo", "-o", tmp_path / "new"])
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "new").iterdir()) == ["disp0SSW.pfm",
                                                                    "disp0SSW.png"]
    assert (read_pfm(tmp_path / "new" / "disp0SSW.pfm") == 5).all()


# ---------------------------------------------------------------------------------- atomic_outputs


def test_atomic_outputs_all_or_nothing(tmp_path, monkeypatch):
    old, new = tmp_path / "old.txt", tmp_path / "new.txt"
    old.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_outputs([old, new]) as files:
            assert set(files) == {old, new} and all(t.parent == tmp_path for t in files.values())
            files.write(old, lambda tmp: tmp.write_text("fresh"))
            raise RuntimeError("the run failed")
    assert old.read_text() == "old" and sorted(tmp_path.iterdir()) == [old]
    # a move that fails undoes the moves before it
    real_replace, moves = os.replace, []

    def replace(source, destination):
        moves.append(destination)
        if len(moves) == 2:
            raise OSError(errno.EIO, "Input/output error")
        real_replace(source, destination)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(InputError, match=f"cannot write {new}: Input/output error"):
        with atomic_outputs([old, new]) as files:
            files.write(old, lambda tmp: tmp.write_text("fresh"))
            files.write(new, lambda tmp: tmp.write_text("fresh"))
    monkeypatch.setattr(os, "replace", real_replace)
    assert old.read_text() == "old" and sorted(tmp_path.iterdir()) == [old]
    with atomic_outputs([old, new]) as files:
        for path in files:
            files.write(path, lambda tmp: tmp.write_text("fresh"))
    assert old.read_text() == new.read_text() == "fresh"
    assert sorted(tmp_path.iterdir()) == [new, old]


def test_atomic_outputs_refuses_before_the_body(tmp_path):
    body = []
    with pytest.raises(InputError, match="are the same file"):
        with atomic_outputs([tmp_path / "a", tmp_path / "x" / ".." / "a"]):
            body.append(1)
    with pytest.raises(InputError, match=f"cannot write {tmp_path / 'no' / 'b'}"):
        with atomic_outputs([tmp_path / "a", tmp_path / "no" / "b"]):
            body.append(1)
    assert body == [] and list(tmp_path.iterdir()) == []

    def disk_full(tmp):
        tmp.write_text("half")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(InputError, match="cannot write .*a: No space left"):
        with atomic_outputs([tmp_path / "a"]) as files:
            files.write(tmp_path / "a", disk_full)
    assert list(tmp_path.iterdir()) == []


def test_same_file(tmp_path):
    (tmp_path / "a").write_text("a")
    os.link(tmp_path / "a", tmp_path / "hard")
    (tmp_path / "soft").symlink_to(tmp_path / "a")
    assert same_file(tmp_path / "a", tmp_path / "hard")
    assert same_file(tmp_path / "soft", tmp_path / "a")
    assert same_file(tmp_path / "x" / ".." / "a", tmp_path / "a")
    assert same_file(tmp_path / "missing", tmp_path / "." / "missing")
    assert not same_file(tmp_path / "a", tmp_path / "missing")


# ------------------------------------------------------------------------------------ the property


SUFFIXES = {"-o": (".pfm", ".npy", ".png", ".tif"), "--png": (".png",),
            "--depth": (".pfm", ".npy", ".tiff"), "--confidence": (".pfm", ".npy", ".tif"),
            "--validity": (".png",), "--ply": (".ply",), "--kitti-png": (".png",)}
KINDS = ("fresh", "existing", "input", "other-output", "missing-folder", "read-only-folder",
         "folder")
_DRAWN = KINDS[:2] * 4 + KINDS  # the two that work drawn more often: runs that write happen


def _valid(option: str, path: Path) -> bool:
    """Whether ``path`` is a readable output of ``option`` for the 24x40 pair."""
    if option == "--ply":
        data = path.read_bytes()
        return (data.startswith(b"ply\nformat binary_little_endian 1.0\n")
                and b"end_header\n" in data)
    if option in ("-o", "--kitti-png") and path.suffix == ".png":
        return read_scaled_disparity(path, scale=256).shape == SHAPE
    image = _read_map(path)
    shape = SHAPE + (3,) if option == "--png" else SHAPE
    dtype = np.uint8 if option in ("--png", "--validity") else np.float32
    return image.shape == shape and image.dtype == dtype


@st.composite
def invocations(draw):
    """``[(option, kind, suffix, choice)]``: -o and a random subset of the other outputs, each
    with where its path comes from, its extension, and which input / output / spelling."""
    options = ["-o"] + draw(st.lists(st.sampled_from(OPTIONS[1:]), unique=True, max_size=4))
    return [(option, draw(st.sampled_from(_DRAWN)), draw(st.sampled_from(SUFFIXES[option])),
             draw(st.integers(0, 5))) for option in options]


@settings(max_examples=25, deadline=None, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(plan=invocations())
def test_outputs_are_all_written_or_none_and_inputs_never_change(small_pair, tiny, tmp_path,
                                                                 run_cli, plan):
    root = Path(tempfile.mkdtemp(dir=tmp_path))
    pair = Pair(small_pair, root / "in", tiny.params)
    inputs = [pair.left, pair.right, pair.params]
    before = pair.snapshot()
    (root / "out").mkdir()
    locked = _unwritable_folder(root)
    try:
        argv, paths, ok, existing = pair.argv(calib=False) + RIG, {}, True, {}
        for option, kind, suffix, choice in plan:
            name = "disparity" if option == "-o" else option.strip("-")
            path = root / "out" / f"{name}{suffix}"
            if kind == "other-output" and not paths:
                kind = "fresh"  # no output before this one to collide with
            if kind == "existing":
                path.write_bytes(f"the user's {name}".encode())
                existing[path] = path.read_bytes()
            elif kind == "input":
                path = inputs[choice % len(inputs)]
            elif kind == "other-output":
                earlier = list(paths.values())[choice % len(paths)]
                path = (earlier if choice < 3  # else the same path spelled another way
                        else earlier.parent / ".." / earlier.parent.name / earlier.name)
            elif kind == "missing-folder":
                path = root / "missing" / path.name
            elif kind == "read-only-folder":
                path = locked / path.name
            elif kind == "folder":
                path.mkdir()
            ok &= kind in ("fresh", "existing")
            paths[option] = path
            argv += [option, path]
        code, out, err = run_cli(argv)
        event(f"exit {code}")
        assert pair.snapshot() == before  # no input ever changes
        assert _temporaries(root) == []
        if ok:
            assert code == 0, err
            for option, path in paths.items():
                assert _valid(option, path), (option, path)
        else:
            assert code == 2 and out == "", err
            assert err.startswith("sswjax: error: ") and err.count("\n") == 1, err
            for option, path in paths.items():
                kept = [old for old in existing if same_file(old, path)]
                if kept:
                    assert path.read_bytes() == existing[kept[0]], (option, path)
                elif not any(same_file(path, source) for source in inputs):
                    assert not path.is_file(), (option, path)
    finally:
        _unlock(root)
        shutil.rmtree(root)
