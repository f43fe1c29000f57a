"""Tests for sswjax.config.params: the root pytree, replace, and its behaviour under jit / grad."""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax import ConfigError, Params, preset
from sswjax.config import (BackgroundFill, LeftRightCheck, SemiGlobal, SideWindowAggregation, SLOTS,
                           VoteFill)
from sswjax.config.fields import option_fields
from sswjax.stages.reference import cost_volume


def test_defaults_are_the_papers_method():
    p = Params()
    assert tuple(name for name, _ in p.stages()) == tuple(SLOTS)
    assert p.optimizer is None and p.coarse is None and p.preprocess is None
    assert p.aggregation == SideWindowAggregation() and p.aggregation.radius == 4
    assert (p.cost.census_height, p.cost.census_width) == (7, 9)
    assert isinstance(p.fill, BackgroundFill) and p.fill.median_radius == 2
    assert p == preset("paper")


def test_replace_by_dotted_option_slot_and_mapping():
    p = Params()
    q = p.replace(**{"cost.census_weight": 0.5, "aggregation.radius": 6}, checks=None, fill=None)
    assert q.cost.census_weight == 0.5 and q.aggregation.radius == 6
    assert q.checks is None and q.fill is None
    assert q.cost == dataclasses.replace(p.cost, census_weight=0.5)
    assert p == Params()  # the original is not modified
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.cost = None  # type: ignore[misc]
    # a mapping changes options of the slot's current part, or, with "kind", starts a new one
    r = p.replace(fill={"median_radius": 3})
    assert r.fill == BackgroundFill(median_radius=3)
    s = p.replace(fill={"kind": "vote", "step": 2})
    assert s.fill == VoteFill(step=2)
    t = p.replace(optimizer=SemiGlobal(p2=1.0))
    assert t.optimizer.p2 == 1.0 and t.optimizer.paths == 8


def test_replace_refuses_unknown_names_kinds_and_options():
    with pytest.raises(ConfigError, match="unknown parameter 'no_such_thing'"):
        Params().replace(no_such_thing=1)
    with pytest.raises(ConfigError, match="'fill' 'background' has no option 'band_fit'|fill "
                       "'background' has no option 'band_fit'"):
        Params().replace(**{"fill.band_fit": 15})
    with pytest.raises(ConfigError, match="stage optimizer is None"):
        Params().replace(**{"optimizer.p2": 1.0})
    with pytest.raises(ConfigError, match="'nope' is not a stage"):
        Params().replace(**{"nope.radius": 1})
    with pytest.raises(ConfigError, match="unknown fill kind 'nope'"):
        Params().replace(fill={"kind": "nope"})
    with pytest.raises(ConfigError, match="stage cost cannot be None"):
        Params().replace(cost=None)
    with pytest.raises(ConfigError, match="stage fill takes a configuration"):
        Params().replace(fill=SemiGlobal())


def test_a_kind_by_name_or_by_mapping_is_one_rule():
    finest = preset("finest")
    assert finest.replace(fill="vote") == finest.replace(fill={"kind": "vote"}) \
        == finest.replace(fill=VoteFill())  # another kind: its defaults
    assert finest.replace(fill="wmedian") == finest.replace(fill={"kind": "wmedian"}) == finest
    assert preset("fast").replace(fill={"median_radius": 5}).fill.band_fit == 15  # kept
    gf = Params().replace(aggregation={"kind": "gf", "radius": 5}).replace(fill="vote")
    assert gf.aggregation.radius == 5 and gf.fill == VoteFill()
    for old in ("census_weight", "fill_radius", "strip_rows"):
        with pytest.raises(ConfigError, match=f"unknown parameter '{old}': name a stage"):
            Params().replace(**{old: 1})


def test_to_dict_is_nested_per_stage():
    data = preset("accurate").to_dict()
    assert list(data) == list(SLOTS)
    assert data["segments"] is None and data["coarse"] is None
    assert data["optimizer"] == {"kind": "sgm", "paths": 4, "dtype": "uint8", "p1": 0.35, "p2": 2.4,
                                 "sigma": 0.05, "segment_factor": 1.0}
    assert "kind" not in data["cost"]  # one part only: no kind to name
    assert data["fill"]["kind"] == "vote" and data["fill"]["band_fit"] == 15


# ---------------------------------------------------------------------------------------------
# pytree behaviour


