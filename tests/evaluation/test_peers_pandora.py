"""The CNES Pandora peer (optional: skipped unless ``pandora`` and its libSGM plugin are installed)."""

import numpy as np
import pytest

pytest.importorskip("pandora")
pytest.importorskip("pandora_plugin_libsgm")


def test_pandora_peer_is_dense_and_recovers_a_shift():
    from sswjax.evaluation.peers import pandora_disparity

    rng = np.random.default_rng(0)
    right = rng.integers(0, 256, size=(40, 80, 3), dtype=np.uint8)
    left = np.roll(right, 6, axis=1)  # left(x) = right(x - 6): Middlebury disparity +6
    disparity = pandora_disparity(left, right, 16)
    assert disparity.dtype == np.float32
    assert disparity.shape == (40, 80)
    assert np.isfinite(disparity).all()
    assert disparity.min() >= 0 and disparity.max() <= 15
    assert abs(float(np.median(disparity[:, 24:])) - 6) <= 0.5


def test_pandora_is_a_registered_peer():
    from sswjax.evaluation.methods import make_method, method_names
    from sswjax.evaluation.peers import pandora_disparity

    assert "pandora" in method_names()
    assert make_method("pandora") is pandora_disparity
