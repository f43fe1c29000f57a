"""Robustness at the boundary: bad input, inputs that must work, nothing lost, determinism.

Every row of the README table "Bad input: what the user sees" names the test that covers it.
Kept small: 24x40 images and ndisp 8, so that the in-process tests share two or three JAX
compilations; the subprocess tests (SIGINT and resume, determinism across processes) use a
cheaper parameter set or run concurrently.
"""

from __future__ import annotations

import functools
import io
import json
import os
import shlex
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import imageio.v3 as iio
import jax
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sswjax
from sswjax import Params
from sswjax.cli import main
from sswjax.data.io import InputError, read_image, read_pfm, write_pfm
from sswjax.params import check_params

H, W, SHIFT, NDISP = 24, 40, 3, 8
CLI = [sys.executable, "-m", "sswjax.cli"]
FUNCTION_SCOPED = [HealthCheck.function_scoped_fixture]


def _texture(seed: int, shape=(H, W, 3)) -> np.ndarray:
    return (np.random.default_rng(seed).random(shape) * 255).astype(np.uint8)


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    """A 24x40 pair with disparity 3 in every input form, plus broken files."""
    folder = tmp_path_factory.mktemp("inputs")
    right = _texture(0)
    left = np.roll(right, SHIFT, axis=1)
    iio.imwrite(folder / "left.png", left)
    iio.imwrite(folder / "right.png", right)
    gray = [np.round(im.astype(np.float64) @ [0.299, 0.587, 0.114]).astype(np.uint8) for im in (left, right)]
    iio.imwrite(folder / "left_gray.png", gray[0])
    iio.imwrite(folder / "right_gray.png", gray[1])
    iio.imwrite(folder / "left_gray16.png", gray[0].astype(np.uint16) * 257)
    iio.imwrite(folder / "right_gray16.png", gray[1].astype(np.uint16) * 257)
    alpha = _texture(1, (H, W, 1))
    iio.imwrite(folder / "left_rgba.png", np.concatenate([left, alpha], axis=-1))
    iio.imwrite(folder / "right_rgba.png", np.concatenate([right, alpha[::-1]], axis=-1))
    iio.imwrite(folder / "small.png", right[:5])
    iio.imwrite(folder / "narrow.png", right[:20, :30])
    iio.imwrite(folder / "animated.gif", np.stack([left, right]))
    png = (folder / "left.png").read_bytes()
    (folder / "truncated.png").write_bytes(png[: len(png) // 2])
    corrupt = bytearray(png)
    idat = png.index(b"IDAT") + 40
    corrupt[idat : idat + 8] = bytes(8)  # zeroes inside the compressed pixels
    (folder / "corrupt.png").write_bytes(bytes(corrupt))
    (folder / "random.png").write_bytes(np.random.default_rng(2).bytes(300))
    (folder / "empty.png").write_bytes(b"")
    (folder / "folder.png").mkdir()
    return folder


def _run(argv, capsys):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exit_:  # argparse's usage errors (the console script exits the same way)
        code = exit_.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _assert_one_line_error(code, err, message):
    assert code == 2, err
    assert err.startswith("sswjax: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert message in err, err


# ============================================================================ 1. bad input: match


@pytest.mark.parametrize(
    "left, right, extra, message",
    [
        ("missing.png", "right.png", [], "image not found: {d}/missing.png"),
        ("left.png", "folder.png", [], "cannot read image {d}/folder.png: Is a directory"),
        ("left.png", "empty.png", [], "cannot read image {d}/empty.png: the file is empty"),
        ("random.png", "right.png", [], "cannot read image {d}/random.png: not an image file"),
        ("left.png", "truncated.png", [], "cannot read image {d}/truncated.png: the file is truncated"),
        ("corrupt.png", "right.png", [], "cannot read image {d}/corrupt.png: the file is corrupt ("),
        ("animated.gif", "right.png", [],
         "must be a single gray or RGB(A) image, got array shape (2, 24, 40, 3)"),
        ("left.png", "narrow.png", [], "left and right images differ in size: 40x24 and 30x20"),
        ("small.png", "small.png", ["--ndisp", "4"],
         "images of 40x5 are smaller than the census window 9x7: both sides must be at least 9 pixels"),
        ("left.png", "right.png", ["--ndisp", "0"], "ndisp must be in [1, 39] for this width, got 0"),
        ("left.png", "right.png", ["--ndisp", "-3"], "ndisp must be in [1, 39] for this width, got -3"),
        ("left.png", "right.png", ["--ndisp", "40"], "ndisp must be in [1, 39] for this width, got 40"),
        ("left.png", "right.png", ["--ndisp", "2.5"], "argument --ndisp: invalid int value: '2.5'"),
        ("left.png", "right.png", ["--ndisp", "eight"], "argument --ndisp: invalid int value: 'eight'"),
    ],
    ids=["missing", "directory", "empty", "not-an-image", "truncated-png", "corrupt-png", "multi-frame",
         "size-mismatch", "below-census-window", "ndisp-0", "ndisp-negative", "ndisp-width",
         "ndisp-float", "ndisp-text"],
)
def test_match_bad_input(files, tmp_path, capsys, left, right, extra, message):
    out = tmp_path / "d.pfm"
    write_pfm(out, np.full((2, 3), 7, np.float32))  # the user's earlier result
    argv = ["match", files / left, files / right, *(extra or ["--ndisp", NDISP]), "-o", out]
    code, _, err = _run(argv, capsys)
    _assert_one_line_error(code, err, message.format(d=files))
    assert (read_pfm(out) == 7).all()  # survives the failed run
    assert [p.name for p in tmp_path.iterdir()] == ["d.pfm"]  # and no temporary debris


def _drop_privileges_and_run(argv, err_path: Path) -> int:
    """Run ``main(argv)`` in a forked child as user nobody (root reads every file)."""
    with open(err_path, "w") as err_file:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # JAX warns about fork() in a threaded process
            pid = os.fork()
        if pid == 0:  # child: never return into pytest
            code = 99
            try:
                os.setgid(65534)
                os.setuid(65534)
                os.dup2(err_file.fileno(), 2)
                sys.stderr = os.fdopen(2, "w")
                code = main(argv)
                sys.stderr.flush()
            finally:
                os._exit(code)
    return os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])


def test_match_unreadable_image(files, capsys):
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="sswjax-unreadable-"))  # traversable by nobody
    try:
        folder.chmod(0o755)
        locked = folder / "locked.png"
        locked.write_bytes((files / "left.png").read_bytes())
        locked.chmod(0)
        argv = ["match", str(locked), str(files / "right.png"), "--ndisp", "8", "-o", str(folder / "d.pfm")]
        if os.geteuid() == 0:
            code = _drop_privileges_and_run(argv, folder / "stderr.txt")
            err = (folder / "stderr.txt").read_text()
        else:
            code, _, err = _run(argv, capsys)
        _assert_one_line_error(code, err, f"cannot read image {locked}: Permission denied")
        assert not (folder / "d.pfm").exists()
    finally:
        for path in folder.iterdir():
            path.unlink()
        folder.rmdir()


