"""Tests of the differentiable parameter search (sswjax.search): tiny synthetic crops only."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from sswjax import search as tuning
from sswjax.config import Params, SemiGlobal, preset
from sswjax.config.cost import MatchingCost
from sswjax.config.fields import option_fields
from sswjax.data.layouts import StereoScene
from sswjax.runtime.devices import device_mesh

NDISP = 8
BASE = Params().replace(**{"segments.n_segments": 8, "segments.iterations": 2,
                           "cost.census_height": 5, "cost.census_width": 5,
                           "aggregation.iterations": 1, "aggregation.radius": 2})


def _scene(name, image, ndisp, gt, mask=None):
    return StereoScene(name=name, left=image, right=image, ndisp=ndisp, ground_truth=gt,
                       mask=mask, path=None)


def _crops(shifts=(3, 5)):
    """24 x 48 crops: a textured right view shifted by each of ``shifts`` pixels, with noise."""
    rng = np.random.default_rng(0)
    lefts, rights, gts, valids = [], [], [], []
    for shift in shifts:
        base = rng.random((24, 48 + shift, 3)).astype(np.float32)
        base = (base + np.roll(base, 1, axis=1)) / 2  # some spatial correlation
        right = base[:, shift:]
        left = base[:, :48]
        left = np.clip(left + 0.01 * rng.standard_normal(left.shape), 0, 1).astype(np.float32)
        gt = np.full((24, 48), float(shift), np.float32)
        valid = tuning.valid_mask(gt, None, ndisp=NDISP)
        lefts.append(left), rights.append(right), gts.append(gt), valids.append(valid)
    return (np.stack(lefts), np.stack(rights), np.stack(gts), np.stack(valids),
            np.full(len(shifts), NDISP, np.int32))


@pytest.fixture(scope="module")
def batch():
    """Two crops, shifted by 3 and 5 pixels."""
    return _crops()


@pytest.fixture(scope="module")
def adam():
    """Adam with a small step and its jitted update step (compiled once for the module)."""
    optimizer = optax.adam(0.01)
    step = tuning.make_update_step(optimizer, base=BASE, ndisp=NDISP)
    return optimizer, step


def test_round_trip():
    params = Params().replace(**{"cost.tad_weight": 0.1, "cost.gradient_weight": 0.3,
                                 "cost.census_weight": 0.6, "cost.tad_truncation": 0.05,
                                 "cost.gradient_truncation": 0.2,
                                 "aggregation.segment_weight": 0.7,
                                 "segments.compactness": 12.0, "checks.tolerance": 0.5})
    back, temperature = tuning.from_unconstrained(
        tuning.to_unconstrained(params, temperature=0.03), base=params)
    for path in tuning.SEARCHED:
        assert float(tuning.value_of(back, path)) == pytest.approx(tuning.value_of(params, path),
                                                                   rel=1e-4)
    assert float(temperature) == pytest.approx(0.03, rel=1e-4)
    # no useful gradient on the soft path: not searchable, held at the base values
    for path in ("segments.compactness", "checks.tolerance"):
        assert path not in tuning.searchable(params)
        assert tuning.value_of(back, path) == tuning.value_of(params, path)
    assert tuning.searchable(Params()) == tuning.SEARCHED


def test_weights_normalised_and_ranges():
    start = Params().replace(**{"cost.tad_weight": 1.0, "cost.gradient_weight": 1.0,
                                "cost.census_weight": 2.0})
    raw = tuning.to_unconstrained(start)
    raw = {k: v + 50.0 for k, v in raw.items()}  # extreme values stay in range
    params, temperature = tuning.from_unconstrained(raw, base=start)
    cost = params.cost
    assert float(cost.tad_weight + cost.gradient_weight + cost.census_weight) == pytest.approx(1.0)
    ranges = {name: spec.search for name, spec in option_fields(MatchingCost)
              if name.endswith("_truncation")}
    assert set(ranges) == {"tad_truncation", "gradient_truncation"}
    for name, (low, high) in ranges.items():
        assert low - 1e-6 <= float(getattr(cost, name)) <= high + 1e-6
    assert float(temperature) > 0
    params = tuning.raw_to_params(raw, Params())
    assert isinstance(params.cost.tad_weight, float)


def test_valid_mask_excludes_matches_outside():
    """The one loss mask: known, non-occluded, 0 <= gt <= ndisp - 1, match inside the crop."""
    gt = np.array([[0.0, 2.0, 2.0, np.inf, 9.0, -1.0, 1.0]], np.float32)
    assert tuning.valid_mask(gt, None, ndisp=8).tolist() == [
        [True, False, True, False, False, False, True]]
    mask = np.array([[255, 255, 128, 255, 255, 255, 0]], np.uint8)
    assert tuning.valid_mask(gt, mask, ndisp=8).tolist() == [
        [True, False, False, False, False, False, False]]
    # random_crops uses it: the valid pixels of each crop are the mask of its ground truth
    rng = np.random.default_rng(2)
    truth = rng.uniform(-2, 10, (20, 30)).astype(np.float32)
    truth[rng.random((20, 30)) < 0.2] = np.nan
    occlusion = np.where(rng.random((20, 30)) < 0.3, 128, 255).astype(np.uint8)
    scene = _scene("m", np.zeros((20, 30, 1), np.float32), 8, truth, occlusion)
    _, _, gts, valids, _ = tuning.random_crops([scene], rng, batch=1, height=20, width=30)
    assert valids[0].tolist() == tuning.valid_mask(truth, occlusion, ndisp=8).tolist()
    assert not valids[0][truth < 0].any() and valids[0].any()
    assert np.all(np.isfinite(gts))


def test_loss_and_gradients_finite_nonzero(batch, adam):
    """Through Adam's first step, -lr * g / (|g| + eps): finite iff g is, nonzero iff g is."""
    optimizer, step = adam
    raw = tuning.to_unconstrained(BASE, temperature=0.05)
    new_raw, _, value = step(raw, optimizer.init(raw), batch)
    assert np.isfinite(float(value)) and float(value) > 0
    for key in tuning.raw_keys(tuning.SEARCHED):
        moved = np.asarray(new_raw[key]) - np.asarray(raw[key])
        assert np.all(np.isfinite(moved)), key
        assert np.all(np.abs(moved) > 1e-3), key  # |g| >> eps


