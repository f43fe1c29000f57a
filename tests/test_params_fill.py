"""``--params FILE`` fills what the file leaves out from ``--preset`` (default: the default
preset), in every command that takes it, and ``sswjax.load_params`` from ``base=``.

The files written by :func:`sswjax.save_params` (every stage) keep their meaning, those of an
earlier version too (``tuning/params/searched.json``, written before the alignment, the band
and the equiangular fit); the old flat files are refused in one line that names their converter
(``sswjax params --upgrade``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import sswjax
from sswjax.cli.app import build_parser
from sswjax.config import DEFAULT_PRESET, Params, default_params, load_params, params_from_dict
from sswjax.evaluation import methods

ROOT = Path(__file__).resolve().parents[1]
PARTIAL = {"optimizer": {"p2": 1.3}}


def _write(path: Path, data) -> Path:
    path.write_text(json.dumps(data))
    return path


def _printed(run_cli, *args) -> dict:
    """What ``sswjax params ARGS`` prints, without its provenance."""
    code, out, err = run_cli(["params", *args])
    assert code == 0, err
    data = json.loads(out)
    data.pop("provenance")
    return data


def test_an_empty_file_is_the_default_preset(tmp_path, run_cli):
    empty = _write(tmp_path / "empty.json", {})
    assert load_params(empty) == default_params() == sswjax.preset(DEFAULT_PRESET)
    assert params_from_dict({}) == default_params()
    assert _printed(run_cli, "--params", empty) == _printed(run_cli)


def test_a_partial_file_fills_its_stages_from_the_default_preset(tmp_path, run_cli):
    path = _write(tmp_path / "p2.json", PARTIAL)
    expected = default_params().replace(**{"optimizer.p2": 1.3})
    assert load_params(path) == expected
    assert expected.alignment is not None and expected.smoothing is not None  # not the paper's
    assert _printed(run_cli, "--params", path) == _printed(run_cli, "--set", "optimizer.p2=1.3")


@pytest.mark.parametrize("name", ["fast", "paper"])
def test_a_partial_file_fills_from_the_preset_given_with_it(tmp_path, run_cli, name):
    data = {"optimizer": {"kind": "sgm", "p2": 1.3}}  # paper's optimizer is None
    path = _write(tmp_path / "p2.json", data)
    expected = sswjax.preset(name).replace(**data)
    assert load_params(path, base=name) == expected
    assert params_from_dict(data, base=name) == expected
    assert _printed(run_cli, "--preset", name, "--params", path) == \
        _printed(run_cli, "--preset", name, "--set", "optimizer={\"kind\": \"sgm\", \"p2\": 1.3}")


def test_every_command_with_params_takes_a_preset_beside_it(tmp_path):
    path = _write(tmp_path / "p2.json", PARTIAL)
    parser = build_parser()
    for argv in (["match", "l.png", "r.png", "-o", "d.pfm"],
                 ["evaluate"], ["search", "--data", "D", "-o", "s.json"], ["warmup", "--ndisp", "8"],
                 ["demo"], ["params"]):
        args = parser.parse_args([*argv, "--preset", "fast", "--params", str(path)])
        assert (args.preset, args.params) == ("fast", path), argv


def test_the_help_of_params_says_what_fills_the_rest(capsys):
    parser = build_parser()
    for command in ("match", "evaluate", "search", "warmup", "demo", "params"):
        with pytest.raises(SystemExit):
            parser.parse_args([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        start = text.rindex("--params FILE")  # its entry, after the usage
        assert f"what the file leaves out comes from --preset (default: {DEFAULT_PRESET})" in \
            text[start:start + 400], command


@pytest.fixture()
def constant_method(monkeypatch):
    """A method "constant" without JAX: disparity 3 everywhere (evaluate's parameters are
    only recorded then, in the run's record)."""
    monkeypatch.setitem(methods.PEERS, "constant", methods.Peer(
        lambda left, right, ndisp: np.full(left.shape[:2], 3, np.float32), "a stand-in"))


def test_evaluate_fills_a_partial_file_from_its_preset(tmp_path, run_cli, middeval3,
                                                       constant_method):
    root = middeval3(tmp_path / "MiddEval3")
    path = _write(tmp_path / "p2.json", PARTIAL)
    for extra, expected in (([], default_params()), (["--preset", "fast"], sswjax.preset("fast"))):
        out = tmp_path / f"out{len(extra)}"
        code, _, err = run_cli(["evaluate", "--data", root, "--methods", "constant",
                                "--params", path, "-o", out, *extra])
        assert code == 0, err
        record = json.loads((out / ".sswjax-run.json").read_text())
        assert record["settings"]["params"] == \
            expected.replace(**{"optimizer.p2": 1.3}).to_dict()


def test_a_file_naming_another_preset_than_the_option_is_refused(tmp_path, run_cli):
    path = _write(tmp_path / "fast.json", {"preset": "fast", **PARTIAL})
    assert load_params(path) == sswjax.preset("fast").replace(**{"optimizer.p2": 1.3})
    assert load_params(path, base="fast") == load_params(path)
    code, out, err = run_cli(["params", "--preset", "balanced", "--params", path])
    assert (code, out) == (2, "")
    assert err == (f"sswjax: error: {path}: the file starts from the preset 'fast', not "
                   "'balanced': drop --preset or the file's \"preset\"\n")
    with pytest.raises(ValueError, match="starts from the preset 'fast', not 'balanced'"):
        load_params(path, base="balanced")
    with pytest.raises(ValueError, match="unknown preset 'nope'"):
        load_params(path, base="nope")


def test_complete_files_keep_their_meaning_whatever_the_preset(tmp_path, run_cli):
    for name in sswjax.PRESETS:
        path = tmp_path / f"{name}.json"
        sswjax.save_params(path, sswjax.preset(name))
        for base in sswjax.PRESETS:
            assert load_params(path, base=base) == sswjax.preset(name)
    # a file of an earlier version lists every stage of then: those added since stay off and
    # the options added since at their defaults, as it was written (the paper's Params())
    searched = ROOT / "tuning" / "params" / "searched.json"
    data = json.loads(searched.read_text())
    assert "alignment" not in data and "fit" not in data["selection"]
    params = load_params(searched)
    assert params.alignment is None and params.band is None
    assert params.selection == Params().selection
    assert params == params_from_dict({**data, "preset": "paper"})
    assert load_params(searched, base="fast") == params


def test_old_flat_files_are_refused_naming_the_converter(tmp_path, run_cli):
    path = _write(tmp_path / "flat.json", {"fill_radius": 3})
    for extra in ([], ["--preset", "fast"]):
        code, out, err = run_cli(["params", *extra, "--params", path])
        assert (code, out) == (2, "")
        assert err == (f"sswjax: error: {path}: parameters in the old flat names "
                       f"('fill_radius'): convert the file with sswjax params --upgrade {path} "
                       "-o NEW.json\n")
    new = tmp_path / "new.json"
    assert run_cli(["params", "--upgrade", path, "-o", new])[0] == 0
    assert load_params(new) == Params().replace(**{"fill.median_radius": 3})  # the paper's
