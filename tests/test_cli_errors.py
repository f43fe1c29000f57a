"""Bad input on the command line: one line on stderr, exit status 2, outputs left as they were.

Every ``sswjax match`` and ``sswjax evaluate`` row of the README table "Bad input: what the user
sees" names its test here. The inputs are conftest's ``small_pair`` files (24x40, disparity 3)
and ``middeval3`` folders; ``ndisp`` is 8, so the in-process runs share one or two compilations.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest

from sswjax.cli import main
from sswjax.data.io import read_pfm, write_pfm

NDISP = 8  # conftest's small_pair.ndisp
CLI = [sys.executable, "-m", "sswjax.cli"]


@pytest.fixture(scope="module")
def files(small_pair) -> Path:
    return small_pair.folder


def _assert_one_line_error(code, err, message):
    assert code == 2, err
    assert err.startswith("sswjax: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert message in err, err


# ----------------------------------------------------------------------------- sswjax match


@pytest.mark.parametrize(
    "left, right, extra, message",
    [
        ("missing.png", "right.png", [], "image not found: {d}/missing.png"),
        ("left.png", "folder.png", [], "LEFT and RIGHT must be two image files or two folders: "
                                       "{d}/folder.png is a folder, {d}/left.png is not"),
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
def test_match_bad_input(files, tmp_path, run_cli, left, right, extra, message):
    out = tmp_path / "d.pfm"
    write_pfm(out, np.full((2, 3), 7, np.float32))  # the user's earlier result
    argv = ["match", files / left, files / right, *(extra or ["--ndisp", NDISP]), "-o", out]
    code, _, err = run_cli(argv)
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


def test_match_unreadable_image(files, run_cli):
    folder = Path(tempfile.mkdtemp(prefix="sswjax-unreadable-"))
    try:
        folder.chmod(0o777)  # nobody may write the output there: only the image is unreadable
        locked = folder / "locked.png"
        locked.write_bytes((files / "left.png").read_bytes())
        locked.chmod(0)
        argv = ["match", str(locked), str(files / "right.png"), "--ndisp", "8", "-o", str(folder / "d.pfm")]
        if os.geteuid() == 0:
            code = _drop_privileges_and_run(argv, folder / "stderr.txt")
            err = (folder / "stderr.txt").read_text()
        else:
            code, _, err = run_cli(argv)
        _assert_one_line_error(code, err, f"cannot read image {locked}: Permission denied")
        assert not (folder / "d.pfm").exists()
    finally:
        for path in folder.iterdir():
            path.unlink()
        folder.rmdir()


@pytest.mark.parametrize(
    "content, message",
    [
        ('{"cost": {"tad_truncation": NaN}}',
         "parameter cost.tad_truncation must be finite in float32 (the graph's dtype), got nan"),
        ('{"cost": {"tad_truncation": Infinity}}', "parameter cost.tad_truncation must be finite in float32 (the graph's dtype), got inf"),
        ('{"cost": {"tad_truncation": -0.1}}',
         "parameter cost.tad_truncation must be a number > 0, got -0.1"),
        ('{"cost": {"census_weight": -1}}', "parameter cost.census_weight must be a number >= 0, got -1.0"),
        ('{"cost": {"census_width": 17}}', "parameter cost.census_width must be an odd integer in [1, 15], got 17"),
        ('{"cost": {"census_height": 8}}', "parameter cost.census_height must be an odd integer in [1, 15], got 8"),
        ('{"refinement": {"radius": -1}}', "parameter refinement.radius must be an integer in [1, 7], got -1"),
        ('{"preset": "paper", "fill": {"median_radius": 8}}', "parameter fill.median_radius must be in [0, 5] with fill.median 'square', got 8"),
        ('{"fill": {"median_radius": 16, "median": "separable"}}', "parameter fill.median_radius must be an integer in [0, 15], got 16"),
        ('{"static": {"radius": 3}}', "parameters in the old flat names ('static'): convert the file with sswjax params --upgrade {p} -o NEW.json"),
        ('{"bogus": {}}', "unknown parameter 'bogus'"),
        ('{"cost": {"census_width": "9"}}', "parameter cost.census_width must be an odd integer in [1, 15], got '9'"),
        ('{"selection": {"subpixel": "yes"}}', "parameter selection.subpixel must be true or false, got 'yes'"),
        ('{"cost": {"census_weight": null}}', "parameter cost.census_weight must be a number >= 0, got None"),
        ("[1, 2]", "parameters must be a JSON object, got list"),
        ("{not json", "cannot read parameter file {p}: Expecting property name"),
        (b"\xff\xfe{}", "cannot read parameter file {p}: 'utf-8' codec can't decode"),
        ('{"cost": {"tad_weight": 1e308, "census_weight": 1e308}}',
         "parameter cost.tad_weight must be finite in float32 (the graph's dtype), got 1e+308"),
        ('{"cost": {"tad_weight": 0, "gradient_weight": 0, "census_weight": 0}}',
         "parameters cost.tad_weight, gradient_weight and census_weight are all 0: no pixel has a cost"),
        ('{"cost": {"census_width": 1, "census_height": 1}}',
         "parameters cost.census_height and cost.census_width: a 1 x 1 census window compares no neighbour"),
        ("[" * 100_000 + "]" * 100_000, "cannot read parameter file {p}: nested too deeply"),
    ],
    ids=["nan", "infinity", "negative-truncation", "negative-weight", "int-too-large", "even-census",
         "negative-radius", "fill-radius-too-large", "separable-fill-radius-too-large",
         "old-flat-file", "unknown-key", "string-for-int", "string-for-bool",
         "null-for-number", "not-an-object", "bad-json", "not-utf8", "beyond-float32",
         "no-weight", "census-1x1", "nested-too-deeply"],
)
def test_match_bad_params_json(files, tmp_path, run_cli, content, message):
    params = tmp_path / "params.json"
    params.write_bytes(content if isinstance(content, bytes) else content.encode())
    argv = ["match", files / "left.png", files / "right.png", "--ndisp", NDISP,
            "-o", tmp_path / "d.pfm", "--params", params]
    code, _, err = run_cli(argv)
    _assert_one_line_error(code, err, message.format(p=params))
    if not message.startswith("cannot read"):
        assert err.startswith(f"sswjax: error: {params}: ")  # names the file
    assert not (tmp_path / "d.pfm").exists()


def test_match_output_is_a_folder(files, tmp_path, run_cli):
    code, _, err = run_cli(["match", files / "left.png", files / "right.png", "--ndisp", NDISP,
                            "-o", tmp_path])
    _assert_one_line_error(code, err, f"output {tmp_path} is a folder, expected a file name")


def test_debug_shows_the_traceback(files, tmp_path):
    argv = ["match", str(files / "missing.png"), str(files / "right.png"), "--ndisp", "8",
            "-o", str(tmp_path / "d.pfm")]
    plain = subprocess.run(CLI + argv, capture_output=True, text=True, timeout=120)
    assert plain.returncode == 2 and plain.stderr.count("\n") == 1 and "Traceback" not in plain.stderr
    debug = subprocess.run(CLI + ["--debug"] + argv, capture_output=True, text=True, timeout=120)
    assert debug.returncode == 1
    assert debug.stderr.startswith("Traceback (most recent call last):")
    assert "sswjax._files.InputError: image not found" in debug.stderr


# ----------------------------------------------------------------------------- sswjax evaluate


def _break_truncated_gt(scene: Path) -> None:
    data = (scene / "disp0GT.pfm").read_bytes()
    (scene / "disp0GT.pfm").write_bytes(data[:100])


@pytest.mark.parametrize(
    "damage, extra, message",
    [
        (lambda s: (s / "im1.png").unlink(), [], "scene Teddy: missing im1.png in {s}"),
        (lambda s: (s / "im0.png").unlink(), [], "scene Teddy: missing im0.png in {s}"),
        (lambda s: (s / "calib.txt").unlink(), [], "scene Teddy: missing calib.txt in {s}"),
        (lambda s: (s / "disp0GT.pfm").unlink(), [], "scene Teddy: missing disp0GT.pfm in {s}"),
        (lambda s: (s / "mask0nocc.png").unlink(), [], "scene Teddy: missing mask0nocc.png in {s}"),
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
def test_evaluate_bad_folder(tmp_path, run_cli, middeval3, damage, extra, message):
    root = middeval3(tmp_path / "MiddEval3")
    scene = root / "trainingQ" / "Teddy"
    damage(scene)
    code, out, err = run_cli(["evaluate", "--data", root, "--methods", "ssw", *extra])
    _assert_one_line_error(code, err, message.format(s=scene))
    assert out == ""  # failed before any scene was run


# ----------------------------------------------------------------------------- the reader goes away


def _reader_stops_after_one_line(argv: list[str]) -> tuple[bytes, subprocess.CompletedProcess]:
    """Run ``python -m sswjax.cli ARGV`` with stdout a real pipe of 4 KiB (fewer bytes than the
    command prints, so that it is still writing), read one line and close the pipe, as
    ``| head -1`` does. Returns the line read and the process (its stderr captured)."""
    import fcntl

    read_end, write_end = os.pipe()
    fcntl.fcntl(write_end, fcntl.F_SETPIPE_SZ, 4096)
    env = {name: value for name, value in os.environ.items() if name != "PYTHONUNBUFFERED"}
    process = subprocess.Popen(CLI + argv, stdout=write_end, stderr=subprocess.PIPE, env=env)
    os.close(write_end)
    with os.fdopen(read_end, "rb", buffering=0) as pipe:
        line = b""
        while not line.endswith(b"\n"):
            line += pipe.read(1)
    err = process.communicate(timeout=120)[1]
    return line, subprocess.CompletedProcess(process.args, process.returncode, None, err)


def test_a_reader_that_stops_early_ends_the_command_quietly():
    """``sswjax params --list | head -1``: the first line, then nothing on stderr and status 141
    (128 + SIGPIPE, what ``yes | head -1`` reports to the shell), not ``sswjax: error: [Errno 32]
    Broken pipe`` with status 2. (The catalogue, 17 kB, is longer than the pipe.)"""
    line, run = _reader_stops_after_one_line(["params", "--list"])
    assert line.startswith(b"Stages in pipeline order"), line
    assert run.stderr == b"", run.stderr.decode()
    assert run.returncode == 141


# ----------------------------------------------------------------------------- what --help claims


def _option_help(command: str, option: str) -> str:
    """The help of ``option`` in ``sswjax COMMAND --help``, as one line."""
    from sswjax.cli.app import build_parser

    parser = build_parser((command,))
    sub = next(action for action in parser._actions if action.dest == "command").choices[command]
    action = next(action for action in sub._actions if option in action.option_strings)
    return " ".join(action.help.replace("%%", "%").split())


@pytest.mark.parametrize("command", ["match", "params"])
def test_the_set_examples_of_the_help_run_on_the_default_preset(command, run_cli, tmp_path):
    """Each ``--set`` example the help gives (``e.g. A, B.``) is accepted as written, on the
    default preset: a user who copies one gets a run, not an error."""
    text = _option_help(command, "--set")
    examples = text.split("e.g. ", 1)[1].split(". ", 1)[0].split(", ")
    assert len(examples) >= 2 and all("=" in example for example in examples), text
    for example in examples:
        code, _, err = run_cli(["params", "--set", example, "-o", tmp_path / "p.json"])
        assert code == 0, f"--set {example}: {err}"


def test_a_fill_that_needs_segments_says_how_to_turn_them_on(run_cli):
    code, out, err = run_cli(["params", "--set", "fill=plane"])
    _assert_one_line_error(code, err, "fill 'plane' fits a plane per superpixel: it needs "
                                      "segments (--set segments=slic)")
    code, out, err = run_cli(["params", "--set", "fill=plane", "--set", "segments=slic"])
    assert code == 0 and '"kind": "plane"' in out, err


def test_max_memory_help_says_what_the_guard_does(small_pair):
    """``--max-memory``: a pair over the limit is matched in strips, refused only when even
    strips do not fit; the help says so (it said "refuse to run")."""
    from sswjax.cli.guard import guard_memory
    from sswjax.config import default_params
    from sswjax.runtime.memory import estimate_peak_bytes
    from sswjax.runtime.plan import ExecutionPlan

    params, plan = default_params(), ExecutionPlan()
    whole = estimate_peak_bytes(1000, 1000, 64, params=params, plan=plan, channels=3)
    fitted = guard_memory([(1000, 1000, 3)], 64, params=params, plan=plan,
                          limit_gb=whole * 0.9 / 1e9)
    assert fitted.strip_rows or fitted.tile  # over the limit: strips, not a refusal
    text = _option_help("match", "--max-memory")
    assert "refuse to run if" not in text
    assert "strips or tiles" in text and "refused only" in text, text


@pytest.mark.parametrize("flag", ["--bucket", "--strict"])
def test_folder_flags_with_one_pair_say_they_are_ignored(small_pair, tmp_path, run_cli, tiny,
                                                          flag):
    """``--bucket`` pads the pairs of a folder run and ``--strict`` refuses a folder run with a
    bad pair; one pair is matched at its own shape and refused whole anyway: a note says the
    option is ignored (the run goes on: a script may pass it for both)."""
    files = small_pair.folder
    code, out, err = run_cli(["match", files / "left.png", files / "right.png", "--ndisp", NDISP,
                              flag, *tiny.args, "-o", tmp_path / "d.pfm"])
    assert code == 0, err
    assert f"sswjax: note: {flag} applies to folder runs; ignored for one pair\n" in err
    assert read_pfm(tmp_path / "d.pfm").shape == (small_pair.height, small_pair.width)


def test_no_cache_help_names_the_folder_the_cache_is_in(monkeypatch, tmp_path):
    """The help of ``--no-cache`` names where the cache is: ``$XDG_CACHE_HOME`` counts."""
    from sswjax.cli.app import build_parser
    from sswjax.runtime.compilation import default_cache_dir

    monkeypatch.delenv("SSWJAX_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert default_cache_dir() == tmp_path / "sswjax" / "xla"
    action = next(a for a in build_parser(("params",))._actions if "--no-cache" in a.option_strings)
    assert "$XDG_CACHE_HOME/sswjax/xla" in action.help