def test_padded_ndisp_is_masked(batch):
    raw = tuning.to_unconstrained(BASE, temperature=0.05)
    left, right = batch[0][0], batch[1][0]
    d = jax.jit(lambda r: tuning.soft_disparity(r, left, right, base=BASE, ndisp=NDISP,
                                                scene_ndisp=4))(raw)
    assert float(jnp.max(d)) <= 3.0 + 1e-4


def test_update_step_lowers_loss(batch, adam):
    optimizer, step = adam
    raw = tuning.to_unconstrained(BASE, temperature=0.05)
    state = optimizer.init(raw)
    new_raw, state, before = step(raw, state, batch)
    _, _, after = step(new_raw, state, batch)  # the loss returned is at new_raw
    assert np.isfinite(float(before)) and float(after) < float(before)


def test_frozen_keys_by_construction(batch):
    """make_optimizer's frozen keys get zero updates and no Adam moments; the trained keys take
    bit for bit the steps of Adam fed a zeroed gradient on the frozen keys (the hand-made way)."""
    frozen = ("cost.weight_logits", "temperature")
    raw0 = tuning.to_unconstrained(BASE, temperature=0.05)
    mask = {k: k in frozen for k in raw0}
    zeroed = optax.chain(optax.masked(optax.set_to_zero(), mask), optax.adam(0.05))
    paths = []
    for optimizer in (tuning.make_optimizer(0.05, frozen=frozen), zeroed):
        step = tuning.make_update_step(optimizer, base=BASE, ndisp=NDISP)
        raw, state, path = raw0, optimizer.init(raw0), []
        for _ in range(3):
            raw, state, value = step(raw, state, batch)
            path.append((float(value), {k: np.asarray(v) for k, v in raw.items()}))
        paths.append(path)
    assert paths[0][2][0] != paths[0][0][0]  # the loss moved
    for (loss_new, raw_new), (loss_old, raw_old) in zip(*paths):
        assert loss_new == loss_old
        for key in raw0:
            np.testing.assert_array_equal(raw_new[key], raw_old[key], err_msg=key)
            if key in frozen:
                np.testing.assert_array_equal(raw_new[key], np.asarray(raw0[key]), err_msg=key)
    # Adam's moments exist only for the trained keys
    adam_state = tuning.make_optimizer(0.05, frozen=frozen).init(raw0).inner_states["train"]
    mu = adam_state.inner_state[0].mu
    assert {k for k, v in mu.items() if not isinstance(v, optax.MaskedNode)} == set(raw0) - set(frozen)
    with pytest.raises(ValueError, match="unknown raw keys"):
        tuning.make_optimizer(0.05, frozen=("cost.tad_weight",))


