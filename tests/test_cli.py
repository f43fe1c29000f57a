"""The ``sswjax`` command line: outputs, exit codes and one-line errors."""

from __future__ import annotations

import contextlib
import io
import json
import os
import pty
import subprocess
import sys

import imageio.v3 as iio
import numpy as np
import pytest

import sswjax
from sswjax.cli import guard, main
from sswjax.cli import match as cli_match
from sswjax.cli.app import COMMANDS, build_parser, commands_needed
from sswjax.config.fields import option_fields
from sswjax.config.parts import unregister
from sswjax.data.io import read_image, read_pfm, write_pfm
from sswjax.runtime import memory
from sswjax.runtime.memory import MemoryEstimateError

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
    return folder


def test_match_writes_pfm_and_png(small_pair, tmp_path, capsys, tiny):
    # conftest's small pair: the colour graph of test_cli_inputs_that_must_work below
    out, files = tmp_path / "d.pfm", small_pair.folder
    code = main(["match", str(files / "left.png"), str(files / "right.png"), "--ndisp",
                 str(small_pair.ndisp), "-o", str(out), "--png", str(tmp_path / "d.png"),
                 *tiny.args])
    assert code == 0
    disparity = read_pfm(out)
    assert disparity.shape == (24, 40) and disparity.dtype == np.float32
    assert np.median(disparity[:, 12:]) == pytest.approx(small_pair.shift, abs=0.01)
    assert iio.imread(tmp_path / "d.png").shape == (24, 40, 3)
    assert "wrote" in capsys.readouterr().out


def test_match_gray_colour_mix(small_pair, tmp_path, tiny):
    # the graph of the colour/gray pairs of test_cli_inputs_that_must_work below
    out = tmp_path / "d.pfm"
    files = small_pair.folder
    code = main(["match", str(files / "left.png"), str(files / "right_gray.png"), "--ndisp", "8",
                 "-o", str(out), *tiny.args])
    assert code == 0 and read_pfm(out).shape == (small_pair.height, small_pair.width)


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
    params.write_text('{"aggregation": {"radius": 2.5}}')
    code = main(["match", str(pair / "im0.png"), str(pair / "im1.png"), "--ndisp", "8",
                 "-o", str(tmp_path / "d.pfm"), "--params", str(params)])
    err = capsys.readouterr().err
    assert code == 2 and "aggregation.radius" in err and err.count("\n") == 1


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


def test_a_command_line_imports_only_the_module_of_its_command():
    """``sswjax match`` does not pay for the modules of ``search`` (optax), ``evaluate`` (its
    figures) and ``download``; ``--help``, no command or a typo build every parser."""
    script = ("import atexit, sys; atexit.register(lambda: print('loaded:', *(m for m in ("
              "'optax', 'sswjax.search', 'sswjax.cli.evaluate', 'sswjax.evaluation.figures', "
              "'sswjax.data.download', 'sswjax.cli.match') if m in sys.modules))); "
              "from sswjax.cli import main; main(sys.argv[1:])")
    loaded = subprocess.run([sys.executable, "-c", script, "--debug", "match", "--help"],
                            capture_output=True, text=True)
    assert loaded.returncode == 0 and "--ndisp" in loaded.stdout
    assert loaded.stdout.splitlines()[-1].split() == ["loaded:", "sswjax.cli.match"]
    assert commands_needed(["--no-cache", "search", "--data", "d"]) == ("search",)
    for argv in ([], ["-h", "match"], ["--debug"], ["mach", "l", "r"]):
        assert commands_needed(argv) == COMMANDS
    assert " ".join(COMMANDS) in " ".join(build_parser().format_help().replace(",", " ").split())