def _traced(params):
    return [(slot, name) for slot, config in params.stages() if config is not None
            for name, spec in option_fields(config) if not spec.static]


def test_tree_leaves_are_the_traced_options():
    p = Params().replace(**{"cost.tad_weight": 0.11, "checks.tolerance": 2.5})
    leaves = jax.tree_util.tree_leaves(p)
    assert leaves == [getattr(getattr(p, slot), name) for slot, name in _traced(p)]
    treedef = jax.tree_util.tree_structure(p)
    rebuilt = jax.tree_util.tree_unflatten(treedef, [float(i) for i in range(len(leaves))])
    assert rebuilt.aggregation.radius == p.aggregation.radius  # static options in the treedef
    assert jax.tree_util.tree_leaves(rebuilt) == [float(i) for i in range(len(leaves))]
    # a static option, or another part, gives another treedef
    assert jax.tree_util.tree_structure(p.replace(**{"fill.median_radius": 1})) != treedef
    assert jax.tree_util.tree_structure(p.replace(fill=VoteFill())) != treedef
    assert len(jax.tree_util.tree_leaves(preset("accurate"))) == len(_traced(preset("accurate")))


def test_jit_recompiles_on_static_change_only():
    traces = []

    @jax.jit
    def f(params, x):
        traces.append(1)
        return x * params.cost.census_weight + params.aggregation.radius

    x = jnp.ones(3)
    np.testing.assert_allclose(f(Params(), x), 0.8 + 4)
    np.testing.assert_allclose(f(Params().replace(**{"cost.census_weight": 0.5,
                                                     "cost.tad_truncation": 0.2}), x), 0.5 + 4)
    assert len(traces) == 1  # a traced change: the same trace, new values
    np.testing.assert_allclose(f(Params().replace(**{"aggregation.radius": 6}), x), 0.8 + 6)
    assert len(traces) == 2
    f(Params().replace(**{"aggregation.window_selection": "guide"}), x)
    f(Params().replace(checks=LeftRightCheck(uniqueness_gap=2)), x)
    assert len(traces) == 4
    f(Params(), x)  # back to the first structure: cached
    assert len(traces) == 4


def test_grad_through_traced_options():
    def loss(params):
        return (params.cost.tad_weight ** 2 + 3.0 * params.cost.census_weight
                * params.cost.tad_truncation + jnp.sin(params.checks.tolerance))

    p = Params().replace(**{"cost.tad_weight": 0.5, "cost.census_weight": 2.0,
                            "cost.tad_truncation": 0.25, "checks.tolerance": 1.0})
    grads = jax.grad(loss)(p)
    assert isinstance(grads, Params) and grads.aggregation.radius == p.aggregation.radius
    assert float(grads.cost.tad_weight) == pytest.approx(1.0)
    assert float(grads.cost.census_weight) == pytest.approx(0.75)
    assert float(grads.cost.tad_truncation) == pytest.approx(6.0)
    assert float(grads.checks.tolerance) == pytest.approx(math.cos(1.0), rel=1e-6)
    assert float(grads.cost.gradient_weight) == 0.0 == float(grads.aggregation.segment_weight)


def test_grad_through_the_cost_volume_wrt_the_weights():
    # d/d alpha of sum(C) is the sum of the normalised TAD term: compare with finite differences
    rng = np.random.default_rng(0)
    left = jnp.asarray(rng.random((6, 10, 3)), jnp.float32)
    right = jnp.asarray(rng.random((6, 10, 3)), jnp.float32)

    def total(params):
        c = params.cost
        return cost_volume(left, right, ndisp=3, tad_weight=c.tad_weight,
                           gradient_weight=c.gradient_weight, census_weight=c.census_weight,
                           tad_truncation=c.tad_truncation,
                           gradient_truncation=c.gradient_truncation, census_height=3,
                           census_width=3).sum()

    p = Params()
    g = jax.grad(total)(p).cost
    eps = 1e-2
    for name in ("tad_weight", "gradient_weight", "census_weight"):
        plus = float(total(p.replace(**{f"cost.{name}": getattr(p.cost, name) + eps})))
        minus = float(total(p.replace(**{f"cost.{name}": getattr(p.cost, name) - eps})))
        # the cost is linear in the weights: central differences are exact up to rounding
        assert float(getattr(g, name)) == pytest.approx((plus - minus) / (2 * eps), rel=1e-3)
        assert float(getattr(g, name)) > 0