@pytest.mark.parametrize(
    "content, message",
    [
        ('{"dynamic": {"tad_truncation": NaN}}',
         "parameter tad_truncation must be a finite number > 0, got nan"),
        ('{"tad_truncation": Infinity}', "parameter tad_truncation must be a finite number > 0, got inf"),
        ('{"dynamic": {"tad_truncation": -0.1}}',
         "parameter tad_truncation must be a finite number > 0, got -0.1"),
        ('{"census_weight": -1}', "parameter census_weight must be a finite number >= 0, got -1.0"),
        ('{"static": {"census_width": 17}}', "parameter census_width must be in [1, 15], got 17"),
        ('{"static": {"census_height": 8}}', "parameter census_height must be odd, got 8"),
        ('{"static": {"refine_radius": -1}}', "parameter refine_radius must be in [0, 20], got -1"),
        ('{"static": {"radius": 3}}', "unknown static parameter 'radius'"),
        ('{"bogus": 1}', "unknown parameter 'bogus'"),
        ('{"static": {"census_width": "9"}}', "parameter census_width must be an integer, got '9'"),
        ('{"lr_check": "yes"}', "parameter lr_check must be true or false, got 'yes'"),
        ('{"census_weight": null}', "parameter census_weight must be a number, got None"),
        ("[1, 2]", "parameters must be a JSON object, got list"),
        ("{not json", "cannot read parameter file {p}: Expecting property name"),
        (b"\xff\xfe{}", "cannot read parameter file {p}: 'utf-8' codec can't decode"),
    ],
    ids=["nan", "infinity", "negative-truncation", "negative-weight", "int-too-large", "even-census",
         "negative-radius", "unknown-static-key", "unknown-key", "string-for-int", "string-for-bool",
         "null-for-number", "not-an-object", "bad-json", "not-utf8"],
)
def test_match_bad_params_json(files, tmp_path, capsys, content, message):
    params = tmp_path / "params.json"
    params.write_bytes(content if isinstance(content, bytes) else content.encode())
    argv = ["match", files / "left.png", files / "right.png", "--ndisp", NDISP,
            "-o", tmp_path / "d.pfm", "--params", params]
    code, _, err = _run(argv, capsys)
    _assert_one_line_error(code, err, message.format(p=params))
    if not message.startswith("cannot read"):
        assert err.startswith(f"sswjax: error: {params}: ")  # names the file
    assert not (tmp_path / "d.pfm").exists()


