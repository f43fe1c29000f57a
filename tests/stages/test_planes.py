"""Tests for sswjax.stages.planes against NumPy least squares."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.planes import fit_segment_planes, plane_disparity, plane_refine


def lstsq_reference(disparity, weights, labels, segment):
    ys, xs = np.nonzero((labels == segment) & (weights > 0))
    w = np.sqrt(weights[ys, xs])
    design = np.stack([xs, ys, np.ones_like(xs)], 1).astype(np.float64) * w[:, None]
    solution, *_ = np.linalg.lstsq(design, disparity[ys, xs] * w, rcond=None)
    return solution  # a, b and the value at x = y = 0


def test_weighted_fit_matches_lstsq():
    rng = np.random.default_rng(0)
    labels = np.repeat(np.arange(4), 30).reshape(8, 15).astype(np.int32)
    y, x = np.mgrid[0:8, 0:15].astype(np.float64)
    disparity = (0.3 * x - 0.2 * y + 5 + labels + rng.normal(0, 0.3, x.shape)).astype(np.float32)
    weights = rng.random(x.shape).astype(np.float32)
    fit = fit_segment_planes(jnp.asarray(disparity), jnp.asarray(weights), jnp.asarray(labels),
                             num_segments=4, iterations=1, ridge=0.0)
    ours = np.asarray(plane_disparity(fit, jnp.asarray(labels)))
    for segment in range(4):
        a, b, c = lstsq_reference(disparity, weights, labels, segment)
        inside = labels == segment
        np.testing.assert_allclose(ours[inside], (a * x + b * y + c)[inside], atol=1e-3)


def test_robust_fit_ignores_outliers_and_refine_fills_invalid_pixels():
    y, x = np.mgrid[0:12, 0:16].astype(np.float32)
    truth = 0.25 * x + 0.5 * y + 10
    noisy = truth.copy()
    noisy[2, 3], noisy[7, 9], noisy[5, 5] = 40.0, 0.0, 25.0         # gross errors
    valid = np.ones(truth.shape, bool)
    valid[4:8, 10:14] = False                                         # rejected by the LR check
    labels = np.zeros(truth.shape, np.int32)
    run = jax.jit(lambda d, v, l: plane_refine(d, v, l, num_segments=1, iterations=4))
    out = np.asarray(run(jnp.asarray(noisy), jnp.asarray(valid), jnp.asarray(labels)))
    np.testing.assert_allclose(out[~valid], truth[~valid], atol=0.2)
    np.testing.assert_array_equal(out[valid], noisy[valid])          # valid pixels untouched


def test_unsupported_segments_keep_their_fill():
    disparity = np.full((6, 8), 3.0, np.float32)
    valid = np.zeros((6, 8), bool)
    valid[:, :4] = True                                               # segment 0 all valid
    labels = np.zeros((6, 8), np.int32)
    labels[:, 4:] = 1                                                 # segment 1: none valid
    disparity[:, 4:] = 7.0
    out = np.asarray(plane_refine(jnp.asarray(disparity), jnp.asarray(valid), jnp.asarray(labels),
                                  num_segments=2))
    np.testing.assert_array_equal(out, disparity)


def test_entry_checks():
    d = jnp.zeros((4, 5))
    with pytest.raises(ValueError, match="one shape"):
        fit_segment_planes(d, jnp.zeros((4, 6)), jnp.zeros((4, 5), jnp.int32), num_segments=1)
    with pytest.raises(TypeError, match="integer"):
        fit_segment_planes(d, d, jnp.zeros((4, 5)), num_segments=1)
    with pytest.raises(ValueError, match="num_segments"):
        fit_segment_planes(d, d, jnp.zeros((4, 5), jnp.int32), num_segments=0)
