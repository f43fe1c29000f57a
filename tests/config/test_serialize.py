"""Tests for sswjax.config.serialize: nested JSON, partial files, the old flat files."""

import json
import warnings
from pathlib import Path

import pytest

from sswjax import Params, load_params, preset, save_params
from sswjax.config import PRESETS, VoteFill, params_from_dict, read_params_file

ROOT = Path(__file__).parents[2]


@pytest.mark.parametrize("name", list(PRESETS))
def test_json_round_trip_of_every_preset(tmp_path, name):
    path = tmp_path / "params.json"
    save_params(path, preset(name), provenance={"dataset": "unit-test", "score": 1.5})
    data = json.loads(path.read_text())
    assert data["format"] == "sswjax-params/2" and data["provenance"]["score"] == 1.5
    loaded = load_params(path)
    assert loaded == preset(name)
    assert isinstance(loaded.aggregation.radius, int) and isinstance(loaded.selection.subpixel, bool)
    assert [f.name for f in tmp_path.iterdir()] == ["params.json"]  # no temporary file left


def test_a_partial_file_starts_from_its_preset():
    p = params_from_dict({"preset": "accurate", "optimizer": {"p2": 1.3}, "fill": {"radius": 5}})
    assert p == preset("accurate").replace(**{"optimizer.p2": 1.3, "fill.radius": 5})
    q = params_from_dict({"fill": {"kind": "vote", "step": 2}}, base="paper")
    assert q == Params().replace(fill=VoteFill(step=2))  # another kind: from its defaults
    assert params_from_dict({}, base="paper") == Params()
    # without a base: the default preset (accurate), whose fill is a vote already
    assert params_from_dict({}) == preset("accurate")
    assert params_from_dict({"fill": {"kind": "vote", "step": 2}}) == \
        preset("accurate").replace(**{"fill.step": 2})
    r = params_from_dict({"optimizer": {"kind": "sgm", "p2": 2}})  # JSON integer, traced: a float
    assert r.optimizer.p2 == 2.0 and isinstance(r.optimizer.p2, float)


@pytest.mark.parametrize("data, message", [
    ({"bogus": 1}, "unknown parameter 'bogus'"),
    ({"fill": {"kind": "vote", "typo": 1}}, "fill 'vote' has no option 'typo'"),
    ({"fill": "vote", "optimizer": {"kind": "sgm"}}, "mix the flat name 'fill'"),
    ({"format": "sswjax-params/9"}, "unknown parameter format"),
    ({"preset": "nope"}, "unknown preset 'nope'"),
    ({"optimizer": [1]}, "stage optimizer must be null or an object"),
    ({"aggregation": {"radius": 2.5}}, "parameter aggregation.radius must be an integer"),
    ({"cost": {"census_height": 8}}, "parameter cost.census_height must be an odd integer"),
    ({"checks": None}, "with checks None, set fill to None too"),
])
def test_bad_nested_files(data, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        params_from_dict(data)


def test_the_flat_forms_still_load():
    nested = params_from_dict({"static": {"fill_radius": 3}, "dynamic": {"gradient_weight": 0.2},
                               "comment": "x"})
    flat = params_from_dict({"fill_radius": 3, "gradient_weight": 0.2})
    assert nested == flat == Params().replace(fill_radius=3, gradient_weight=0.2)
    with pytest.warns(UserWarning, match="segment_weight acts only with aggregation 'ssw' and "
                      "superpixels"):
        zero = params_from_dict({"tad_weight": 0, "segment_weight": 0.0, "lr_tolerance": 0,
                                 "n_segments": 0})
    assert zero.segments is None and zero.cost.tad_weight == 0.0
    assert isinstance(zero.cost.tad_weight, float)


@pytest.mark.parametrize("data", [
    {"static": {"census_weight": 0.5}}, {"dynamic": {"typo_radius": 2}}, {"aggregation_radius": 2.5},
    {"aggregation_radius": True}, {"aggregation_radius": "3"}, {"aggregation_radius": 0},
    {"census_height": 8}, {"census_width": 17}, {"lr_check": "yes"}, {"subpixel": 1},
    {"window_selection": "box"}, {"census_weight": "0.5"}, {"census_weight": True},
    {"census_weight": None}, {"tad_truncation": float("nan")}, {"tad_truncation": float("inf")},
    {"tad_truncation": -0.1}, {"tad_truncation": 0}, {"gradient_truncation": 0.0},
    {"slic_compactness": 0.0}, {"census_weight": -1.0}, {"lr_tolerance": float("nan")},
])
def test_bad_flat_values_are_named_by_their_old_names(data):
    name = next(iter(data)) if "static" not in data and "dynamic" not in data else None
    with pytest.raises(ValueError, match=name or "parameter"):
        params_from_dict(data)


def _stored_parameter_files():
    return sorted([*ROOT.glob("tuning/params/*.json"), *ROOT.glob("tuning/runs/**/params.json"),
                   *ROOT.glob("tuning/runs/**/tuned.json")])


def test_every_stored_parameter_file_loads():
    files = _stored_parameter_files()
    assert len(files) >= 10
    for path in files:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no ignored option in them either
            params, execution = read_params_file(path)
        assert isinstance(params, Params) and set(execution) <= {"strip_rows", "strip_overlap",
                                                                 "disparity_chunk"}
    assert load_params(ROOT / "tuning" / "params" / "tuned.json") == Params()


def test_execution_options_of_old_files_come_back_apart(tmp_path):
    path = tmp_path / "old.json"
    path.write_text('{"static": {"strip_rows": 64, "n_segments": 8}}')
    params, execution = read_params_file(path)
    assert execution == {"strip_rows": 64} and params.segments.n_segments == 8
    with pytest.warns(UserWarning, match="strip_rows=64 in the parameters is how a call runs"):
        load_params(path)


def test_an_ignored_old_option_is_a_warning_not_an_error(tmp_path):
    path = tmp_path / "old.json"
    path.write_text('{"fill": "wmedian", "fill_radius": 9}')
    with pytest.warns(UserWarning, match="fill_radius acts only with fill"):
        assert load_params(path).fill.kind == "wmedian"


def test_load_params_errors(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_params(tmp_path / "missing.json")
    for name, text, message in [
        ("bad.json", "{not json", "bad.json"),
        ("nan.json", '{"dynamic": {"tad_truncation": NaN}}', "tad_truncation"),
        ("type.json", '{"static": {"lr_check": "yes"}}', "lr_check"),
        ("list.json", "[1, 2]", "JSON object"),
        ("deep.json", "[" * 100_000 + "]" * 100_000, "nested too deeply"),
    ]:
        (tmp_path / name).write_text(text)
        with pytest.raises(ValueError, match=message) as error:
            load_params(tmp_path / name)
        assert "\n" not in str(error.value)