def test_match_output_is_a_folder(files, tmp_path, capsys):
    code, _, err = _run(["match", files / "left.png", files / "right.png", "--ndisp", NDISP,
                         "-o", tmp_path], capsys)
    _assert_one_line_error(code, err, f"output {tmp_path} is a folder, expected a file name")


def test_debug_shows_the_traceback(files, tmp_path):
    argv = ["match", str(files / "missing.png"), str(files / "right.png"), "--ndisp", "8",
            "-o", str(tmp_path / "d.pfm")]
    plain = subprocess.run(CLI + argv, capture_output=True, text=True, timeout=120)
    assert plain.returncode == 2 and plain.stderr.count("\n") == 1 and "Traceback" not in plain.stderr
    debug = subprocess.run(CLI + ["--debug"] + argv, capture_output=True, text=True, timeout=120)
    assert debug.returncode == 1
    assert debug.stderr.startswith("Traceback (most recent call last):")
    assert "sswjax.data.io.InputError: image not found" in debug.stderr


# ============================================================================ 1. bad input: API


def test_api_rejects_bad_params_and_empty_images():
    left = _texture(0)
    for params, message in [
        (Params().replace(tad_truncation=float("nan")),
         "parameter tad_truncation must be a finite number > 0, got nan"),
        (Params().replace(census_weight=-0.5),
         "parameter census_weight must be a finite number >= 0, got -0.5"),
        (Params().replace(census_width=8), "parameter census_width must be odd, got 8"),
        (Params().replace(aggregation_radius=2.5),
         "parameter aggregation_radius must be an integer, got 2.5"),
        (Params().replace(tad_weight=np.ones(2)), "parameter tad_weight must be a scalar, got shape (2,)"),
    ]:
        with pytest.raises(ValueError) as info:
            sswjax.match(left, left, NDISP, params)
        assert str(info.value) == message
    message = r"^params must be a sswjax.Params \(see sswjax.load_params\), got dict$"
    with pytest.raises(TypeError, match=message):
        sswjax.match(left, left, NDISP, {"tad_truncation": 0.1})
    with pytest.raises(ValueError, match=r"^left image is empty, got shape \(24, 0, 1\)$"):
        sswjax.match(np.zeros((H, 0), np.uint8), left, NDISP)
    with pytest.raises(ValueError, match=r"^ndisp must be an integer, got 8.0$"):
        sswjax.match(left, left, 8.0)
    # valid NumPy and JAX scalars pass the check (match would recompile for them: not run here)
    params = Params().replace(tad_weight=np.float32(0.05), census_weight=jax.numpy.float32(0.8))
    assert check_params(params) is params


# ============================================================================ 1. bad input: evaluate


def _make_scene(folder: Path, width: int, seed: int, *, ndisp: int = NDISP) -> None:
    folder.mkdir(parents=True)
    right = _texture(seed, (H, width, 3))
    iio.imwrite(folder / "im0.png", np.roll(right, SHIFT, axis=1))
    iio.imwrite(folder / "im1.png", right)
    (folder / "calib.txt").write_text(f"cam0=[1 0 0; 0 1 0; 0 0 1]\nndisp={ndisp}\nvmin=0\nvmax=7\n")
    truth = np.full((H, width), SHIFT, np.float32)
    truth[:, :SHIFT] = np.inf
    write_pfm(folder / "disp0GT.pfm", truth)
    mask = np.full((H, width), 255, np.uint8)
    mask[:, :SHIFT] = 0
    iio.imwrite(folder / "mask0nocc.png", mask)


SCENES = (("Adirondack", 40), ("Teddy", 44), ("Vintage", 48))  # widths differ: one compile each


def _middeval3(root: Path) -> Path:
    for seed, (name, width) in enumerate(SCENES):
        _make_scene(root / "trainingQ" / name, width, seed)
    return root


def _break_truncated_gt(scene: Path) -> None:
    data = (scene / "disp0GT.pfm").read_bytes()
    (scene / "disp0GT.pfm").write_bytes(data[:100])