def test_the_console_script_runs_main_and_leaves_its_objects_to_the_exit(tmp_path):
    """``sswjax`` (``console``) returns ``main``'s status, writes its output, and freezes what
    the run left so that the exit does not collect it; ``main`` itself freezes nothing."""
    script = ("import gc, sys; from sswjax.cli.app import console, main; "
              "assert main(['params', '--preset', 'fast', '-o', sys.argv[1]]) == 0; "
              "assert gc.get_freeze_count() == 0; "
              "sys.argv = ['sswjax', 'params', '--preset', 'fast', '-o', sys.argv[2]]; "
              "code = console(); print(code, gc.get_freeze_count() > 0)")
    first, second = tmp_path / "main.json", tmp_path / "console.json"
    run = subprocess.run([sys.executable, "-c", script, str(first), str(second)],
                         capture_output=True, text=True, check=True)
    assert run.stdout.splitlines()[-1] == "0 True"
    assert json.loads(second.read_text()) == json.loads(first.read_text())


@pytest.mark.parametrize("collecting", [True, False])
def test_importing_the_package_pauses_the_collector_and_sets_it_back(collecting):
    """JAX and the package import without a single collection (counted from JAX's import to
    the package's ``__all__``, which follows its imports), and the collector is left on or off
    as the importer had it."""
    script = ("import gc, sys; collections = []; "
              "gc.callbacks.append(lambda phase, info: collections.append(phase) "
              "if 'jax' in sys.modules and not hasattr(sys.modules['sswjax'], '__all__') "
              "else None); "
              f"gc.enable() if {collecting} else gc.disable(); "
              "import sswjax; print(len(collections), gc.isenabled())")
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True)
    assert run.stdout.split() == ["0", str(collecting)]


def _stderr_on_a_terminal(argv: list[str], env: dict) -> tuple[int, list[str]]:
    """Run ``argv`` with its stderr on a pseudo-terminal; its exit status and stderr's lines."""
    reader, writer = pty.openpty()
    try:
        done = subprocess.run(argv, env=env, stdout=subprocess.DEVNULL, stderr=writer)
    finally:
        os.close(writer)
    chunks = []
    with contextlib.suppress(OSError):  # the terminal's end: EIO once all is read
        while chunk := os.read(reader, 4096):
            chunks.append(chunk)
    os.close(reader)
    return done.returncode, b"".join(chunks).decode().splitlines()


@pytest.mark.slow  # four fresh processes, each importing JAX (and two compiling)
def test_a_first_match_says_it_compiles_on_a_terminal_and_a_warm_one_does_not(pair, tmp_path,
                                                                               tiny):
    """A first call for an image size compiles for seconds: ``match`` says so on a terminal
    (``sswjax: compiling ...``, then its time). A second process finds the graph in the cache
    and says nothing; without the cache every process compiles, and says that. Where stderr is
    not a terminal (a script, a log) the same lines are written (issue 72: no silence there
    either; ``--quiet`` leaves them out, ``tests/test_compile_log.py``). (The method is a cheap
    one, conftest's tiny: the lines are the same for every method, compiling it is not.)"""
    cheap = tiny.args
    cache = tmp_path / "cache"
    env = {**os.environ, "SSWJAX_CACHE_DIR": str(cache)}
    out = tmp_path / "d.pfm"

    def argv(*before):
        out.unlink(missing_ok=True)
        return [sys.executable, "-m", "sswjax.cli", *before, "match", str(pair / "im0.png"),
                str(pair / "im1.png"), "--ndisp", "8", *cheap, "-o", str(out)]

    def notes(*before):
        code, lines = _stderr_on_a_terminal(argv(*before), env)
        assert code == 0 and out.exists(), lines
        return [line.strip() for line in lines if "compiling" in line]

    height, width = read_image(pair / "im0.png").shape[:2]
    compiling = (f"sswjax: compiling paper (segments off, aggregation changed) for {width}x"
                 f"{height}, ndisp 8 (first call for this shape; cached for the next)")
    assert notes() == [compiling]
    assert notes() == []
    assert notes("--no-cache") == [compiling]
    piped = subprocess.run(argv("--no-cache"), env=env, capture_output=True, text=True)
    assert piped.returncode == 0 and compiling in piped.stderr.splitlines()


