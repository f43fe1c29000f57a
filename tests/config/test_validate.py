"""Tests for sswjax.config.validate: checks from the options' declarations, rules across stages."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax import ConfigError, Params, check_params, preset
from sswjax.config import PRESETS, SLOTS, kinds
from sswjax.config.fields import option_fields


@pytest.mark.parametrize("name", list(PRESETS))
def test_every_preset_is_valid(name):
    assert check_params(preset(name)) is preset(name)


def test_every_option_is_declared():
    for slot in SLOTS:
        for kind, cls in kinds(slot).items():
            options = option_fields(cls)
            assert cls.summary() and "\n" not in cls.summary(), (slot, kind)
            for option, spec in options:
                assert spec.help and "\n" not in spec.help, (slot, kind, option)
                assert spec.static or spec.kind is float, (slot, kind, option)
                assert isinstance(cls(), cls)


@pytest.mark.parametrize("changes, message", [
    ({"aggregation.radius": 0}, "aggregation.radius must be an integer in [1, 50], got 0"),
    ({"aggregation.radius": 2.5}, "aggregation.radius must be an integer"),
    ({"cost.census_height": 8}, "cost.census_height must be an odd integer in [1, 15], got 8"),
    ({"selection.subpixel": 1}, "selection.subpixel must be true or false, got 1"),
    ({"aggregation.window_selection": "box"}, "must be one of 'slice', 'guide', got 'box'"),
    ({"cost.tad_truncation": 0.0}, "cost.tad_truncation must be a number > 0, got 0.0"),
    ({"cost.census_weight": "0.5"}, "cost.census_weight must be a number >= 0, got '0.5'"),
    ({"cost.census_weight": True}, "cost.census_weight must be a number >= 0, got True"),
    ({"cost.tad_weight": 1e308}, "cost.tad_weight must be finite in float32"),
    ({"checks.tolerance": float("nan")}, "checks.tolerance must be finite in float32"),
    ({"cost.census_weight": np.ones(2)}, "cost.census_weight must be a scalar, got shape (2,)"),
])
def test_bad_values_name_the_option(changes, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")
                       .replace("[", r"\[").replace("]", r"\]")):
        check_params(Params().replace(**changes))


def test_numpy_and_jax_scalars_are_numbers():
    check_params(Params().replace(**{"cost.census_weight": np.float32(0.5),
                                     "checks.tolerance": jnp.float32(1.0)}))


@pytest.mark.parametrize("params, message", [
    (Params().replace(checks=None), "with checks None, set fill to None too"),
    (Params().replace(fill=None), "stage fill is None, but the checks reject pixels"),
    (Params().replace(aggregation={"kind": "box"}), "no stage uses the superpixels"),
    (preset("accurate").replace(fill={"kind": "plane"}), "fill 'plane' fits a plane per "
                                                          "superpixel: it needs segments"),
    (preset("accurate").replace(**{"aggregation.segment_weight": 0.3}),
     "aggregation.segment_weight acts only with superpixels"),
    (preset("accurate").replace(**{"optimizer.segment_factor": 0.5}),
     "optimizer.segment_factor acts only with superpixels"),
    (preset("balanced").replace(**{"band.segment_range": True}),
     "band.segment_range takes each band's range over its superpixel: it needs segments"),
    (Params().replace(**{"checks.aggregated_gap": 2}), "checks.aggregated_gap needs an optimizer"),
    (Params().replace(**{"checks.uniqueness_radius": 3}), "uniqueness_radius acts only with"),
    (Params().replace(**{"fill.median_radius": 7}), "fill.median_radius must be in [0, 5] with "
                                                    "fill.median 'square', got 7"),
    (preset("fast").replace(**{"coarse.median_radius": 0, "coarse.median_iterations": 3}),
     "coarse.median_iterations acts only with"),
    (Params().replace(**{"cost.census_height": 1, "cost.census_width": 1}),
     "a 1 x 1 census window compares no neighbour"),
    (Params().replace(**{"cost.tad_weight": 0.0, "cost.gradient_weight": 0.0,
                         "cost.census_weight": 0.0}), "are all 0: no pixel has a cost"),
])
def test_rules_across_stages(params, message):
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("]", r"\]")):
        check_params(params)


def test_check_params_refuses_other_types():
    with pytest.raises(TypeError, match="params must be a sswjax.Params"):
        check_params({"static": {}})
    with pytest.raises(ConfigError, match="stage fill takes one of the kinds"):
        check_params(Params(fill=kinds("optimizer")["sgm"]()))


def test_traced_values_are_not_inspected():
    @jax.jit
    def checked(params):
        check_params(params)
        return params.cost.census_weight

    assert float(checked(Params())) == pytest.approx(0.8)