@pytest.mark.parametrize(
    "damage, extra, message",
    [
        (lambda s: (s / "im1.png").unlink(), [], "scene Teddy: missing im1.png in {s}"),
        (lambda s: (s / "im0.png").unlink(), [], "scene Teddy: missing im0.png in {s}"),
        (lambda s: (s / "calib.txt").unlink(), [], "scene Teddy: missing calib.txt in {s}"),
        (lambda s: (s / "disp0GT.pfm").unlink(), [],
         "cannot score scene(s) without disp0GT.pfm: Teddy in {s.parent}"),
        (lambda s: (s / "mask0nocc.png").unlink(), [],
         "cannot score scene(s) without mask0nocc.png: Teddy in {s.parent}"),
        (_break_truncated_gt, [], "PFM file {s}/disp0GT.pfm is truncated: 86 of 4224 data bytes"),
        (lambda s: (s / "disp0GT.pfm").write_bytes(b"P5\n44 24\n255\n" + bytes(44 * 24)),
         [], "PFM file {s}/disp0GT.pfm has bad magic b'P5', expected b'Pf' or b'PF'"),
        (lambda s: (s / "im1.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage"), [],
         "cannot read image {s}/im1.png: the file is truncated"),
        (lambda s: (s / "calib.txt").write_text("baseline=193.001\n"), [],
         "calibration file {s}/calib.txt needs ndisp=<positive integer>, got None"),
        (lambda s: None, ["--scenes", "Nope"], "unknown scene(s) Nope in"),
        (lambda s: None, ["--resume"], "--resume needs -o/--output: the folder of the run to continue"),
        (lambda s: None, ["--methods", " , "], "no method given in --methods ' , '"),
    ],
    ids=["no-im1", "no-im0", "no-calib", "no-ground-truth", "no-mask", "truncated-pfm", "bad-pfm-magic",
         "corrupt-png", "calib-without-ndisp", "unknown-scene", "resume-without-output", "no-method"],
)
def test_evaluate_bad_folder(tmp_path, capsys, damage, extra, message):
    root = _middeval3(tmp_path / "MiddEval3")
    scene = root / "trainingQ" / "Teddy"
    damage(scene)
    code, out, err = _run(["evaluate", "--data", root, "--methods", "ssw", *extra], capsys)
    _assert_one_line_error(code, err, message.format(s=scene))
    assert out == ""  # failed before any scene was run


# ============================================================================ 1. inputs that must work


def _match_cli(files, tmp_path, left, right, name="d.pfm"):
    out = tmp_path / name
    assert main(["match", str(files / left), str(files / right), "--ndisp", str(NDISP), "-o", str(out)]) == 0
    return read_pfm(out)


def test_cli_inputs_that_must_work(files, tmp_path, capsys):
    """Colour, gray, 16-bit, RGBA and colour/gray pairs, from files, agree with the API."""
    colour = _match_cli(files, tmp_path, "left.png", "right.png")
    assert np.median(colour[:, 12:]) == pytest.approx(SHIFT, abs=0.05)
    # RGBA: the alpha channel is dropped, the result is bit-identical
    np.testing.assert_array_equal(_match_cli(files, tmp_path, "left_rgba.png", "right_rgba.png"), colour)
    # gray pairs, 8 and 16 bits (v * 257 / 65535 == v / 255 exactly in float32)
    gray = _match_cli(files, tmp_path, "left_gray.png", "right_gray.png")
    assert np.median(gray[:, 12:]) == pytest.approx(SHIFT, abs=0.05)
    assert read_image(files / "left_gray16.png").dtype == np.uint16
    np.testing.assert_array_equal(_match_cli(files, tmp_path, "left_gray16.png", "right_gray16.png"), gray)
    # colour + gray (either side): both used as gray, the colour one by BT.601 luma, like the API
    mixed = _match_cli(files, tmp_path, "left.png", "right_gray.png")
    assert np.median(mixed[:, 12:]) == pytest.approx(SHIFT, abs=0.05)
    api = sswjax.match(read_image(files / "left.png"), read_image(files / "right_gray.png"), NDISP)
    np.testing.assert_array_equal(mixed, api)
    mixed_other_way = _match_cli(files, tmp_path, "left_gray16.png", "right.png")
    api = sswjax.match(read_image(files / "left_gray16.png"), read_image(files / "right.png"), NDISP)
    np.testing.assert_array_equal(mixed_other_way, api)
    assert "wrote" in capsys.readouterr().out


