"""Tests for sswjax.stages.confidence and the runner-up of the fold, against NumPy references."""

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax import Params, graph
from sswjax.stages.confidence import (
    AMBIGUITY_TOLERANCE,
    AMBIGUOUS,
    LEFT_BAND,
    LOW_CONFIDENCE,
    LR_FAILED,
    MEASURES,
    OUTSIDE_VIEW,
    ConfidenceCues,
    ambiguous,
    confidence,
    ratio_confidence,
    validity_mask,
)
from sswjax.stages.checks import left_right_distance as lr_distance
from sswjax.stages.selection import fold_winners, no_winners


def _runner_up_reference(cost, limit):
    """Smallest cost at |d - argmin| > 1 over disparities < limit, by brute force."""
    inside = cost[:limit].astype(np.float64)
    best = np.argmin(inside, axis=0)
    second = np.full(best.shape, np.inf)
    for d in range(limit):
        away = np.abs(d - best) > 1
        second = np.where(away, np.minimum(second, inside[d]), second)
    return second


@pytest.mark.parametrize("block", [1, 3, 4, 9])
@pytest.mark.parametrize("integers", [False, True])
def test_fold_runner_up_equals_brute_force(block, integers):
    rng = np.random.default_rng(block)
    ndisp, limit = 9, 8
    shape = (ndisp, 5, 11)
    cost = (rng.integers(0, 4, size=shape) if integers else rng.random(shape)).astype(np.float32)
    cost[:, 0, 0] = np.arange(ndisp)[::-1]           # winner at the last valid disparity
    cost[:, 0, 1] = [0, 1, 0.5, 3, 3, 3, 3, 3, 3]    # runner-up two below the winner...
    cost[:, 0, 2] = [3, 0.5, 0, 3, 3, 3, 3, 3, 3]    # ... winner moving by one: d - 2 counts
    padded = np.concatenate([np.full((1, *shape[1:]), 7, np.float32), cost,
                             np.full((block + 1, *shape[1:]), 7, np.float32)])
    state = no_winners(shape[1:])
    for first in range(0, ndisp, block):
        state = fold_winners(state, jnp.asarray(padded[first:first + block + 2]),
                             jnp.int32(first), limit=limit)
    np.testing.assert_array_equal(np.asarray(state.second), _runner_up_reference(cost, limit))
    assert float(state.second[0, 1]) == 0.5 and float(state.second[0, 2]) == 3.0


def test_measures_against_numpy():
    rng = np.random.default_rng(0)
    h, w = 6, 10
    left = rng.integers(0, 5, size=(h, w)).astype(np.int32)
    right = rng.integers(0, 5, size=(h, w)).astype(np.int32)
    ours = np.asarray(lr_distance(jnp.asarray(left), jnp.asarray(right)))
    reference = np.full((h, w), np.inf)
    for y in range(h):
        for x in range(w):
            if x - left[y, x] >= 0:
                reference[y, x] = abs(left[y, x] - right[y, x - left[y, x]])
    np.testing.assert_array_equal(ours, reference)

    cost = rng.random((h, w)).astype(np.float32)
    second = cost + rng.random((h, w)).astype(np.float32)
    second[0, 0] = np.inf
    second[0, 1] = cost[0, 1]
    ratio = np.asarray(ratio_confidence(jnp.asarray(cost), jnp.asarray(second)))
    expected = np.where(np.isinf(second), 1.0, 1.0 - cost.astype(np.float64) / second)
    np.testing.assert_allclose(ratio, expected, rtol=1e-6, atol=1e-7)
    assert ratio[0, 1] == 0.0

    initial = rng.random((h, w)).astype(np.float32) * 4
    final = initial + rng.integers(-2, 3, size=(h, w)).astype(np.float32)
    cues = ConfidenceCues(*(jnp.asarray(a) for a in (cost, second, ours, initial)),
                          jnp.zeros((h, w), bool))
    lr = 1 / (1 + reference)
    agreement = 1 / (1 + np.abs(final - initial))
    references = {"ratio": expected, "lr": lr, "agreement": agreement,
                  "combined": expected * lr * agreement}
    assert set(references) == set(MEASURES)
    for name, want in references.items():
        got = np.asarray(confidence(cues, jnp.asarray(final), measure=name))
        assert got.dtype == np.float32 and (got >= 0).all() and (got <= 1).all()
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6, err_msg=name)
    with pytest.raises(ValueError, match="unknown confidence measure"):
        confidence(cues, jnp.asarray(final), measure="peak")


def test_validity_bits_on_a_constructed_case():
    disparity = np.array([[3.0, 0.0, 1.5, 2.0, 2.0, 1.0]], np.float32)
    conf = np.array([[0.9, 0.9, 0.9, 0.01, 0.9, 0.05]], np.float32)
    failed = np.array([[True, False, False, False, True, True]])
    bits = np.asarray(validity_mask(jnp.asarray(disparity), jnp.asarray(conf), jnp.asarray(failed),
                                    threshold=0.1))
    assert bits.dtype == np.uint8
    # x=0: band and LR; x=1: valid; x=2: 2 - 1.5 >= 0, valid; x=3: low confidence;
    # x=4: LR only; x=5: LR and low confidence
    assert bits.tolist() == [[LEFT_BAND | LR_FAILED, 0, 0, LOW_CONFIDENCE, LR_FAILED,
                              LR_FAILED | LOW_CONFIDENCE]]
    none = validity_mask(jnp.asarray(disparity), jnp.asarray(conf), jnp.asarray(failed), threshold=0)
    assert not (np.asarray(none) & LOW_CONFIDENCE).any()
    with pytest.raises(ValueError, match="threshold"):
        validity_mask(jnp.asarray(disparity), jnp.asarray(conf), jnp.asarray(failed), threshold=2)