@pytest.mark.slow  # the default preset on a 500 x 741 pair
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


def _match_cli(files, tmp_path, left, right, cheap, ndisp=8):  # small_pair.ndisp; tiny.args
    out = tmp_path / "d.pfm"
    assert main(["match", str(files / left), str(files / right), "--ndisp", str(ndisp), "-o", str(out),
                 *cheap]) == 0
    return read_pfm(out)


def test_cli_inputs_that_must_work(small_pair, tmp_path, capsys, tiny):
    """Colour, gray, 16-bit, RGBA and colour/gray pairs, from files, agree with the API (on
    conftest's tiny configuration: the inputs are what is tested)."""
    files, shift, ndisp = small_pair.folder, small_pair.shift, small_pair.ndisp
    colour = _match_cli(files, tmp_path, "left.png", "right.png", tiny.args)
    assert np.median(colour[:, 12:]) == pytest.approx(shift, abs=0.05)
    # RGBA: the alpha channel is dropped, the result is bit-identical
    np.testing.assert_array_equal(_match_cli(files, tmp_path, "left_rgba.png", "right_rgba.png", tiny.args),
                                  colour)
    # gray pairs, 8 and 16 bits (v * 257 / 65535 == v / 255 exactly in float32)
    gray = _match_cli(files, tmp_path, "left_gray.png", "right_gray.png", tiny.args)
    assert np.median(gray[:, 12:]) == pytest.approx(shift, abs=0.05)
    assert read_image(files / "left_gray16.png").dtype == np.uint16
    np.testing.assert_array_equal(_match_cli(files, tmp_path, "left_gray16.png", "right_gray16.png",
                                             tiny.args), gray)
    # colour + gray (either side): both used as gray, the colour one by BT.601 luma, like the API
    mixed = _match_cli(files, tmp_path, "left.png", "right_gray.png", tiny.args)
    assert np.median(mixed[:, 12:]) == pytest.approx(shift, abs=0.05)
    api = sswjax.match(read_image(files / "left.png"), read_image(files / "right_gray.png"), ndisp,
                       params=tiny.params)
    np.testing.assert_array_equal(mixed, api)
    mixed_other_way = _match_cli(files, tmp_path, "left_gray16.png", "right.png", tiny.args)
    api = sswjax.match(read_image(files / "left_gray16.png"), read_image(files / "right.png"), ndisp,
                       params=tiny.params)
    np.testing.assert_array_equal(mixed_other_way, api)
    assert "wrote" in capsys.readouterr().out


def test_cli_16bit_colour_png(small_pair, tmp_path, tiny):
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
    disparity = _match_cli(tmp_path, tmp_path, "left48.png", "right48.png", tiny.args)
    assert np.median(disparity[:, 12:]) == pytest.approx(small_pair.shift, abs=0.05)


@pytest.mark.parametrize("preset", sorted(sswjax.PRESETS))
def test_match_preset(pair, tmp_path, preset, recorded_match):
    """``--preset NAME`` hands the matcher the preset and nothing else of its own: the same
    call as ``sswjax.match(left, right, ndisp, params=sswjax.preset(NAME))``, whose maps are
    the preset tests'. (The command's own map is compared with the API's, matched for real,
    in ``test_set_reaches_the_matcher``.)"""
    out = tmp_path / "d.pfm"
    code = main(["match", str(pair / "im0.png"), str(pair / "im1.png"), "--ndisp", str(NDISP),
                 "-o", str(out), "--preset", preset])
    assert code == 0
    assert recorded_match == [{"min_disp": 0, "params": sswjax.preset(preset),
                               "plan": sswjax.ExecutionPlan(), "check_memory": False}]
    assert read_pfm(out).shape == (40, 64)