def test_checkpoint_round_trip(tmp_path):
    raw = tuning.to_unconstrained(Params())
    optimizer = tuning.make_optimizer(0.05, frozen=("cost.weight_logits",))
    state = optimizer.init(raw)
    grads = jax.tree_util.tree_map(jnp.ones_like, raw)
    updates, state = optimizer.update(grads, state, raw)
    raw = optax.apply_updates(raw, updates)
    rng = np.random.default_rng(3)
    rng.random(5)
    path = tmp_path / "ckpt.pkl"
    tuning.save_checkpoint(path, raw=raw, opt_state=state, step=7, rng=rng, extra={"loss": [[1, 2.0]]})
    raw2, state2, step2, rng2, extra = tuning.load_checkpoint(path, opt_state_like=optimizer.init(raw))
    assert step2 == 7 and extra == {"loss": [[1, 2.0]]}
    for a, b in zip(jax.tree_util.tree_leaves((raw, state)), jax.tree_util.tree_leaves((raw2, state2))):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert rng.random() == rng2.random()
    # the restored optimizer state continues identically
    u1, _ = optimizer.update(grads, state, raw)
    u2, _ = optimizer.update(grads, state2, raw2)
    for a, b in zip(jax.tree_util.tree_leaves(u1), jax.tree_util.tree_leaves(u2)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b))
    # another frozen set, or the plain Adam state of the old format, is refused
    for other in (tuning.make_optimizer(0.05, frozen=("temperature",)), optax.adam(0.05)):
        with pytest.raises(ValueError, match="does not match"):
            tuning.load_checkpoint(path, opt_state_like=other.init(raw))


def test_random_crops_shapes():
    rng = np.random.default_rng(0)
    image = rng.random((30, 60, 3)).astype(np.float32)
    gt = np.full((30, 60), 4.0, np.float32)
    gt[0, 0] = np.inf
    scene = _scene("x", image, 16, gt, np.full((30, 60), 255, np.uint8))
    lefts, rights, gts, valids, nds = tuning.random_crops([scene], rng, batch=3, height=20, width=40)
    assert lefts.shape == (3, 20, 40, 3) and gts.shape == (3, 20, 40) and valids.dtype == bool
    assert np.all(np.isfinite(gts)) and nds.tolist() == [16, 16]  + [16]
    assert not valids[:, :, :4].any()


def _two_steps(devices):
    """Loss and raw parameters after each of two Adam steps on three crops (not a multiple of
    two devices), sharded over ``devices``; and how :func:`tuning.shard_crops` splits them."""
    crops = _crops((3, 5, 2))
    optimizer = optax.adam(0.05)
    step = tuning.make_update_step(optimizer, base=BASE, ndisp=NDISP, devices=devices)
    raw = tuning.to_unconstrained(BASE, temperature=1.0)  # a loss far from 0
    state, out = optimizer.init(raw), []
    for _ in range(2):
        raw, state, value = step(raw, state, crops)
        out.append({"loss": float(value), **{k: np.asarray(v).tolist() for k, v in raw.items()}})
    placed = tuning.shard_crops(crops, device_mesh(devices=devices))
    lefts = placed[0]
    layout = {"size": lefts.shape[0], "per_device": lefts.sharding.shard_shape(lefts.shape)[0],
              "padding_valid": bool(np.asarray(placed[3])[3:].any()),
              "raw_devices": len(raw["temperature"].sharding.device_set)}
    return out, layout


TUNING_SCRIPT = """
import json
from test_tuning import _two_steps
print(json.dumps(_two_steps(None)))
"""


def test_sharded_step_same_on_one_and_two_devices(run_on_devices):
    one, layout_one = _two_steps(jax.devices()[:1])
    assert layout_one == {"size": 3, "per_device": 3, "padding_valid": False, "raw_devices": 1}
    two, layout_two = json.loads(run_on_devices(TUNING_SCRIPT))
    # padded to 4 with one zero-weight crop, 2 crops per device; parameters on both devices
    assert layout_two == {"size": 4, "per_device": 2, "padding_valid": False, "raw_devices": 2}
    for step_one, step_two in zip(one, two):
        assert step_one.keys() == step_two.keys()
        for key in step_one:
            np.testing.assert_allclose(step_two[key], step_one[key], rtol=1e-5, atol=1e-7,
                                       err_msg=key)
    assert one[1]["loss"] != one[0]["loss"]  # the parameters moved


# --- the search through the semi-global optimiser, and the data-set folds ------------------

SGM_BASE = BASE.replace(segments=None, optimizer=SemiGlobal(paths=4, p1=0.05, p2=0.8, sigma=0.05))


