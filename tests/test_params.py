"""Tests for sswjax.params: replace, validation, JSON round trip, pytree behaviour under jit/grad."""

import json
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax import DynamicParams, Params, StaticParams, load_params, save_params
from sswjax.params import params_from_dict


def test_defaults():
    p = Params()
    assert p.static == StaticParams()
    assert p.dynamic == DynamicParams()
    assert p.static.aggregation_radius == 4
    assert (p.static.census_height, p.static.census_width) == (7, 9)


def test_defaults_are_tuned_json():
    """``Params()`` is ``tuning/params/tuned.json`` exactly: every field, no rounding."""
    tuned = Path(__file__).parents[1] / "tuning" / "params" / "tuned.json"
    data = json.loads(tuned.read_text())
    defaults = Params()
    # Fields added after the search (the optional stages) are absent from the file and keep
    # the values that leave those stages off or neutral.
    assert set(data["static"]) <= set(StaticParams._fields)
    assert set(data["dynamic"]) <= set(DynamicParams._fields)
    assert defaults.static.optimizer == "none" and defaults.static.fill == "background"
    for name, value in data["static"].items():
        default = getattr(defaults.static, name)
        assert default == value and type(default) is type(value), (name, default, value)
    for name, value in data["dynamic"].items():
        assert getattr(defaults.dynamic, name) == value, (name, getattr(defaults.dynamic, name), value)
    assert load_params(tuned) == defaults


def test_replace_static_and_dynamic():
    p = Params()
    q = p.replace(census_weight=0.5, aggregation_radius=6, lr_check=False)
    assert q.dynamic.census_weight == 0.5
    assert q.static.aggregation_radius == 6
    assert q.static.lr_check is False
    # everything else unchanged, and the original is not modified
    assert q.dynamic._replace(census_weight=p.dynamic.census_weight) == p.dynamic
    assert q.static._replace(aggregation_radius=4, lr_check=True) == p.static
    assert p == Params()
    with pytest.raises(dataclass_frozen_error()):
        p.static = StaticParams()  # type: ignore[misc]


def dataclass_frozen_error():
    import dataclasses

    return dataclasses.FrozenInstanceError


def test_replace_unknown_field():
    with pytest.raises(ValueError, match="unknown parameter.*no_such_thing"):
        Params().replace(no_such_thing=1)
    with pytest.raises(ValueError, match="unknown"):
        Params().replace(census_weight=0.1, radius=3)


def test_json_round_trip(tmp_path):
    p = Params().replace(
        census_weight=0.25,
        tad_truncation=0.07,
        lr_tolerance=0.0,
        aggregation_radius=3,
        window_selection="slice",
        subpixel=False,
        n_segments=0,
    )
    path = tmp_path / "params.json"
    save_params(path, p, provenance={"dataset": "unit-test", "score": 1.5})
    data = json.loads(path.read_text())
    assert set(data) == {"static", "dynamic", "provenance"}
    assert data["static"]["window_selection"] == "slice"
    assert data["static"]["subpixel"] is False
    loaded = load_params(path)
    assert loaded == p
    assert loaded.static == p.static
    assert isinstance(loaded.static.aggregation_radius, int)
    assert isinstance(loaded.static.subpixel, bool)
    # the defaults too, and without provenance
    save_params(path, Params())
    assert load_params(path) == Params()
    # the atomic write leaves no temporary file behind
    assert [f.name for f in tmp_path.iterdir()] == ["params.json"]


def test_params_from_dict_flat_and_nested():
    nested = params_from_dict({"static": {"fill_radius": 3}, "dynamic": {"gradient_weight": 0.2}, "comment": "x"})
    flat = params_from_dict({"fill_radius": 3, "gradient_weight": 0.2})
    assert nested == flat == Params().replace(fill_radius=3, gradient_weight=0.2)
    assert params_from_dict({}) == Params()


@pytest.mark.parametrize(
    "data",
    [
        {"bogus": 1},
        {"static": {"census_weight": 0.5}},  # a dynamic field in the static section
        {"dynamic": {"aggregation_radius": 2}},
        {"static": {"typo_radius": 2}},
    ],
)
def test_params_from_dict_rejects_unknown_keys(data):
    with pytest.raises(ValueError, match="unknown"):
        params_from_dict(data)


@pytest.mark.parametrize(
    "data",
    [
        {"aggregation_radius": 2.5},
        {"aggregation_radius": True},
        {"aggregation_radius": "3"},
        {"aggregation_radius": 0},
        {"census_height": 8},  # even
        {"census_width": 17},  # too large
        {"lr_check": "yes"},
        {"subpixel": 1},
        {"window_selection": "box"},
        {"census_weight": "0.5"},
        {"census_weight": True},
        {"census_weight": None},
        {"tad_truncation": float("nan")},
        {"tad_truncation": float("inf")},
        {"tad_truncation": -0.1},
        {"tad_truncation": 0},
        {"gradient_truncation": 0.0},
        {"slic_compactness": 0.0},
        {"census_weight": -1.0},
        {"lr_tolerance": float("nan")},
    ],
)
def test_params_from_dict_rejects_bad_values(data):
    with pytest.raises(ValueError, match=next(iter(data))):
        params_from_dict(data)


