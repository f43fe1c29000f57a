"""The registry of interchangeable parts: every name elsewhere derives from it."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sswjax
from sswjax import registry
from sswjax.cli import build_parser
from sswjax.evaluation.methods import make_method
from sswjax.params import params_from_dict
from sswjax.stages.aggregation import SegmentTerm


@pytest.mark.parametrize("name", sorted(registry.AGGREGATORS))
def test_every_aggregator_takes_the_common_call(name):
    rng = np.random.default_rng(0)
    cost = jnp.asarray(rng.random((4, 10, 12), dtype=np.float32))
    guide = jnp.asarray(rng.random((10, 12, 3), dtype=np.float32))
    segments = SegmentTerm(jnp.zeros((10, 12), jnp.int32), 1, 0.5)
    entry = registry.AGGREGATORS[name]
    run = jax.jit(lambda c, g: entry.fn(c, g, radius=2, iterations=1, window_selection="slice",
                                        segments=segments))
    out = run(cost, guide)
    assert out.shape == cost.shape and out.dtype == jnp.float32
    assert bool(jnp.isfinite(out).all())
    assert entry.summary and "\n" not in entry.summary


@pytest.mark.parametrize("name", sorted(registry.AGGREGATORS))
def test_each_aggregator_is_a_valid_parameter_and_a_method(name):
    assert params_from_dict({"aggregation": name}).static.aggregation == name
    assert name in registry.method_names()
    method = make_method(name)
    rng = np.random.default_rng(1)
    right = rng.random((24, 40, 3), dtype=np.float32)
    left = np.roll(right, 3, axis=1)
    disparity = method(left, right, 8)
    assert disparity.shape == (24, 40)


def test_parameter_validation_lists_the_registry():
    with pytest.raises(ValueError, match="aggregation must be one of") as error:
        params_from_dict({"aggregation": "nope"})
    for name in registry.AGGREGATORS:
        assert repr(name) in str(error.value)


def test_an_entry_added_is_usable_everywhere(monkeypatch):
    # One entry is all it takes: validation, the pipeline and the method names follow.
    box = registry.AGGREGATORS["box"]
    monkeypatch.setitem(registry.AGGREGATORS, "box3", box._replace(radius=3, summary="box r 3"))
    params = params_from_dict({"aggregation": "box3"})
    assert "box3" in registry.method_names()
    rng = np.random.default_rng(2)
    right = rng.random((24, 40), dtype=np.float32)
    left = np.roll(right, 2, axis=1)
    ours = sswjax.match(left, right, 8, params=params)
    same = sswjax.match(left, right, 8, params=params.replace(aggregation="box", aggregation_radius=3))
    np.testing.assert_array_equal(ours, same)


def test_cli_help_lists_every_method():
    evaluate = build_parser()._subparsers._group_actions[0].choices["evaluate"]
    text = evaluate.format_help()
    for name in registry.method_names():
        assert name in text


def test_variant_changes():
    assert registry.variant_changes("ssw") == {}
    assert registry.variant_changes("mf") == {"aggregation": "mf"}
    assert registry.variant_changes("ssw-noseg") == {"n_segments": 0}
    with pytest.raises(KeyError):
        registry.variant_changes("sgbm")


def test_presets():
    assert set(registry.PRESETS) >= {"paper", "accurate"}
    assert sswjax.preset("paper") == sswjax.Params().replace(**registry.PRESETS["paper"].changes)
    for name in registry.PRESETS:
        sswjax.params.check_params(sswjax.preset(name))
    with pytest.raises(ValueError, match="unknown preset 'nope'; choose from paper"):
        sswjax.preset("nope")


# Every non-default entry alone, and all of them together (the defaults run everywhere else).
STAGE_CASES = [(fill, "none", "none") for fill in registry.FILLS if fill != "background"] + [
    ("background", opt, "none") for opt in registry.OPTIMIZERS if opt != "none"] + [
    ("background", "none", pre) for pre in registry.PREPROCESSORS if pre != "none"] + [
    ("plane", "sgm", "lcn")]


@pytest.mark.parametrize("name, optimizer, preprocess", STAGE_CASES)
def test_every_stage_entry_runs_in_the_pipeline(name, optimizer, preprocess):
    rng = np.random.default_rng(5)
    right = rng.random((32, 48, 3), dtype=np.float32)
    left = np.roll(right, 3, axis=1)
    params = sswjax.Params().replace(fill=name, optimizer=optimizer, preprocess=preprocess,
                                     n_segments=24)
    disparity = sswjax.match(left, right, 8, params=params)
    assert disparity.shape == (32, 48) and np.isfinite(disparity).all()
    assert np.median(disparity[:, 10:]) == pytest.approx(3, abs=0.01)