def test_sgm_objective_gradients_finite_nonzero():
    """Soft-argmin over the SGM-optimised volume: finite, non-zero gradients with respect to
    the penalties (which enter only through the optimiser) and the truncations (the int16
    paths of inference, if the default, would round them to zero: the search runs the float32
    ones)."""
    lefts, rights, gts, valids, nds = _crops((3,))
    raw = tuning.to_unconstrained(SGM_BASE, temperature=0.08, searched=tuning.SGM_SEARCHED)
    assert set(raw) == {"cost.tad_truncation", "cost.gradient_truncation", "optimizer.p1",
                        "optimizer.p2", "optimizer.sigma", "temperature"}
    value, grads = jax.jit(jax.value_and_grad(
        lambda r: tuning.batch_loss(r, lefts, rights, gts, valids, nds, base=SGM_BASE,
                                    ndisp=NDISP)))(raw)
    assert np.isfinite(float(value)) and float(value) > 0
    for key in raw:
        g = float(grads[key])
        assert np.isfinite(g) and abs(g) > 1e-7, (key, g)
    # a non-differentiable inference switch is replaced in the search, as its option declares
    assert SGM_BASE.optimizer.dtype == "int16"
    declared = {name: spec.differentiable for name, spec in option_fields(SemiGlobal)
                if spec.differentiable is not None}
    assert declared == {"dtype": "float32"}
    for name, value in declared.items():
        assert getattr(tuning.differentiable(SGM_BASE).optimizer, name) == value


def test_search_spaces_round_trip():
    start = SGM_BASE.replace(**{"optimizer.p1": 0.03, "optimizer.p2": 1.1,
                                "optimizer.sigma": 0.02, "cost.tad_truncation": 0.05})
    raw = tuning.to_unconstrained(start, temperature=0.1, searched=tuning.SGM_SEARCHED)
    assert tuple(raw) == tuning.raw_keys(tuning.SGM_SEARCHED)
    assert tuning.searched_fields(raw) == tuning.SGM_SEARCHED
    assert set(tuning.SGM_SEARCHED) <= set(tuning.searchable(preset("accurate")))
    back, temperature = tuning.from_unconstrained(raw, base=SGM_BASE)
    for path in tuning.SGM_SEARCHED:
        assert float(tuning.value_of(back, path)) == pytest.approx(
            float(tuning.value_of(start, path)), rel=1e-4)
    assert back.cost.tad_weight == SGM_BASE.cost.tad_weight  # not searched: from base
    assert float(temperature) == pytest.approx(0.1, rel=1e-4)
    params = tuning.raw_to_params({k: v - 30.0 for k, v in raw.items()}, SGM_BASE)
    floor = dict(option_fields(SemiGlobal))["sigma"].search.floor
    assert floor > 0 and params.optimizer.sigma >= floor
    assert params.optimizer.p1 >= 0 and params.cost.census_weight == SGM_BASE.cost.census_weight
    with pytest.raises(ValueError, match="all together"):
        tuning.raw_keys(("cost.tad_weight", "optimizer.p1"))
    with pytest.raises(ValueError, match="no reparametrisation"):
        tuning.raw_keys(("checks.tolerance",))
    with pytest.raises(ValueError, match="stage optimizer is None"):
        tuning.to_unconstrained(Params(), searched=tuning.SGM_SEARCHED)
    # the freeze keys of the SGM space are accepted
    tuning.make_optimizer(0.05, frozen=("optimizer.sigma",))


def test_dataset_folds_leave_one_out():
    names = ["MiddEval3", "KITTI2012", "Middlebury2001"]
    folds = tuning.dataset_folds(names)
    assert [held for held, _ in folds] == names
    for held, others in folds:
        assert held not in others and sorted(others + [held]) == sorted(names)
    with pytest.raises(ValueError):
        tuning.dataset_folds(["a"])
    with pytest.raises(ValueError):
        tuning.dataset_folds(["a", "a"])


def test_random_crops_sparse_ground_truth():
    """KITTI-like: ground truth on the bottom rows only, no mask; gray repeated to 3 channels."""
    rng = np.random.default_rng(1)
    image = (rng.random((40, 60)) * 255).astype(np.uint8)
    gt = np.full((40, 60), np.nan, np.float32)
    gt[32:] = 3.0
    scene = tuning.prepare_scene(_scene("k", image, 8, gt), channels=3)
    assert scene.left.shape == (40, 60, 3) and np.array_equal(scene.left[..., 0], scene.left[..., 2])
    lefts, _, _, valids, _ = tuning.random_crops([scene], rng, batch=6, height=12, width=20,
                                                 min_valid=0.2)
    assert lefts.shape == (6, 12, 20, 3)
    assert valids.mean(axis=(1, 2)).min() >= 0.2
    _, _, _, once, _ = tuning.random_crops([scene], np.random.default_rng(1), batch=20, height=12,
                                           width=20)
    assert once.mean(axis=(1, 2)).min() < 0.2  # without min_valid some crops miss it