def test_zero_weights_and_tolerance_are_allowed():
    p = params_from_dict({"tad_weight": 0, "segment_weight": 0.0, "lr_tolerance": 0, "n_segments": 0})
    assert p.dynamic.tad_weight == 0.0 and isinstance(p.dynamic.tad_weight, float)
    assert p.static.n_segments == 0


def test_load_params_errors(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_params(tmp_path / "missing.json")
    bad_json = tmp_path / "bad.json"
    bad_json.write_text("{not json")
    with pytest.raises(ValueError, match="bad.json"):
        load_params(bad_json)
    nan_file = tmp_path / "nan.json"
    nan_file.write_text('{"dynamic": {"tad_truncation": NaN}}')
    with pytest.raises(ValueError, match="tad_truncation"):
        load_params(nan_file)
    wrong_type = tmp_path / "type.json"
    wrong_type.write_text('{"static": {"lr_check": "yes"}}')
    with pytest.raises(ValueError, match="lr_check"):
        load_params(wrong_type)
    not_object = tmp_path / "list.json"
    not_object.write_text("[1, 2]")
    with pytest.raises(ValueError):
        load_params(not_object)


# ---------------------------------------------------------------------------------------------
# pytree behaviour


def test_tree_leaves_are_the_dynamic_values():
    p = Params().replace(tad_weight=0.11, lr_tolerance=2.5)
    leaves = jax.tree_util.tree_leaves(p)
    count = len(DynamicParams._fields)
    assert len(leaves) == count
    assert leaves == list(p.dynamic)
    # static fields live in the treedef: rebuild with new leaves keeps them
    treedef = jax.tree_util.tree_structure(p)
    rebuilt = jax.tree_util.tree_unflatten(treedef, [float(i) for i in range(count)])
    assert rebuilt.static == p.static
    assert list(rebuilt.dynamic) == [float(i) for i in range(count)]
    # a different static value gives a different treedef
    assert jax.tree_util.tree_structure(p.replace(fill_radius=1)) != treedef


def test_jit_recompiles_on_static_change_only():
    traces = []

    @jax.jit
    def f(params, x):
        traces.append(params.static)
        return x * params.dynamic.census_weight + params.static.aggregation_radius

    x = jnp.ones(3)
    np.testing.assert_allclose(f(Params(), x), 0.8 + 4)
    assert len(traces) == 1
    # dynamic change: same trace, new value
    np.testing.assert_allclose(f(Params().replace(census_weight=0.5, tad_truncation=0.2), x), 0.5 + 4)
    assert len(traces) == 1
    # static change: retrace
    np.testing.assert_allclose(f(Params().replace(aggregation_radius=6), x), 0.8 + 6)
    assert len(traces) == 2
    np.testing.assert_allclose(f(Params().replace(aggregation_radius=6, census_weight=0.1), x), 0.1 + 6)
    assert len(traces) == 2
    f(Params().replace(window_selection="guide"), x)
    assert len(traces) == 3
    # back to the first static values: cached
    f(Params(), x)
    assert len(traces) == 3


def test_grad_through_dynamic_params():
    def loss(params):
        d = params.dynamic
        return d.tad_weight**2 + 3.0 * d.census_weight * d.tad_truncation + jnp.sin(d.lr_tolerance)

    p = Params().replace(tad_weight=0.5, census_weight=2.0, tad_truncation=0.25, lr_tolerance=1.0)
    grads = jax.grad(loss)(p)
    assert isinstance(grads, Params)
    assert grads.static == p.static
    g = grads.dynamic
    assert float(g.tad_weight) == pytest.approx(1.0)
    assert float(g.census_weight) == pytest.approx(0.75)
    assert float(g.tad_truncation) == pytest.approx(6.0)
    assert float(g.lr_tolerance) == pytest.approx(math.cos(1.0), rel=1e-6)
    for name in ("gradient_weight", "gradient_truncation", "segment_weight", "slic_compactness"):
        assert float(getattr(g, name)) == 0.0


def test_grad_through_cost_volume_wrt_weights():
    # d/d alpha of sum(C) is the sum of the normalised TAD term: compare with finite differences
    from sswjax.stages.cost import cost_volume

    rng = np.random.default_rng(0)
    left = jnp.asarray(rng.random((6, 10, 3)), jnp.float32)
    right = jnp.asarray(rng.random((6, 10, 3)), jnp.float32)

    def total(params):
        d = params.dynamic
        c = cost_volume(
            left, right, ndisp=3, tad_weight=d.tad_weight, gradient_weight=d.gradient_weight,
            census_weight=d.census_weight, tad_truncation=d.tad_truncation,
            gradient_truncation=d.gradient_truncation, census_height=3, census_width=3,
        )
        return c.sum()

    p = Params()
    g = jax.grad(total)(p).dynamic
    eps = 1e-2
    for name in ("tad_weight", "gradient_weight", "census_weight"):
        plus = float(total(p.replace(**{name: getattr(p.dynamic, name) + eps})))
        minus = float(total(p.replace(**{name: getattr(p.dynamic, name) - eps})))
        # the cost is linear in the weights: central differences are exact up to rounding
        assert float(getattr(g, name)) == pytest.approx((plus - minus) / (2 * eps), rel=1e-3)
        assert float(getattr(g, name)) > 0
