"""The bound on live compiled graphs: least recently used dropped, mappings released, results
unchanged; 300 image shapes in one process stay within a fixed number of memory mappings."""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.runtime.executables import BoundedJit, ExecutableCache

# One process, 300 shapes through one bounded function, at most 8 graphs kept (a small stage
# function: each compiles in tens of milliseconds), then 12 shapes of a cheap configuration of the
# whole graph
# through sswjax.match with 4 kept: both mapping counts stop growing once the bound is reached
# (unbounded, each graph of the match added about 50 mappings, 540 for the presets; the 300
# shapes of the whole graph: executables.py, a concluded benchmark in
# docs/notes/benchmarks-concluded.md, and docs/notes/speed-and-memory.md).
SCRIPT = r"""
import json
import jax.numpy as jnp
import numpy as np
import sswjax
from sswjax.runtime.executables import EXECUTABLES, bounded
from sswjax.stages.color import rgb_to_gray

def mappings():
    with open("/proc/self/maps") as handle:
        return sum(1 for _ in handle)

gray = bounded(rgb_to_gray, static_argnames=())
rng = np.random.default_rng(0)
stage = []
for height in range(8, 28):
    for width in range(8, 23):
        luma = gray(jnp.asarray(rng.random((height, width, 3), dtype=np.float32)))
        assert luma.shape == (height, width)
        stage.append(mappings())
EXECUTABLES.clear()
EXECUTABLES.limit = 4
params = sswjax.Params().replace(segments=None, aggregation={"kind": "box", "radius": 1},
                                 checks=None, fill=None, refinement=None,
                                 selection={"subpixel": False},
                                 **{"cost.census_height": 3, "cost.census_width": 3})
graph, exact = [], 0
for height in range(16, 22):
    for width in (24, 25):
        right = rng.random((height, width), dtype=np.float32)
        disparity = sswjax.match(np.roll(right, 2, axis=1), right, 4, params=params)
        exact += bool(np.all(disparity[:, 8:-2] == 2))
        graph.append(mappings())
print(json.dumps({"stage": stage, "graph": graph, "exact": exact}))
"""


def test_300_shapes_in_one_process_keep_the_mappings_bounded(run_on_devices, monkeypatch):
    monkeypatch.setenv("SSWJAX_MAX_EXECUTABLES", "8")
    result = json.loads(run_on_devices(SCRIPT, devices=1, timeout=900))
    stage, graph = result["stage"], result["graph"]
    assert len(stage) == 300 and len(graph) == 12 and result["exact"] == 12
    # once the bound is reached the counts stop growing: what more shapes add is noise
    assert max(stage[20:]) - stage[19] < 60, (stage[19], max(stage[20:]))
    assert max(graph[8:]) - graph[7] < 60, (graph[7], max(graph[8:]))


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
