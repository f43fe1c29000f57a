"""Tests for sswjax.config.legacy: the flat names of before the per-stage configuration."""

import pytest

from sswjax import ConfigError, Params, preset
from sswjax.config import PRESETS, kinds
from sswjax.config.fields import default_of
from sswjax.config.legacy import (EXECUTION_DEFAULTS, FLAT_DEFAULTS, NEWER_OPTIONS, NEWER_SLOTS,
                                  from_flat, old_names, to_flat)

# The presets as the flat registry wrote them (changes from Params()), before the nesting.
_OCCLUSIONS = {"uniqueness_gap": 2, "uniqueness_radius": 2, "aggregated_lr_gap": 2,
               "fill_band_fit": 15}
_SGM = {"optimizer": "sgm", "sgm_paths": 4, "sgm_p1": 0.12, "sgm_p2": 0.8, "n_segments": 0,
        "fill_radius": 7, "fill_median": "separable", "fill": "left-band", "sgm_dtype": "uint8",
        **_OCCLUSIONS}
_ACCURATE = {**_SGM, "aggregation_iterations": 1, "fill_radius": 9, "fill": "vote",
             "sgm_p1": 0.35, "sgm_p2": 2.4}
OLD_PRESETS = {
    "paper": {},
    "accurate": _ACCURATE,
    # fast took accurate's side-window pass and penalties after the nesting (2026-12-05) and a
    # 7 x 7 fill median (2026-12-06); the flat names write them as they would have then
    "fast": {**_SGM, "coarse_levels": 1, "aggregation_iterations": 1, "sgm_p1": 0.2,
             "sgm_p2": 1.15, "fill_radius": 3},
    "finest": {**_ACCURATE, "aggregation_iterations": 2, "fill": "wmedian", "sgm_paths": 8,
               "sgm_p1": 0.05, "sgm_p2": 0.8},
}


def test_the_old_names_are_the_53_fields():
    assert len(FLAT_DEFAULTS) + len(EXECUTION_DEFAULTS) == 53
    assert old_names() == set(FLAT_DEFAULTS) | set(EXECUTION_DEFAULTS)


@pytest.mark.parametrize("name", list(OLD_PRESETS))
def test_the_old_presets_are_the_new_ones(name):
    # The presets as they were before the stages the flat names never had (NEWER_SLOTS: the
    # band, the smoothing), which a flat file leaves off, and before the options it never had
    # (NEWER_OPTIONS: the sub-pixel fit, the coarse map's refit), which it leaves at their
    # defaults.
    current = preset(name).replace(**{slot: None for slot in NEWER_SLOTS})
    current = current.replace(**{slot: {field: default_of(getattr(current, slot), field)}
                                 for slot, field in NEWER_OPTIONS
                                 if getattr(current, slot) is not None})
    reading = from_flat(OLD_PRESETS[name])
    assert Params(**reading.slots) == current
    slots = dict(current.stages())
    for slot in NEWER_SLOTS:
        del slots[slot]
    assert to_flat(slots) == {
        **FLAT_DEFAULTS, **{k: v for k, v in OLD_PRESETS[name].items()
                            if (name, k) not in {("finest", "fill_radius"),
                                                 ("finest", "fill_median")}}}
    # finest inherited accurate's fill median, which its weighted-median fill never used
    assert set(reading.unused) == ({"fill_radius", "fill_median"} if name == "finest" else set())
    # balanced came with the band, after the flat names: it has no flat form
    assert set(PRESETS) - {"balanced"} == set(OLD_PRESETS)


def test_a_change_by_flat_names_keeps_the_newer_options():
    accurate = preset("accurate")
    assert accurate.selection.fit == "equiangular"
    changed = accurate.replace(lr_check=False, sgm_p1=0.3)
    assert changed.selection.fit == "equiangular" and changed.checks is None
    assert changed.optimizer.p1 == pytest.approx(0.3)
    assert Params().replace(subpixel=False).selection.fit == "parabola"
    assert preset("fast").replace(sgm_p1=0.3).coarse.refit_radius == 2
    # the flat form leaves them out, whatever they are
    slots = dict(accurate.stages())
    for slot in NEWER_SLOTS:
        del slots[slot]
    assert to_flat(slots)["subpixel"] is True and "fit" not in to_flat(slots)


def test_switches_choose_the_stages():
    slots = from_flat({"lr_check": False, "refine_radius": 0, "n_segments": 0,
                       "optimizer": "sgm-half", "preprocess": "lcn"}).slots
    assert slots["checks"] is slots["fill"] is slots["refinement"] is slots["segments"] is None
    assert slots["optimizer"].kind == "sgm-half" and slots["preprocess"].kind == "lcn"
    # superpixels only where a stage uses them, as the flat code computed them
    assert from_flat({"aggregation": "box"}).slots["segments"] is None
    assert from_flat({"aggregation": "box", "optimizer": "sgm"}).slots["segments"] is not None
    # the guided filter kept its own radius, whatever aggregation_radius said
    assert from_flat({"aggregation": "gf", "aggregation_radius": 3}).slots["aggregation"].radius == 9
    coarse = from_flat({"coarse_levels": 2, "upsample_radius": 2, "refine_iterations": 3}).slots
    assert (coarse["coarse"].levels, coarse["coarse"].median_radius,
            coarse["coarse"].median_iterations, coarse["refinement"].iterations) == (2, 2, 3, 3)


def test_unused_options_are_listed_and_bad_values_refused():
    reading = from_flat({"fill_band_fit": 15, "sgm_p2": 1.0, "uniqueness_radius": 2})
    assert set(reading.unused) == {"fill_band_fit", "sgm_p2"}  # radius 2 is the default
    assert "acts only with fill 'left-band', 'vote' or 'wmedian'" in reading.unused["fill_band_fit"]
    with pytest.raises(ConfigError, match="parameter fill_source must be one of 'filled', 'valid'"):
        from_flat({"fill_source": "all"})  # unused here, and refused all the same
    with pytest.raises(ConfigError, match="unknown parameter 'radius'"):
        from_flat({"radius": 3})
    with pytest.raises(ConfigError, match="parameter fill must be one of"):
        from_flat({"fill": "nope"})
    assert from_flat({"strip_rows": 64, "disparity_chunk": 0}).execution == {
        "strip_rows": 64, "disparity_chunk": 0}


def test_to_flat_refuses_what_the_flat_names_cannot_say():
    with pytest.raises(ConfigError, match="has no flat name"):
        to_flat(dict(Params().replace(aggregation=kinds("aggregation")["gf"](radius=5)).stages()))