@pytest.mark.parametrize("args, message", [
    (["--preset", "nope"], "argument --preset: invalid choice: 'nope'"),
    # both are allowed (the preset fills what the file leaves out): the missing file is named
    (["--preset", "paper", "--params", "p.json"], "parameter file not found: p.json"),
])
def test_match_bad_preset_one_line_exit_2(pair, tmp_path, capsys, args, message):
    out = tmp_path / "d.pfm"
    try:  # argparse's errors exit, the command's return 2
        code = main(["match", str(pair / "im0.png"), str(pair / "im1.png"), "--ndisp",
                     str(NDISP), "-o", str(out), *args])
    except SystemExit as exit_:
        code = exit_.code
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert not out.exists()


# ----------------------------------------------------------------------------- --set, sswjax params


def _params_json(run_cli, *args):
    """The parameters ``sswjax params ARGS`` prints, loaded back as ``--params`` would."""
    code, out, err = run_cli(["params", *args])
    assert code == 0, err
    data = json.loads(out)
    assert data["format"] == "sswjax-params/2"
    return sswjax.config.params_from_dict(data)


@pytest.mark.parametrize("preset", sorted(sswjax.PRESETS))
def test_params_prints_a_file_that_loads_as_the_preset(run_cli, tmp_path, preset):
    assert _params_json(run_cli, "--preset", preset) == sswjax.preset(preset)
    path = tmp_path / f"{preset}.json"
    code, out, err = run_cli(["params", "--preset", preset, "-o", path])
    assert code == 0 and out == f"wrote {path}\n", err
    assert sswjax.load_params(path) == sswjax.preset(preset)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # atomic: no debris
    # the default is the default preset, and a file goes round unchanged
    assert _params_json(run_cli) == sswjax.default_params()
    assert _params_json(run_cli, "--params", path) == sswjax.preset(preset)


def test_set_changes_a_stage_and_options(run_cli):
    params = _params_json(run_cli, "--preset", "paper", "--set", "fill=vote", "--set",
                          "optimizer=sgm", "--set", "optimizer.p2=1.2", "--set",
                          "checks.uniqueness_gap=2", "--set", "refinement=none",
                          "--set", 'aggregation={"kind": "box", "radius": 3}')
    expected = sswjax.preset("paper").replace(
        fill={"kind": "vote"}, optimizer={"kind": "sgm"}, refinement=None,
        aggregation={"kind": "box", "radius": 3},
        **{"optimizer.p2": 1.2, "checks.uniqueness_gap": 2})
    assert params == expected
    assert params.fill.kind == "vote" and params.optimizer.p2 == 1.2 and params.refinement is None
    # a JSON integer for a traced option is stored as a float, like a file's
    assert type(_params_json(run_cli, "--set", "optimizer.p2=1").optimizer.p2) is float
    # later settings win, "null" turns a stage off too
    assert _params_json(run_cli, "--set", "coarse=halving", "--set", "coarse=null").coarse is None


@pytest.mark.parametrize("setting, message", [
    ("bogus=1", "--set bogus=1: unknown parameter 'bogus': name a stage (alignment, preprocess,"),
    ("fill=nope", "--set fill=nope: unknown fill kind 'nope'; choose from background,"),
    ("fill.nope=1", "--set fill.nope=1: fill 'vote' has no option 'nope'"),
    ("nostage.p2=1", "--set nostage.p2=1: unknown parameter 'nostage.p2'"),
    ("optimizer.p2=-1", "--set optimizer.p2=-1: parameter optimizer.p2 must be a number >= 0"),
    ("optimizer.paths=true", "parameter optimizer.paths must be one of 4, 8, got True"),
    ("cost=none", "--set cost=none: stage cost cannot be None"),
    ("fill=3", "--set fill=3: stage fill takes a kind (none, background,"),
    ('fill={"kind": [1]}', "stage fill: \"kind\" must be one of background,"),
    ("checks=none", "fills what the checks reject: with checks None, set fill to None too"),
    ("strip_rows=64", "strip_rows is how a call runs, not a parameter: use --strip-rows"),
    ("novalue", "argument --set: expected PATH=VALUE (a stage or stage.option), got 'novalue'"),
])
def test_bad_set_one_line_exit_2(pair, run_cli, tmp_path, setting, message):
    out = tmp_path / "d.pfm"
    code, stdout, err = run_cli(["match", pair / "im0.png", pair / "im1.png", "--ndisp", NDISP,
                                 "-o", out, "--set", setting])
    assert code == 2 and stdout == "", err
    assert err.startswith("sswjax: error: ") and err.count("\n") == 1 and message in err, err
    assert not out.exists()


