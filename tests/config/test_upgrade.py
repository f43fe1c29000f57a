"""Tests for sswjax.cli.upgrade: the one converter of the old flat parameter names."""

import json

import pytest

from sswjax import ConfigError, Params, load_params, preset
from sswjax.cli.upgrade import FLAT_DEFAULTS, OLD_NAMES, upgrade, upgrade_file

# Each old name -> (a flat set giving it a value other than its default, with the switches it
# needs; the nested path it converts to; the value there). None as the path: the stage off.
CONVERSIONS = {
    "census_height": ({"census_height": 5}, "cost.census_height", 5),
    "census_width": ({"census_width": 7}, "cost.census_width", 7),
    "tad_weight": ({"tad_weight": 0.1}, "cost.tad_weight", 0.1),
    "gradient_weight": ({"gradient_weight": 0.2}, "cost.gradient_weight", 0.2),
    "census_weight": ({"census_weight": 0.7}, "cost.census_weight", 0.7),
    "tad_truncation": ({"tad_truncation": 0.03}, "cost.tad_truncation", 0.03),
    "gradient_truncation": ({"gradient_truncation": 0.1}, "cost.gradient_truncation", 0.1),
    "preprocess": ({"preprocess": "lcn"}, "preprocess", "lcn"),
    "lcn_radius": ({"preprocess": "lcn", "lcn_radius": 5}, "preprocess.radius", 5),
    "lcn_eps": ({"preprocess": "lcn", "lcn_eps": 0.02}, "preprocess.eps", 0.02),
    "n_segments": ({"n_segments": 500}, "segments.n_segments", 500),
    "slic_iterations": ({"slic_iterations": 4}, "segments.iterations", 4),
    "slic_compactness": ({"slic_compactness": 20.0}, "segments.compactness", 20.0),
    "aggregation": ({"aggregation": "box", "n_segments": 0}, "aggregation", "box"),
    "aggregation_radius": ({"aggregation_radius": 3}, "aggregation.radius", 3),
    "aggregation_iterations": ({"aggregation_iterations": 1}, "aggregation.iterations", 1),
    "window_selection": ({"window_selection": "guide"}, "aggregation.window_selection", "guide"),
    "segment_weight": ({"segment_weight": 0.3}, "aggregation.segment_weight", 0.3),
    "optimizer": ({"optimizer": "sgm"}, "optimizer", "sgm"),
    "sgm_paths": ({"optimizer": "sgm", "sgm_paths": 4}, "optimizer.paths", 4),
    "sgm_dtype": ({"optimizer": "sgm", "sgm_dtype": "uint8"}, "optimizer.dtype", "uint8"),
    "sgm_p1": ({"optimizer": "sgm", "sgm_p1": 0.2}, "optimizer.p1", 0.2),
    "sgm_p2": ({"optimizer": "sgm", "sgm_p2": 1.2}, "optimizer.p2", 1.2),
    "sgm_sigma": ({"optimizer": "sgm", "sgm_sigma": 0.1}, "optimizer.sigma", 0.1),
    "sgm_segment_factor": ({"optimizer": "sgm", "sgm_segment_factor": 0.5},
                           "optimizer.segment_factor", 0.5),
    "sgm_detail_weight": ({"optimizer": "sgm-half", "sgm_detail_weight": 0.5},
                          "optimizer.detail_weight", 0.5),
    "subpixel": ({"subpixel": False}, "selection.subpixel", False),
    "lr_check": ({"lr_check": False}, "checks", None),
    "lr_tolerance": ({"lr_tolerance": 1.0}, "checks.tolerance", 1.0),
    "uniqueness_gap": ({"uniqueness_gap": 2}, "checks.uniqueness_gap", 2),
    "uniqueness_radius": ({"uniqueness_gap": 2, "uniqueness_radius": 3},
                          "checks.uniqueness_radius", 3),
    "aggregated_lr_gap": ({"optimizer": "sgm", "aggregated_lr_gap": 2},
                          "checks.aggregated_gap", 2),
    "fill": ({"fill": "vote"}, "fill", "vote"),
    "fill_radius": ({"fill_radius": 3}, "fill.median_radius", 3),
    "fill_median": ({"fill_median": "separable"}, "fill.median", "separable"),
    "fill_band_fit": ({"fill": "left-band", "fill_band_fit": 15}, "fill.band_fit", 15),
    "fill_weight_radius": ({"fill": "vote", "fill_weight_radius": 5}, "fill.radius", 5),
    "vote_step": ({"fill": "vote", "vote_step": 2}, "fill.step", 2),
    "vote_sigma": ({"fill": "vote", "vote_sigma": 0.3}, "fill.sigma", 0.3),
    "vote_tolerance": ({"fill": "vote", "vote_tolerance": 1.0}, "fill.tolerance", 1.0),
    "fill_eps": ({"fill": "wmedian", "fill_eps": 0.01}, "fill.eps", 0.01),
    "fill_quantile": ({"fill": "wmedian", "fill_quantile": 0.4}, "fill.quantile", 0.4),
    "fill_source": ({"fill": "wmedian", "fill_source": "valid"}, "fill.source", "valid"),
    "plane_min_support": ({"fill": "plane", "plane_min_support": 0.5}, "fill.min_support", 0.5),
    "plane_inlier_scale": ({"fill": "plane", "plane_inlier_scale": 2.0}, "fill.inlier_scale",
                           2.0),
    "refine_radius": ({"refine_radius": 3}, "refinement.radius", 3),
    "refine_iterations": ({"refine_iterations": 1}, "refinement.iterations", 1),
    "coarse_levels": ({"coarse_levels": 2}, "coarse.levels", 2),
    "upsample_radius": ({"coarse_levels": 1, "upsample_radius": 2}, "coarse.median_radius", 2),
    "upsample_jump": ({"coarse_levels": 1, "upsample_jump": 2.0}, "coarse.jump", 2.0),
    # how a call ran: no parameter, a note
    "strip_rows": ({"strip_rows": 64}, None, None),
    "strip_overlap": ({"strip_overlap": 16}, None, None),
    "disparity_chunk": ({"disparity_chunk": 0}, None, None),
}


