"""The suite compiles with faster but less optimising XLA flags (``tests/conftest.py``): the maps
they give are the maps a user's flags give, to rounding.

Both runs are fresh processes with compilation caches of their own, so that neither reads an
executable the other compiled."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

MATCH_BOTH_PRESETS = r"""
import sys
import numpy as np
import skimage.data
import sswjax
left, right, _ = skimage.data.stereo_motorcycle()
left, right = left[104:488:4, ::4], right[104:488:4, ::4]
np.save(sys.argv[1], np.stack([sswjax.match(left, right, 48, params=sswjax.preset(name))
                               for name in ("accurate", "fast")]))
"""


def _maps(path, env, cache) -> np.ndarray:
    """``(2, 96, 186)`` float32: ``accurate``'s and ``fast``'s maps of a crop of Motorcycle."""
    run = subprocess.run([sys.executable, "-c", MATCH_BOTH_PRESETS, str(path)], capture_output=True,
                         text=True, timeout=600, env=dict(env, SSWJAX_CACHE_DIR=str(cache)))
    assert run.returncode == 0, run.stderr
    return np.load(path)


@pytest.mark.slow  # two fresh processes, each compiling two whole presets
def test_the_suites_compiler_flags_give_the_users_maps_to_rounding(tmp_path, user_environment):
    suite = _maps(tmp_path / "suite.npy", os.environ, tmp_path / "suite-cache")
    user = _maps(tmp_path / "user.npy", user_environment, tmp_path / "user-cache")
    assert suite.shape == user.shape == (2, 96, 186)
    difference = np.abs(suite - user)
    # Measured on jaxlib 0.10.2: at most 0.042 px (accurate) and 0.006 px (fast), 1.9 % and
    # 1.1 % of the pixels by more than 0.001 px, none by half a pixel.
    assert difference.max() < 0.1
    assert (difference > 1e-3).mean() < 0.05
    assert np.all(np.isfinite(suite) == np.isfinite(user))


def test_the_shared_tiny_configuration_says_the_same_on_the_command_line(tiny, tmp_path, run_cli):
    """``tiny.args`` and ``tiny.params`` are one configuration (conftest.py)."""
    import sswjax

    code, _, err = run_cli(["params", *tiny.args, "-o", tmp_path / "p.json"])
    assert code == 0, err
    assert sswjax.load_params(tmp_path / "p.json") == tiny.params
