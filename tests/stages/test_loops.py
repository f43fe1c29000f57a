"""``stages.loops.repeated`` against the unrolled Python loop it replaces."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.loops import repeated
from sswjax.stages.medians import side_window_median_filter
from sswjax.stages.smoothing import gated_bilateral_smoothing


def _step(carry):
    """A pass on a pytree: a nonlinear map of an array and a counter."""
    x, n = carry
    return jnp.sqrt(x + 1.0) * jnp.cos(x), n + 1


@pytest.mark.parametrize("times", [0, 1, 2, 5])
def test_repeated_is_the_unrolled_loop_and_traces_its_step_once(times):
    x = jnp.asarray(np.random.default_rng(times).random((4, 6), np.float32))
    unrolled = (x, jnp.int32(0))
    for _ in range(times):
        unrolled = _step(unrolled)
    traced = []

    def counted(carry):
        traced.append(1)
        return _step(carry)

    looped = jax.jit(lambda v: repeated(counted, v, times=times))((x, jnp.int32(0)))
    np.testing.assert_allclose(looped[0], unrolled[0], rtol=1e-6)
    assert int(looped[1]) == times
    assert len(traced) == min(times, 1)
    jaxpr = jax.make_jaxpr(lambda v: repeated(_step, v, times=times))((x, 0))
    loops = [e.primitive.name for e in jaxpr.eqns if e.primitive.name in ("scan", "while")]
    assert len(loops) == (1 if times >= 2 else 0)


def test_a_negative_count_is_refused():
    with pytest.raises(ValueError, match="times must be >= 0"):
        repeated(_step, (jnp.zeros(2), 0), times=-1)


def test_the_filters_that_repeat_their_passes_equal_their_passes_one_by_one():
    """The side-window median and the smoothing, whose iterations are a loop, give what
    their single passes applied in turn give, bit for bit."""
    rng = np.random.default_rng(3)
    disparity = jnp.asarray(rng.integers(0, 9, (20, 24)).astype(np.float32))
    guide = jnp.asarray(rng.random((20, 24, 3), np.float32))
    once = jax.jit(lambda d: side_window_median_filter(d, radius=2, iterations=1))
    np.testing.assert_array_equal(
        jax.jit(lambda d: side_window_median_filter(d, radius=2, iterations=3))(disparity),
        once(once(once(disparity))))
    options = dict(radius=2, gate=2.0, colour_scale=0.1)
    for separable in (True, False):
        step = jax.jit(lambda d: gated_bilateral_smoothing(  # noqa: B023 (called at once)
            d, guide, iterations=1, separable=separable, **options))
        np.testing.assert_allclose(
            gated_bilateral_smoothing(disparity, guide, iterations=2, separable=separable,
                                      **options), step(step(disparity)), rtol=0, atol=1e-5)
