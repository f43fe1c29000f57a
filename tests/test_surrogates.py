"""The search's surrogates against what they stand in for, its settings, its folds and its grid.

The surrogates run jitted, as the search runs them (inside its step): one compilation per
surrogate and options, not one per operation."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sswjax
from sswjax.data.layouts import StereoScene
from sswjax.search import SURROGATES, SearchSettings, folds, surrogate
from sswjax.search.grid import grid_options, grid_search
from sswjax.search.surrogates import WINDOW_FLOOR, soft_bad, window_nll



def _jit(fn, **options):
    """``fn`` with keyword ``options`` fixed, jitted."""
    return jax.jit(functools.partial(fn, **options))


def _volume(winners, ndisp=16, depth=5.0):
    """A (D, 1, N) cost volume with one clear minimum per pixel at ``winners``."""
    d = np.arange(ndisp, dtype=np.float32)[:, None, None]
    return jnp.asarray(depth * np.minimum(np.abs(d - np.asarray(winners, np.float32)), 1.0))


def test_soft_bad_tends_to_the_bad_pixel_count():
    winners = np.array([[3, 7, 10, 12]])
    truth = jnp.asarray([[3.2, 8.5, 12.5, 12.0]], jnp.float32)  # errors 0.2, 1.5, 2.5, 0
    loss = _jit(soft_bad, temperature=0.01, threshold=2.0, width=0.01)(_volume(winners), truth)
    assert np.allclose(np.asarray(loss), [[0, 0, 1, 0]], atol=1e-3)
    loss = _jit(soft_bad, temperature=0.01, threshold=1.0, width=0.01)(_volume(winners), truth)
    assert np.allclose(np.asarray(loss), [[0, 1, 1, 0]], atol=1e-3)


def test_window_nll_asks_for_mass_near_the_truth_not_a_mean_between_modes():
    truth = jnp.asarray([[6.0]], jnp.float32)
    nll = _jit(window_nll, temperature=0.1, radius=1.0)
    right = nll(_volume([[6]]), truth)
    assert float(right[0, 0]) < 1e-3
    d = np.arange(16, dtype=np.float32)[:, None, None]
    two_modes = jnp.asarray(5.0 * np.minimum(np.minimum(np.abs(d - 2), np.abs(d - 10)), 1.0))
    wrong = nll(two_modes, truth)
    assert float(wrong[0, 0]) == pytest.approx(-np.log(WINDOW_FLOOR), rel=1e-3)
    # the soft-argmin of the same volume sits at the truth: a smooth L1 would call it right
    assert float(_jit(SURROGATES["soft_l1"], temperature=0.1)(two_modes, truth)[0, 0]) < 0.01


@pytest.mark.parametrize("name", sorted(SURROGATES))
def test_every_surrogate_has_a_finite_gradient(name):
    volume = _volume([[3, 7, 10]]) + jnp.asarray(np.random.default_rng(0).random((16, 1, 3)),
                                                 jnp.float32)
    truth = jnp.asarray([[3.0, 9.0, 14.0]], jnp.float32)
    grad = jax.jit(jax.grad(lambda c: surrogate(name)(c, truth, temperature=0.5).sum()))(volume)
    assert grad.shape == volume.shape and bool(jnp.isfinite(grad).all())
    assert float(jnp.abs(grad).sum()) > 0


def test_an_unknown_surrogate_names_the_known_ones():
    with pytest.raises(ValueError, match="known: soft_l1"):
        surrogate("l2")
    with pytest.raises(ValueError, match="unknown surrogate"):
        SearchSettings(surrogate="l2")


def test_settings_round_trip_and_refuse_bad_values():
    settings = SearchSettings(steps=5, frozen=["temperature"])
    assert SearchSettings.from_dict(settings.to_dict()) == settings
    for bad in ({"steps": 0}, {"ema": 1.0}, {"lr": 0.0}, {"min_valid": 1.0}, {"batch": 2.5}):
        with pytest.raises(ValueError):
            SearchSettings(**bad)
    with pytest.raises(ValueError, match="unknown search settings"):
        SearchSettings.from_dict({"step": 3})


def _scenes(*names):
    image = np.zeros((4, 4), np.uint8)
    return [StereoScene(n, image, image, 4, np.zeros((4, 4), np.float32), None, None)
            for n in names]


def test_folds_leave_one_data_set_or_one_scene_out():
    sets = {"A": (_scenes("a1", "a2"), "mean"), "B": (_scenes("b1"), "mean")}
    by_set = folds(sets, "datasets")
    assert [(name, sorted(train), list(held)) for name, train, held in by_set] == \
        [("A", ["B"], ["A"]), ("B", ["A"], ["B"])]
    by_scene = folds(sets, "scenes")
    assert [name for name, _, _ in by_scene] == ["A-a1", "A-a2", "B-b1"]
    name, train, held = by_scene[2]
    assert list(train) == ["A"] and [s.name for s in held["B"]] == ["b1"]  # B had only b1
    assert folds(sets, "none") == []
    with pytest.raises(ValueError, match="two data sets"):
        folds({"A": sets["A"]}, "datasets")


def test_grid_search_walks_each_option_once_and_replays_its_trials():
    base = sswjax.preset("accurate")
    assert dict(grid_options(base))["checks.uniqueness_gap"] == 1

    def error(params):  # lowest at fill.tolerance 3 and gap 3; the other options indifferent
        return abs(params.fill.tolerance - 3.0) + abs(params.checks.uniqueness_gap - 3) + 1.0

    calls = []
    best, best_error, trials = grid_search(base, lambda p: calls.append(p) or error(p))
    assert best.fill.tolerance == 3.0 and best.checks.uniqueness_gap == 3
    assert best_error == 1.0
    assert best.smoothing.gate == base.smoothing.gate  # ties keep the start
    assert len(calls) == len(trials) + 1  # + the start
    replayed = []
    again = grid_search(base, lambda p: replayed.append(p) or error(p), log=trials[:3])
    assert again[0] == best and len(replayed) == len(trials) - 3 + 1
    tried = [value for path, value, _ in trials if path == "checks.tolerance"]
    assert base.checks.tolerance == 0.0 and tried == [0.5]  # -0.5 is out of bounds: not tried
