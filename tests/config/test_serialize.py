"""Tests for sswjax.config.serialize: nested JSON, partial files, the old flat files refused."""

import json
import warnings
from pathlib import Path

import pytest

from sswjax import Params, load_params, preset, save_params
from sswjax.config import PRESETS, VoteFill, params_from_dict

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
    ({"bogus": {}}, "unknown parameter 'bogus'"),
    ({"bogus": 1}, "old flat names ('bogus')"),
    ({"fill": {"kind": "vote", "typo": 1}}, "fill 'vote' has no option 'typo'"),
    ({"fill": "vote", "optimizer": {"kind": "sgm"}}, "in the old flat names ('fill'): convert "
                                                     "the file with sswjax params --upgrade"),
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


@pytest.mark.parametrize("data", [
    {"static": {"fill_radius": 3}}, {"dynamic": {"gradient_weight": 0.2}}, {"fill_radius": 3},
    {"fill": "vote"}, {"sgm_p2": 1.0, "provenance": {}},
])
def test_the_flat_forms_are_refused_naming_the_converter(tmp_path, data):
    with pytest.raises(ValueError, match=r"old flat names \('.*'\): convert the file with sswjax "
                                         "params --upgrade OLD.json -o NEW.json"):
        params_from_dict(data)
    path = tmp_path / "old.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"old.json: parameters in the old flat names \('.*'\): "
                                         "convert the file with sswjax params --upgrade") as error:
        load_params(path)
    assert "\n" not in str(error.value)


def _stored_parameter_files():
    return sorted([*ROOT.glob("tuning/params/*.json"), *ROOT.glob("tuning/runs/**/params.json"),
                   *ROOT.glob("tuning/runs/**/tuned.json")])


def test_every_stored_parameter_file_loads():
    files = _stored_parameter_files()
    assert len(files) >= 10
    for path in files:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert isinstance(load_params(path), Params)
    assert load_params(ROOT / "tuning" / "params" / "tuned.json") == Params()


def test_load_params_errors(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_params(tmp_path / "missing.json")
    for name, text, message in [
        ("bad.json", "{not json", "bad.json"),
        ("nan.json", '{"cost": {"tad_truncation": NaN}}', "tad_truncation"),
        ("type.json", '{"selection": {"subpixel": "yes"}}', "subpixel"),
        ("list.json", "[1, 2]", "JSON object"),
        ("deep.json", "[" * 100_000 + "]" * 100_000, "nested too deeply"),
    ]:
        (tmp_path / name).write_text(text)
        with pytest.raises(ValueError, match=message) as error:
            load_params(tmp_path / name)
        assert "\n" not in str(error.value)