def _at(params: Params, path: str):
    slot, _, option = path.partition(".")
    config = getattr(params, slot)
    if not option:
        return None if config is None else config.kind
    return getattr(config, option)


def test_the_table_has_the_53_old_names():
    assert len(OLD_NAMES) == 53 and set(CONVERSIONS) == OLD_NAMES


@pytest.mark.parametrize("name", sorted(CONVERSIONS))
def test_each_old_name_converts_to_its_nested_form(name):
    flat, path, expected = CONVERSIONS[name]
    params, notes = upgrade({"static": {k: v for k, v in flat.items()
                                        if not isinstance(v, float)},
                             "dynamic": {k: v for k, v in flat.items() if isinstance(v, float)}})
    if path is None:
        assert params == Params() and notes == [
            f"{name}={flat[name]!r} is how a call runs, not a parameter: pass "
            f"--{name.replace('_', '-')} {flat[name]} to sswjax match"]
        return
    assert _at(params, path) == expected and notes == []
    assert upgrade(flat)[0] == params  # the names at the top level read the same


def test_the_old_defaults_are_the_paper_method_and_decimal():
    assert upgrade({})[0] == Params()
    # a full dump of the old search's float32 values converts to the decimals of Params()
    dump = {name: value for name, value in FLAT_DEFAULTS.items()}
    dump.update(tad_weight=0.05000000074505806, segment_weight=0.5996789336204529)
    params, notes = upgrade(dump)
    assert params == Params() and notes == []