def test_cli_16bit_colour_png(files, tmp_path):
    """16-bit colour PNGs: all 16 bits read (with OpenCV), and matched like their 8-bit twins."""
    cv2 = pytest.importorskip("cv2")
    left8, right8 = read_image(files / "left.png"), read_image(files / "right.png")
    rng = np.random.default_rng(4)
    for name, image in (("left48.png", left8), ("right48.png", right8)):
        # v * 257 plus low-byte noise that only a 16-bit reader sees
        wide = image.astype(np.uint16) * 257 + rng.integers(0, 2, image.shape, dtype=np.uint16)
        assert cv2.imwrite(str(tmp_path / name), wide[..., ::-1])
        np.testing.assert_array_equal(read_image(tmp_path / name), wide)
    rgba = np.concatenate([left8.astype(np.uint16) * 257, np.full((H, W, 1), 65535, np.uint16)], -1)
    assert cv2.imwrite(str(tmp_path / "rgba64.png"), rgba[..., [2, 1, 0, 3]])
    np.testing.assert_array_equal(read_image(tmp_path / "rgba64.png"), rgba[..., :3])
    disparity = _match_cli(tmp_path, tmp_path, "left48.png", "right48.png")
    assert np.median(disparity[:, 12:]) == pytest.approx(SHIFT, abs=0.05)


def test_read_image_one_bit_png(tmp_path):
    from PIL import Image

    bits = _texture(5, (H, W)) > 127
    Image.fromarray(bits).save(tmp_path / "bits.png")
    image = read_image(tmp_path / "bits.png")
    assert image.dtype == np.uint8
    np.testing.assert_array_equal(image, bits * 255)


# ============================================================================ 2. nothing lost: SIGINT, resume


def _popen_with_default_sigint(argv, **kwargs) -> subprocess.Popen:
    """``Popen`` whose child handles SIGINT as in an interactive terminal.

    A shell without job control starts background jobs with SIGINT ignored, and children
    inherit that; only then is the default disposition restored in the child (which needs a
    ``preexec_fn``, so a fork of this multithreaded process: JAX warns about it).
    """
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        return subprocess.Popen(argv, **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return subprocess.Popen(
            argv, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL), **kwargs
        )


