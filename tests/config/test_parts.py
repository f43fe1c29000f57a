"""Every registered part calls its stage functions with its own options, and only those."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.config import (LocalContrast, PlaneFill, SemiGlobal, VoteFill, WeightedMedianFill,
                           kinds)
from sswjax.stages.fill import vote_fill, weighted_median_fill
from sswjax.stages.planes import plane_refine
from sswjax.stages.preprocess import local_contrast_normalization
from sswjax.stages.background import fill_invalid
from sswjax.stages.sgm import semi_global_sums

RNG = np.random.default_rng(0)
COST = jnp.asarray(RNG.random((4, 10, 12), dtype=np.float32))
GUIDE = jnp.asarray(RNG.random((10, 12, 3), dtype=np.float32))
LABELS = jnp.asarray((np.arange(12)[None, :] // 4 + 3 * (np.arange(10)[:, None] // 5)), jnp.int32)
DISPARITY = jnp.asarray(RNG.random((10, 12), dtype=np.float32) * 5)
VALID = jnp.asarray(RNG.random((10, 12)) > 0.3)


@pytest.mark.parametrize("kind", list(kinds("aggregation")))
def test_every_aggregator_takes_the_common_call(kind):
    part = kinds("aggregation")[kind](radius=2)
    out = jax.jit(lambda c, g, p: p.aggregate(c, g, labels=LABELS, num_segments=6))(COST, GUIDE, part)
    assert out.shape == COST.shape and out.dtype == jnp.float32
    assert bool(jnp.isfinite(out).all())


@pytest.mark.parametrize("part, direct", [
    (kinds("fill")["background"](median_radius=1),
     lambda: fill_invalid(DISPARITY, VALID, radius=1)),
    (kinds("fill")["left-band"](median_radius=2, median="separable", band_fit=4),
     lambda: fill_invalid(DISPARITY, VALID, radius=2, left_band=True, median="separable",
                          band_fit=4)),
    (VoteFill(median_radius=2, median="separable", band_fit=4, radius=3, step=2, sigma=0.1,
              tolerance=1.0),
     lambda: vote_fill(DISPARITY, VALID, guide=GUIDE, median_radius=2, radius=3, step=2,
                       sigma=0.1, tolerance=1.0, band_fit=4)),
    (WeightedMedianFill(radius=2, eps=0.01, source="valid"),
     lambda: weighted_median_fill(DISPARITY, VALID, radius=2, guide=GUIDE, eps=0.01,
                                  source="valid")),
    (PlaneFill(median_radius=1, min_support=0.3),
     lambda: plane_refine(fill_invalid(DISPARITY, VALID, radius=1), VALID, LABELS,
                          num_segments=6, min_support=0.3)),
])
def test_every_fill_is_its_stage_function(part, direct):
    out = jax.jit(lambda d, v, g, p: p.fill(d, v, guide=g, labels=LABELS, num_segments=6))(
        DISPARITY, VALID, GUIDE, part)
    np.testing.assert_allclose(np.asarray(out), np.asarray(direct()), atol=1e-5)  # jit vs eager
    assert set(kinds("fill")) == {"background", "left-band", "vote", "wmedian", "plane"}


def test_the_optimiser_and_the_preprocessor_are_their_stage_functions():
    sgm = SemiGlobal(paths=4, dtype="float32", p1=0.1, p2=0.5)
    ours = sgm.optimise(COST, GUIDE, labels=None, cost_bound=1.0)
    direct = semi_global_sums(COST, GUIDE, p1=0.1, p2=0.5, sigma=0.05, paths=4, labels=None,
                              segment_factor=1.0, cost_bound=None, cost_levels=None)
    np.testing.assert_array_equal(np.asarray(ours.sums), np.asarray(direct.sums))
    assert sgm.storage(1.0) is None  # float32: nothing quantised
    assert SemiGlobal(dtype="uint8").storage(1.0).levels == 255
    lcn = LocalContrast(radius=3, eps=0.02)
    np.testing.assert_array_equal(np.asarray(lcn.apply(GUIDE)),
                                  np.asarray(local_contrast_normalization(GUIDE, radius=3,
                                                                          eps=0.02)))
