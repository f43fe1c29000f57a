"""The bound on live compiled graphs: least recently used dropped, mappings released, results
unchanged; 300 image shapes in one process stay within a fixed number of memory mappings."""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.runtime.executables import BoundedJit, ExecutableCache

# One process, 300 shapes of a cheap configuration through sswjax.match, at most 8 graphs kept:
# unbounded, each shape would add about 50 mappings (15,000 in all; 540 each for the presets).
SCRIPT = r"""
import json
import numpy as np
import sswjax

def mappings():
    with open("/proc/self/maps") as handle:
        return sum(1 for _ in handle)

params = sswjax.Params().replace(segments=None, aggregation={"kind": "box", "radius": 1},
                                 checks=None, fill=None, refinement=None, selection={"subpixel": False},
                                 **{"cost.census_height": 3, "cost.census_width": 3})
rng = np.random.default_rng(0)
counts, exact = [], 0
for height in range(16, 36):
    for width in range(24, 39):
        right = rng.random((height, width), dtype=np.float32)
        disparity = sswjax.match(np.roll(right, 2, axis=1), right, 4, params=params)
        exact += bool(np.all(disparity[:, 8:-2] == 2))
        counts.append(mappings())
print(json.dumps({"counts": counts, "exact": exact}))
"""


def test_300_shapes_in_one_process_keep_the_mappings_bounded(run_on_devices, monkeypatch):
    monkeypatch.setenv("SSWJAX_MAX_EXECUTABLES", "8")
    result = json.loads(run_on_devices(SCRIPT, devices=1, timeout=900))
    counts = result["counts"]
    assert len(counts) == 300
    assert result["exact"] >= 290  # every pair still matched (a few borders aside)
    # after the first 8 graphs the count stops growing: what 292 more shapes add is noise
    assert max(counts[20:]) - counts[19] < 200, (counts[19], max(counts[20:]))


def _identity_cache(limit):
    cache = ExecutableCache(limit)
    calls = []

    def fn(x, *, scale):
        calls.append(x.shape)
        return x * scale

    return cache, calls, BoundedJit(fn, static_argnames=("scale",), cache=cache)


def test_least_recently_used_is_dropped_first():
    cache, calls, double = _identity_cache(2)
    a, b, c = jnp.ones(1), jnp.ones(2), jnp.ones(3)
    for x in (a, b, a, c):  # a was used after b: b is the one dropped for c
        double(x, scale=2.0)
    assert len(cache) == 2 and calls == [(1,), (2,), (3,)]
    double(a, scale=2.0)
    assert calls == [(1,), (2,), (3,)]  # a is still compiled
    double(b, scale=2.0)
    assert calls[-1] == (2,)  # b compiles again
    np.testing.assert_array_equal(np.asarray(double(b, scale=3.0)), [3.0, 3.0])  # static: new
    cache.limit = 1
    assert len(cache) == 1
    cache.clear()
    assert len(cache) == 0
    with pytest.raises(ValueError, match="limit must be an integer >= 1"):
        cache.limit = 0