def test_evaluate_sigint_keeps_finished_scenes_and_resume_skips_them(tmp_path):
    root = _middeval3(tmp_path / "MiddEval3")
    params = tmp_path / "cheap.json"  # faster compilation; the mechanics are what is tested
    params.write_text(json.dumps({"n_segments": 0, "aggregation_iterations": 1, "refine_iterations": 1,
                                  "lr_check": False}))
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.md").write_text("earlier results\n")
    argv = ["evaluate", "--data", str(root), "--methods", "ssw", "--params", str(params), "-o", str(out)]
    first_done = out / "ssw" / SCENES[0][0] / "timeSSW.txt"  # written after the scene's PFM
    with open(tmp_path / "stderr1.txt", "w") as err_file:
        process = _popen_with_default_sigint(CLI + argv, stdout=subprocess.DEVNULL, stderr=err_file)
        try:
            deadline = time.monotonic() + 240
            while not first_done.exists():
                assert process.poll() is None, (tmp_path / "stderr1.txt").read_text()
                assert time.monotonic() < deadline, "no scene finished within 240 s"
                time.sleep(0.01)
            process.send_signal(signal.SIGINT)
            code = process.wait(timeout=240)
        finally:
            if process.poll() is None:
                process.kill()
    err = (tmp_path / "stderr1.txt").read_text()
    assert code == 130, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    prefix = "sswjax: interrupted; "
    assert last.startswith(prefix)
    assert f"of 3 scene results are saved in {out}; continue with: sswjax " in last
    finished = [name for name, _ in SCENES if (out / "ssw" / name / "disp0SSW.pfm").exists()
                and (out / "ssw" / name / "timeSSW.txt").exists()]
    assert 1 <= len(finished) < 3 and finished == [name for name, _ in SCENES[: len(finished)]]
    assert last.startswith(f"{prefix}{len(finished)} of 3 scene results")
    assert (out / "results.md").read_text() == "earlier results\n"  # only written at the end
    assert not list(out.rglob("*.tmp"))
    saved = {}
    for name in finished:
        pfm = out / "ssw" / name / "disp0SSW.pfm"
        assert read_pfm(pfm).shape == (H, dict(SCENES)[name])  # complete and readable
        saved[name] = (pfm.read_bytes(), pfm.stat().st_mtime_ns)

    # run exactly the command that the message suggests
    command = shlex.split(last.split("continue with: ", 1)[1])
    assert command[0] == "sswjax" and command[-1] == "--resume"
    resumed = subprocess.run(CLI + command[1:], capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert f"ssw: resumed {len(finished)} of 3 scenes from {out / 'ssw'}" in resumed.stderr
    for name, (content, mtime) in saved.items():  # not recomputed, not rewritten
        pfm = out / "ssw" / name / "disp0SSW.pfm"
        assert pfm.read_bytes() == content and pfm.stat().st_mtime_ns == mtime
    for name, width in SCENES:
        disparity = read_pfm(out / "ssw" / name / "disp0SSW.pfm")
        assert disparity.shape == (H, width)
        assert np.median(disparity[:, 12:]) == pytest.approx(SHIFT, abs=0.05)
    results = (out / "results.md").read_text()
    assert "| ssw |" in results and all(f"| {name} |" in results for name, _ in SCENES)
    assert len((out / "metrics.csv").read_text().splitlines()) == 1 + 3 * 2
    assert "wrote" in resumed.stdout


def test_match_interrupted_keeps_existing_output(files, tmp_path, capsys, monkeypatch):
    out = tmp_path / "d.pfm"
    write_pfm(out, np.full((2, 3), 7, np.float32))

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(sswjax, "match", interrupted)
    argv = ["match", files / "left.png", files / "right.png", "--ndisp", NDISP, "-o", out]
    code, _, err = _run(argv, capsys)
    assert code == 130 and err == "sswjax: interrupted\n"
    assert (read_pfm(out) == 7).all() and [p.name for p in tmp_path.iterdir()] == ["d.pfm"]


@pytest.fixture()
def fake_method(monkeypatch):
    """A method "fake" without JAX: disparity 3 everywhere; counts its calls per scene width."""
    from sswjax.evaluation import methods

    calls = []

    def fake(left, right, ndisp):
        calls.append(left.shape[1])
        if getattr(fake, "interrupt_at", None) == len(calls):
            raise KeyboardInterrupt
        return np.full(left.shape[:2], SHIFT, np.float32)

    monkeypatch.setitem(methods.PEERS, "fake", fake)
    fake.calls = calls
    return fake


def test_evaluate_interrupted_in_process_messages(tmp_path, capsys, fake_method):
    root = _middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "out"
    fake_method.interrupt_at = 2
    code, stdout, err = _run(["evaluate", "--data", root, "--methods", "fake", "-o", out], capsys)
    assert code == 130 and stdout == ""
    expected = (f"sswjax: interrupted; 1 of 3 scene results are saved in {out}; continue with: "
                f"sswjax evaluate --data {root} --methods fake -o {out} --resume")
    assert err.strip().splitlines()[-1] == expected
    assert sorted(p.name for p in (out / "fake").iterdir()) == ["Adirondack"]
    # without -o nothing can be kept, and the message says so
    fake_method.calls.clear()
    code, _, err = _run(["evaluate", "--data", root, "--methods", "fake"], capsys)
    assert code == 130
    assert err.strip().splitlines()[-1] == ("sswjax: interrupted; nothing was saved (with -o DIR "
                                            "finished scenes are kept and --resume continues)")


def test_evaluate_resume_recomputes_only_missing_or_damaged_scenes(tmp_path, capsys, fake_method):
    root = _middeval3(tmp_path / "MiddEval3")
    out = tmp_path / "out"
    assert _run(["evaluate", "--data", root, "--methods", "fake", "-o", out], capsys)[0] == 0
    first_csv = (out / "metrics.csv").read_text()
    assert fake_method.calls == [40, 44, 48]
    folders = {name: out / "fake" / name for name, _ in SCENES}
    (folders["Adirondack"] / "timeFAKE.txt").write_text("12.5\n")  # a recorded time is kept
    kept_mtime = (folders["Adirondack"] / "disp0FAKE.pfm").stat().st_mtime_ns
    pfm = folders["Teddy"] / "disp0FAKE.pfm"
    pfm.write_bytes(pfm.read_bytes()[:-10])  # damaged by hand: recomputed
    (folders["Vintage"] / "timeFAKE.txt").unlink()  # interrupted between the two writes
    fake_method.calls.clear()
    code, _, err = _run(["evaluate", "--data", root, "--methods", "fake", "-o", out, "--resume"], capsys)
    assert code == 0, err
    assert fake_method.calls == [44, 48]
    assert f"fake Teddy: saved result unusable (PFM file {pfm} is truncated: " in err
    assert f"fake: resumed 1 of 3 scenes from {out / 'fake'}" in err
    assert (folders["Adirondack"] / "disp0FAKE.pfm").stat().st_mtime_ns == kept_mtime
    assert read_pfm(pfm).shape == (H, 44)
    def with_time(row: str) -> str:  # the "seconds" column is the fourth
        cells = row.split(",")
        return ",".join(cells[:3] + ["12.500"] + cells[4:]) if cells[1] == "Adirondack" else row

    rows = (out / "metrics.csv").read_text().splitlines()
    assert rows[1:] == [with_time(r) for r in first_csv.splitlines()[1:]]  # same metrics, its time


# ============================================================================ 3. property-based tests


@settings(max_examples=150, deadline=None, suppress_health_check=FUNCTION_SCOPED)
@given(
    shape=st.tuples(st.integers(1, 6), st.integers(1, 6)).flatmap(
        lambda hw: st.sampled_from([hw, hw + (3,)])),
    dtype=st.sampled_from([np.float32, np.float64]),
    data=st.data(),
)
def test_pfm_round_trip_any_shape_and_value(tmp_path, shape, dtype, data):
    width = 32 if dtype == np.float32 else 64
    values = data.draw(st.lists(st.floats(width=width, allow_nan=True, allow_infinity=True),
                                min_size=int(np.prod(shape)), max_size=int(np.prod(shape))))
    array = np.array(values, dtype=dtype).reshape(shape)
    path = tmp_path / "d.pfm"
    write_pfm(path, array)
    out = read_pfm(path)
    with np.errstate(over="ignore"):
        expected = array.astype(np.float32)  # float64 beyond float32 becomes inf, like the writer
    assert out.dtype == np.float32 and out.shape == shape
    np.testing.assert_array_equal(out.view(np.uint32), expected.view(np.uint32))  # bit for bit


_SEPARATORS = st.sampled_from([b" ", b"\n", b"\r\n", b"\t", b"  \n", b"\n\n", b""])
_NUMBER_TOKENS = st.one_of(
    st.integers(-3, 12).map(lambda n: str(n).encode()),
    st.sampled_from([b"999999999999", b"1e3", b"0x10", b"3.0", b"+4", b"\xff", b"\xd9\xa3"]),
    st.binary(min_size=1, max_size=4),
)
_SCALE_TOKENS = st.one_of(
    st.sampled_from([b"-1.0", b"1.0", b"-1", b"0", b"-0.0", b"nan", b"inf", b"-inf", b"1e400", b"x"]),
    st.floats().map(lambda f: repr(f).encode()),
    st.binary(min_size=1, max_size=4),
)


@settings(max_examples=400, deadline=None, suppress_health_check=FUNCTION_SCOPED)
@given(
    magic=st.one_of(st.sampled_from([b"Pf", b"PF", b"pf", b"P5", b"PFF"]), st.binary(min_size=1, max_size=3)),
    width=_NUMBER_TOKENS,
    height=_NUMBER_TOKENS,
    scale=_SCALE_TOKENS,
    separators=st.lists(_SEPARATORS, min_size=4, max_size=4),
    body=st.integers(0, 200),
)
def test_pfm_fuzzed_headers_raise_only_input_error(tmp_path, magic, width, height, scale, separators, body):
    header = magic + separators[0] + width + separators[1] + height + separators[2] + scale + separators[3]
    path = tmp_path / "fuzz.pfm"
    path.write_bytes(header + bytes(range(256))[:body])
    try:
        out = read_pfm(path)
    except InputError as error:
        message = str(error)
        assert "\n" not in message and str(path) in message
    else:
        assert out.dtype == np.float32 and out.ndim in (2, 3)
        tokens = (magic, width, height, scale)
        if all(t and not any(chr(b).isspace() for b in t) for t in tokens) and all(separators):
            channels = 3 if magic == b"PF" else 1  # a clean header: the size is the header's
            assert out.shape[:2] == (int(height), int(width))
            assert out.size == int(height) * int(width) * channels


@functools.cache
def _small_png() -> bytes:
    buffer = io.BytesIO()
    iio.imwrite(buffer, _texture(6, (6, 9, 3)), extension=".png")
    return buffer.getvalue()


@settings(max_examples=300, deadline=None, suppress_health_check=FUNCTION_SCOPED)
@given(cut=st.integers(0, 400),
       flips=st.lists(st.tuples(st.integers(0, 400), st.integers(0, 255)), max_size=3))
def test_damaged_png_raises_only_input_error(tmp_path, cut, flips):
    data = bytearray(_small_png())
    for position, value in flips:
        if position < len(data):
            data[position] = value
    data = bytes(data[: len(data) - min(cut, len(data))])
    path = tmp_path / "damaged.png"
    path.write_bytes(data)
    try:
        image = read_image(path)
    except InputError as error:
        assert "\n" not in str(error) and str(path) in str(error)
    else:
        assert image.ndim in (2, 3) and image.dtype in (np.uint8, np.uint16)
        if not flips:  # only the trailing IEND chunk was cut: the pixels are all there
            np.testing.assert_array_equal(image, _texture(6, (6, 9, 3)))


_IMAGE_KINDS = ("noise", "constant", "zeros", "saturated", "stripes", "checker", "shifted")


def _image_pair(kind: str, shape: tuple, seed: int):
    rng = np.random.default_rng(seed)
    if kind == "noise":
        return rng.random(shape), rng.random(shape)
    if kind == "constant":
        value = rng.random()
        return np.full(shape, value), np.full(shape, value)
    if kind == "zeros":
        return np.zeros(shape), np.zeros(shape)
    if kind == "saturated":
        return (rng.random(shape) > 0.5) * 1.0, np.ones(shape)
    if kind == "stripes":
        row = (np.arange(shape[1]) % 2) * 1.0
        stripes = np.broadcast_to(row[None, :, None] if len(shape) == 3 else row[None], shape)
        return stripes, np.roll(stripes, 1, axis=1)
    if kind == "checker":
        yy, xx = np.indices(shape[:2])
        board = ((yy // 3 + xx // 3) % 2) * 1.0
        board = board[..., None].repeat(shape[2], -1) if len(shape) == 3 else board
        return board, board
    right = rng.random(shape)
    return np.roll(right, int(rng.integers(0, NDISP)), axis=1), right


@settings(max_examples=12, deadline=None)
@given(
    shape=st.sampled_from([(24, 40, 3), (16, 32)]),
    kind=st.sampled_from(_IMAGE_KINDS),
    dtype=st.sampled_from(["uint8", "uint16", "float32", "float64"]),
    seed=st.integers(0, 2**16),
    weights=st.tuples(*[st.floats(0, 1)] * 3),
    truncations=st.tuples(st.floats(1e-3, 1), st.floats(1e-3, 1)),
    segment_weight=st.floats(0, 2),
    lr_tolerance=st.floats(0, 3),
)
def test_pipeline_invariants_on_random_images(shape, kind, dtype, seed, weights, truncations,
                                              segment_weight, lr_tolerance):
    left, right = _image_pair(kind, shape, seed)
    if dtype.startswith("uint"):
        scale = np.iinfo(dtype).max
        left, right = (np.round(im * scale).astype(dtype) for im in (left, right))
    else:
        left, right = left.astype(dtype), right.astype(dtype)
    params = Params().replace(
        tad_weight=weights[0], gradient_weight=weights[1], census_weight=weights[2],
        tad_truncation=truncations[0], gradient_truncation=truncations[1],
        segment_weight=segment_weight, lr_tolerance=lr_tolerance,
    )
    disparity = sswjax.match(left, right, NDISP, params)
    assert isinstance(disparity, np.ndarray)
    assert disparity.shape == shape[:2] and disparity.dtype == np.float32
    assert np.isfinite(disparity).all()
    assert disparity.min() >= 0 and disparity.max() <= NDISP - 1


# ============================================================================ 4. determinism


def test_same_inputs_bit_identical_in_process(files):
    left, right = read_image(files / "left.png"), read_image(files / "right.png")
    first = sswjax.match(left, right, NDISP)
    second = sswjax.match(left.copy(), right.copy(), NDISP)
    assert first.tobytes() == second.tobytes()


def test_same_inputs_bit_identical_across_processes(files, tmp_path):
    argv = ["match", str(files / "left.png"), str(files / "right.png"), "--ndisp", str(NDISP)]
    processes = [subprocess.Popen(CLI + argv + ["-o", str(tmp_path / f"p{i}.pfm")],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                 for i in range(2)]  # concurrently: two cores, half the wall time
    for process in processes:
        _, err = process.communicate(timeout=300)
        assert process.returncode == 0, err
    assert main(argv + ["-o", str(tmp_path / "here.pfm")]) == 0
    contents = {(tmp_path / name).read_bytes() for name in ("p0.pfm", "p1.pfm", "here.pfm")}
    assert len(contents) == 1
    expected = sswjax.match(read_image(files / "left.png"), read_image(files / "right.png"), NDISP)
    assert read_pfm(tmp_path / "here.pfm").tobytes() == expected.tobytes()
