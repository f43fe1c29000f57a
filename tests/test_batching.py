"""Batches through vmap, sharded over devices: same maps as one pair at a time."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest

import sswjax
from sswjax.api import batch
from sswjax.api.batch import iter_match_scenes, match_batch, match_scenes
from sswjax.runtime.buckets import bucket_shape

PARAMS = sswjax.Params().replace(**{"segments.n_segments": 16})


def _batch(size=3):
    rng = np.random.default_rng(11)
    rights = rng.random((size, 28, 48, 3), dtype=np.float32)
    lefts = np.stack([np.roll(r, 2 + i, axis=1) for i, r in enumerate(rights)])
    return lefts, rights


def test_batch_equals_pairs_one_by_one():
    lefts, rights = _batch()
    batched = match_batch(lefts, rights, 10, params=PARAMS)
    for i in range(len(lefts)):
        np.testing.assert_allclose(batched[i], sswjax.match(lefts[i], rights[i], 10, params=PARAMS), atol=1e-5)


SCRIPT = """
import numpy as np, jax, sswjax
from sswjax.api.batch import match_batch
rng = np.random.default_rng(11)
rights = rng.random((3, 28, 48, 3), dtype=np.float32)
lefts = np.stack([np.roll(r, 2 + i, axis=1) for i, r in enumerate(rights)])
out = match_batch(lefts, rights, 10, params=sswjax.Params().replace(**{{"segments.n_segments": 16}}))
np.save({path!r}, out)
print(len(jax.devices()))
"""


def test_two_devices_give_the_one_device_result(tmp_path, run_on_devices):
    results = {}
    for count in (1, 2):
        path = tmp_path / f"out{count}.npy"
        assert run_on_devices(SCRIPT.format(path=str(path)), devices=count) == str(count)
        results[count] = np.load(path)
    # Same winners; sub-pixel values may differ in the last bits between the two compilations.
    np.testing.assert_allclose(results[1], results[2], rtol=0, atol=1e-5)


# --- pairs of different sizes: grouped by bucket, one pair per device per call ---------------

BUCKETS = sswjax.ShapeBuckets(size_step=32, ndisp_step=8)
LIGHT = PARAMS.replace(**{"segments.iterations": 2, "aggregation.iterations": 1})  # quicker to compile
# (height, width, ndisp, shift): buckets 32x64x8 (three pairs, not a multiple of 2 devices) and
# 32x96x16 (two pairs), interleaved so that grouping reorders them.
SCENES = ((28, 48, 6, 2), (28, 70, 12, 5), (32, 50, 8, 3), (30, 80, 16, 7), (26, 60, 5, 1))


def _scenes():
    rng = np.random.default_rng(5)
    pairs = []
    for height, width, _, shift in SCENES:
        right = (rng.random((height, width, 3)) * 255).astype(np.uint8)
        pairs.append((np.roll(right, shift, axis=1), right))
    return pairs, [ndisp for _, _, ndisp, _ in SCENES]


def _run_scenes(devices):
    """The scenes' maps (in input order), their order of completion and, per sharded call,
    [batch size, pairs per device]."""
    pairs, ndisps = _scenes()
    calls, inner = [], batch._batched

    def spy(lefts, rights, valid_ndisps, valid_shapes, params, *, ndisp, chunk):
        calls.append([lefts.shape[0], lefts.sharding.shard_shape(lefts.shape)[0]])
        return inner(lefts, rights, valid_ndisps, valid_shapes, params, ndisp=ndisp, chunk=chunk)

    batch._batched = spy
    try:
        done = list(iter_match_scenes(pairs, ndisps, params=LIGHT, buckets=BUCKETS, devices=devices))
    finally:
        batch._batched = inner
    maps = [None] * len(pairs)
    for index, disparity, _ in done:
        maps[index] = disparity
    return maps, [index for index, _, _ in done], calls


@pytest.fixture(scope="module")
def one_device():
    return _run_scenes(jax.devices()[:1])


def test_scenes_equal_bucketed_match_one_by_one(one_device):
    maps, order, calls = one_device
    assert len({bucket_shape(h, w, n, BUCKETS) for h, w, n, _ in SCENES}) == 2
    assert order == [0, 2, 4, 1, 3]  # groups in order of their first pair
    assert calls == [[1, 1]] * 5
    pairs, ndisps = _scenes()
    for (left, right), ndisp, disparity, (_, _, _, shift) in zip(pairs, ndisps, maps, SCENES):
        expected = sswjax.match(left, right, ndisp, params=LIGHT, buckets=BUCKETS)
        assert disparity.shape == left.shape[:2] and disparity.dtype == np.float32
        np.testing.assert_allclose(disparity, expected, rtol=0, atol=1e-5)
        assert disparity.max() <= ndisp - 1
        assert np.median(disparity[:, 16:]) == pytest.approx(shift, abs=0.05)


def test_scenes_check_every_pair_before_running(monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("a step ran before the last pair was checked")

    monkeypatch.setattr(batch, "_batched", never)
    pairs, ndisps = _scenes()
    with pytest.raises(ValueError, match="ndisp must be in"):
        match_scenes(pairs, ndisps[:-1] + [60], params=LIGHT, buckets=BUCKETS)
    with pytest.raises(ValueError, match="5 pairs but 4"):
        match_scenes(pairs, ndisps[:-1], params=LIGHT, buckets=BUCKETS)


SCENES_SCRIPT = """
import json
import jax, numpy as np
from test_batching import _run_scenes
maps, order, calls = _run_scenes(None)
np.savez({path!r}, *maps)
print(json.dumps({{"devices": len(jax.devices()), "order": order, "calls": calls}}))
"""


def test_scenes_on_two_devices_give_the_one_device_result(one_device, tmp_path, run_on_devices):
    path = tmp_path / "maps.npz"
    report = json.loads(run_on_devices(SCENES_SCRIPT.format(path=str(path))))
    assert report["devices"] == 2 and report["order"] == [0, 2, 4, 1, 3]
    # one pair per device in every call; the 3-pair group's last step is filled with a copy
    assert report["calls"] == [[2, 1]] * 3
    with np.load(path) as saved:
        two = [saved[f"arr_{i}"] for i in range(len(SCENES))]
    for disparity_one, disparity_two in zip(one_device[0], two):
        assert disparity_two.shape == disparity_one.shape
        np.testing.assert_allclose(disparity_two, disparity_one, rtol=0, atol=1e-5)