def test_the_old_presets_convert_to_the_current_ones_of_then():
    old_accurate = {"optimizer": "sgm", "sgm_paths": 4, "sgm_p1": 0.35, "sgm_p2": 2.4,
                    "n_segments": 0, "fill_radius": 9, "fill_median": "separable",
                    "fill": "vote", "sgm_dtype": "uint8", "uniqueness_gap": 2,
                    "uniqueness_radius": 2, "aggregated_lr_gap": 2, "fill_band_fit": 15,
                    "aggregation_iterations": 1}
    # the stages and options added since the flat names are off or at their defaults
    current = preset("accurate").replace(alignment=None, smoothing=None,
                                         **{"selection.fit": "parabola"})
    assert upgrade(old_accurate)[0] == current


def test_what_the_old_code_ignored_is_left_out_with_a_note():
    params, notes = upgrade({"fill": "wmedian", "fill_radius": 9, "optimizer": "none",
                             "sgm_p2": 1.0})
    assert params.fill.kind == "wmedian" and params.optimizer is None
    assert [note.split(" ")[0] for note in notes] == ["fill_radius=9", "sgm_p2=1.0"]
    assert "acts only with fill 'background'" in notes[0]
    # gf's radius was fixed: the old name did not reach it
    assert upgrade({"aggregation": "gf", "n_segments": 0, "aggregation_radius": 3}
                   )[0].aggregation.radius == 9
    coarse = upgrade({"coarse_levels": 2, "upsample_radius": 2, "refine_iterations": 3}
                     )[0].coarse
    assert (coarse.median_radius, coarse.median_iterations) == (2, 3)


@pytest.mark.parametrize("flat, message", [
    ({"radius": 3}, "unknown parameter 'radius'"),
    ({"fill": "nope"}, "parameter fill must be one of"),
    ({"static": {"sgm_p2": 1.0}}, "unknown static parameter 'sgm_p2'"),
    ({"fill_source": "all"}, "parameter fill_source must be one of"),  # unused, refused anyway
    ({"fill_radius": 20}, "parameter fill_radius must be"),
    ({"lr_check": 1}, "parameter lr_check must be true or false"),
])
def test_bad_flat_values_are_named_by_their_old_names(flat, message):
    with pytest.raises(ConfigError, match=message):
        upgrade(flat)


def test_the_command_converts_a_file_and_the_library_refuses_it(tmp_path, run_cli):
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"static": {"fill_radius": 3, "strip_rows": 64},
                               "dynamic": {"gradient_weight": 0.2},
                               "provenance": {"how": "by hand"}}))
    with pytest.raises(ValueError, match=r"old.json: parameters in the old flat names "
                                         r"\('static'\): convert the file with sswjax params "
                                         r"--upgrade .*old.json -o NEW.json"):
        load_params(old)
    new = tmp_path / "new.json"
    code, out, err = run_cli(["params", "--upgrade", str(old), "-o", str(new)])
    assert code == 0 and "strip_rows=64 is how a call runs" in err
    assert load_params(new) == Params().replace(**{"fill.median_radius": 3,
                                                   "cost.gradient_weight": 0.2})
    assert json.loads(new.read_text())["provenance"] == {"how": "by hand"}
    code, out, err = run_cli(["params", "--upgrade", str(old), "-o", str(new)])
    assert code == 2 and err.strip().endswith("exists: give --overwrite to replace it")
    assert run_cli(["params", "--upgrade", str(old), "-o", str(new), "--overwrite"])[0] == 0
    code, out, err = run_cli(["params", "--upgrade", str(new)])
    assert code == 2 and "not a file of the old flat names" in err
    code, out, err = run_cli(["match", "--params", str(old), "l.png", "r.png", "--ndisp", "4", "-o",
                              str(tmp_path / "d.pfm")])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--upgrade" in err


def test_upgrade_file_keeps_a_nested_document(tmp_path):
    old = tmp_path / "old.json"
    old.write_text('{"optimizer": "sgm", "sgm_p2": 1.5}')
    document, notes = upgrade_file(old)
    assert document["format"] == "sswjax-params/2" and document["optimizer"]["p2"] == 1.5