@pytest.mark.parametrize("typed, got", [
    ("optimizer.p2=1e400", "inf"),      # beyond float64: JSON reads it as infinity
    ("optimizer.p2=1e39", "1e+39"),     # beyond float32
    ('optimizer={"kind": "sgm", "p2": -1e400}', "-inf"),
])
def test_set_echoes_a_number_beyond_float32_as_typed(run_cli, typed, got):
    code, out, err = run_cli(["params", "--set", typed])
    assert (code, out) == (2, "")
    assert err == (f"sswjax: error: --set {typed}: parameter optimizer.p2 must be finite in "
                   f"float32 (the graph's dtype), got {got}\n")


def test_set_reaches_the_matcher(small_pair, tmp_path, run_cli, tiny):
    # a traced option: the graph of test_match_writes_pfm_and_png, other numbers in it
    out, files, ndisp = tmp_path / "d.pfm", small_pair.folder, small_pair.ndisp
    code, _, err = run_cli(["match", files / "left.png", files / "right.png", "--ndisp", ndisp,
                            "-o", out, *tiny.args, "--set", "cost.census_weight=0"])
    assert code == 0, err
    left, right = read_image(files / "left.png"), read_image(files / "right.png")
    expected = sswjax.match(left, right, ndisp,
                            params=tiny.params.replace(**{"cost.census_weight": 0.0}))
    np.testing.assert_array_equal(read_pfm(out), expected)
    assert not np.array_equal(expected, sswjax.match(left, right, ndisp, params=tiny.params))


def test_params_list_names_every_stage_kind_and_option(run_cli):
    code, out, err = run_cli(["params", "--list"])
    assert code == 0, err
    for slot in sswjax.config.SLOTS:
        assert f"\n{slot} (" in out
        for kind, cls in sswjax.config.kinds(slot).items():
            assert f"  {kind}: {cls.summary()}" in out
            for name, spec in option_fields(cls):
                assert f"{slot}.{name}" in out and spec.describe() in out
    assert "optimizer.p2" in out and "traced" in out and "static" in out
    code, _, err = run_cli(["params", "--list", "--preset", "paper"])
    assert code == 2 and err == "sswjax: error: --list prints the catalogue of stages: it takes no --preset\n"


def test_a_part_registered_at_run_time_is_on_the_command_line(run_cli):
    @sswjax.config.register("preprocess", "toy")
    class Toy(sswjax.config.Preprocessor):
        """A toy pre-processor: the images times a gain."""

        gain: float = sswjax.config.option(2.0, above=0, help="factor of every intensity")

        def apply(self, image):
            return image * self.gain

    try:
        code, out, _ = run_cli(["params", "--list"])
        assert code == 0
        assert "  toy: A toy pre-processor: the images times a gain." in out
        assert "preprocess.gain  traced  a number > 0, default 2: factor of every intensity" in out
        params = _params_json(run_cli, "--set", "preprocess=toy", "--set", "preprocess.gain=3")
        assert isinstance(params.preprocess, Toy) and params.preprocess.gain == 3.0
        code, _, err = run_cli(["params", "--set", "preprocess.gain=0"])
        assert code == 2 and "stage preprocess is None" in err
        assert "toy" in main_parser_help(["match", "--help"])
    finally:
        unregister("preprocess", "toy")


def main_parser_help(argv) -> str:
    """The help text of ``sswjax ARGV`` (with ``--help``)."""
    text = io.StringIO()
    with contextlib.redirect_stdout(text), pytest.raises(SystemExit):
        main(argv)
    return text.getvalue()