def test_no_distinct_minimum_is_confidence_zero_and_bit_4_under_every_measure():
    # A blank pair's cues: the winner costs 0, a runner-up a hair above it (the ratio alone
    # says 1), both views agree, nothing moved; the margin says there is no minimum.
    zero, one = jnp.zeros((1, 4)), jnp.ones((1, 4))
    second = jnp.array([[1e-3, 0.5, 0.5, jnp.inf]])
    margin = jnp.array([[0.0, AMBIGUITY_TOLERANCE, 2 * AMBIGUITY_TOLERANCE, jnp.inf]])
    cues = ConfidenceCues(zero, second, zero, zero, one > 2, margin)
    assert np.asarray(ambiguous(cues)).tolist() == [[True, True, False, False]]
    for name in MEASURES:
        # scaled, not zeroed: below every useful threshold, yet still ordered among themselves
        assert np.asarray(confidence(cues, zero, measure=name)).tolist() == [[1 / 256, 1 / 256, 1, 1]], name
    # Without the margin (cues made by hand) nothing is judged ambiguous.
    assert not np.asarray(ambiguous(cues._replace(margin=None))).any()
    assert float(confidence(cues._replace(margin=None), zero).min()) == 1.0
    bits = validity_mask(zero + 2, confidence(cues, zero), one > 2, threshold=0.05,
                         ambiguous=ambiguous(cues))
    # (d = 2: x = 0 and 1 in the left band.)
    assert np.asarray(bits).tolist() == [[AMBIGUOUS | LOW_CONFIDENCE | LEFT_BAND] * 2 + [0, 0]]
    # A bit of its own, beside the others.
    assert AMBIGUOUS == 16 and len({LR_FAILED, LEFT_BAND, LOW_CONFIDENCE, OUTSIDE_VIEW,
                                    AMBIGUOUS}) == 5
    with pytest.raises(ValueError, match="ambiguous"):
        validity_mask(zero, zero, one > 2, threshold=0.05, ambiguous=jnp.zeros((2, 4), bool))


def _pair(seed=3, shift=4, size=(40, 56)):
    rng = np.random.default_rng(seed)
    right = rng.random((*size, 3), dtype=np.float32)
    return jnp.asarray(np.roll(right, shift, axis=1)), jnp.asarray(right)


@pytest.mark.parametrize("optimizer", [None, "sgm"])
def test_outputs_same_for_every_chunk_and_equal_to_ssw_disparity(optimizer):
    left, right = _pair()
    params = Params().replace(**{"segments.n_segments": 16}, optimizer=optimizer)
    params = params.replace(**{"optimizer.paths": 4}) if optimizer else params
    outputs = [graph.ssw_outputs(left, right, params, ndisp=12, chunk=k) for k in (0, 5)]
    disparity = graph.ssw_disparity(left, right, params, ndisp=12)
    for out in outputs:
        np.testing.assert_array_equal(np.asarray(out.disparity), np.asarray(disparity))
        np.testing.assert_allclose(np.asarray(out.confidence), np.asarray(outputs[0].confidence),
                                   rtol=1e-5, atol=1e-6)
        np.testing.assert_array_equal(np.asarray(out.lr_failed), np.asarray(outputs[0].lr_failed))
        np.testing.assert_array_equal(np.asarray(out.ambiguous), np.asarray(outputs[0].ambiguous))
    conf = np.asarray(outputs[0].confidence)
    assert conf.dtype == np.float32 and conf.min() >= 0 and conf.max() <= 1
    # The left band (x < 4) has no true match: a winner there is a guess, low in confidence.
    assert conf[:, :3].max() < 0.1
    assert np.median(conf[:, 12:]) > 0.2
    # Texture has a distinct minimum nearly everywhere.
    assert np.asarray(outputs[0].ambiguous)[:, 12:].mean() < 0.02


def test_confidence_higher_on_texture_than_on_a_flat_pair():
    # The flat pair: a grey wall seen with independent sensor noise in each view, so no
    # disparity is better than another.
    left, right = _pair(seed=8)
    noise = np.random.default_rng(9).random((2, *left.shape), dtype=np.float32)
    flat = jnp.asarray(0.5 + 0.004 * noise)
    params = Params().replace(**{"segments.n_segments": 16})
    textured = np.asarray(graph.ssw_outputs(left, right, params, ndisp=12).confidence)
    faint = np.asarray(graph.ssw_outputs(flat[0], flat[1], params, ndisp=12).confidence)
    assert np.median(textured[:, 12:]) > 0.2 > np.median(faint[:, 12:])
