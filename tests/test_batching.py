"""Batches through vmap, sharded over devices: same maps as one pair at a time."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

import sswjax
from sswjax.batching import match_batch

PARAMS = sswjax.Params().replace(n_segments=16)


def _batch(size=3):
    rng = np.random.default_rng(11)
    rights = rng.random((size, 28, 48, 3), dtype=np.float32)
    lefts = np.stack([np.roll(r, 2 + i, axis=1) for i, r in enumerate(rights)])
    return lefts, rights


def test_batch_equals_pairs_one_by_one():
    lefts, rights = _batch()
    batched = match_batch(lefts, rights, 10, PARAMS)
    for i in range(len(lefts)):
        np.testing.assert_allclose(batched[i], sswjax.match(lefts[i], rights[i], 10, PARAMS), atol=1e-5)


SCRIPT = """
import numpy as np, jax, sswjax
from sswjax.batching import match_batch
rng = np.random.default_rng(11)
rights = rng.random((3, 28, 48, 3), dtype=np.float32)
lefts = np.stack([np.roll(r, 2 + i, axis=1) for i, r in enumerate(rights)])
out = match_batch(lefts, rights, 10, sswjax.Params().replace(n_segments=16))
np.save({path!r}, out)
print(len(jax.devices()))
"""


def test_two_devices_give_the_one_device_result(tmp_path):
    results = {}
    for count in (1, 2):
        path = tmp_path / f"out{count}.npy"
        env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={count}")
        run = subprocess.run([sys.executable, "-c", SCRIPT.format(path=str(path))], env=env,
                             capture_output=True, text=True, check=True)
        assert run.stdout.strip().endswith(str(count))
        results[count] = np.load(path)
    # Same winners; sub-pixel values may differ in the last bits between the two compilations.
    np.testing.assert_allclose(results[1], results[2], rtol=0, atol=1e-5)