def test_match_help_points_to_the_catalogue():
    text = " ".join(main_parser_help(["match", "--help"]).split())
    assert "sswjax params --list" in text and "--strip-rows N" in text
    for preset in sswjax.PRESETS:
        assert f"{preset}:" in text


# ----------------------------------------------------------------------------- the execution plan


@pytest.fixture()
def recorded_match(monkeypatch):
    """``sswjax match``'s matcher replaced by a recorder of its keyword arguments."""
    calls = []

    def match(left, right, ndisp, **kwargs):
        calls.append(kwargs)
        return np.zeros(left.shape[:2], np.float32)

    monkeypatch.setattr(cli_match, "match", match)
    return calls


def test_the_plan_options_reach_the_call(pair, tmp_path, run_cli, recorded_match):
    argv = ["match", pair / "im0.png", pair / "im1.png", "--ndisp", NDISP, "-o",
            tmp_path / "d.pfm", "--set", "segments=none", "--set", "aggregation=box"]
    assert run_cli(argv + ["--strip-rows", 20, "--strip-overlap", 8, "--disparity-chunk", 0]
                   )[0] == 0
    plan = recorded_match[-1]["plan"]
    assert (plan.strip_rows, plan.strip_overlap, plan.disparity_chunk) == (20, 8, 0)
    assert recorded_match[-1]["params"].segments is None
    code, _, err = run_cli(argv + ["--strip-rows", "-1"])
    assert code == 2 and "argument --strip-rows: must be an integer >= 0, got '-1'" in err


def test_strips_from_the_command_line_match_as_the_api(pair, tmp_path, run_cli, tiny):
    out = tmp_path / "d.pfm"
    code, _, err = run_cli(["match", pair / "im0.png", pair / "im1.png", "--ndisp", NDISP,
                            "-o", out, *tiny.args, "--strip-rows", 16, "--strip-overlap", 8])
    assert code == 0, err
    expected = sswjax.match(read_image(pair / "im0.png"), read_image(pair / "im1.png"), NDISP,
                            params=tiny.params,
                            plan=sswjax.ExecutionPlan(strip_rows=16, strip_overlap=8))
    np.testing.assert_array_equal(read_pfm(out), expected)


def test_memory_guard_chooses_strips_or_names_the_options(monkeypatch, capsys):
    # A model in which a plan costs 1 MB per row of its strips (the whole image: 10 000 rows).
    def model(height, width, ndisp, *, plan=None, **_):
        return ((plan.strip_rows if plan is not None and plan.strip_rows else 10**4)
                * 1_000_000)

    monkeypatch.setattr(memory, "estimate_peak_bytes", model)
    monkeypatch.setattr(guard, "estimate_peak_bytes", model)
    monkeypatch.setattr(memory, "available_bytes", lambda: None)
    params, whole = sswjax.Params(), sswjax.ExecutionPlan()
    fitted = guard.guard_memory([(200, 300, 3)], 16, params=params, plan=whole, limit_gb=0.1)
    assert fitted == whole._replace(strip_rows=96)  # the tallest strips under 0.1 GB
    assert capsys.readouterr().err == ("sswjax: note: matching in strips of 96 rows to fit in "
                                       "memory (about 0.10 GB)\n")
    with pytest.raises(MemoryEstimateError) as error:  # the user's strips are too tall
        guard.guard_memory([(200, 300, 3)], 16, params=params,
                           plan=whole._replace(strip_rows=128), limit_gb=0.1)
    assert str(error.value) == ("a 300x200 pair with ndisp 16 needs about 0.13 GB, more than "
                                "the limit (0.10 GB): match in strips with --strip-rows 96 "
                                "(about 0.10 GB), or a smaller ndisp or image")
    with pytest.raises(MemoryEstimateError, match=r"even strips of 16 rows do not fit\), or a "
                                                  r"larger --max-memory$"):
        guard.guard_memory([(200, 300, 3)], 16, params=params, plan=whole, limit_gb=0.01)
