"""Adding a stage is one module, one configuration class, one registry entry: a toy pre-processor
registered at run time goes through validation, JSON, the graph and the command line's help."""

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax import ConfigError, Params, check_params, load_params, save_params
from sswjax.config import Preprocessor, kinds, register
from sswjax.config.fields import option
from sswjax.config.parts import unregister
from sswjax.graph import aggregated_cost, ssw_disparity


@pytest.fixture()
def toy():
    """A pre-processor ``toy-gamma`` (``image ** gamma``), registered for one test."""

    @register("preprocess", "toy-gamma")
    class Gamma(Preprocessor):
        """Gamma correction of the images the cost sees (a toy part for the tests)."""

        gamma: float = option(1.0, above=0, help="exponent applied to the intensities")

        def apply(self, image):
            """float32 (H, W, C) -> ``image ** gamma``, same shape."""
            return image ** self.gamma

    yield Gamma
    unregister("preprocess", "toy-gamma")


def _pair():
    rng = np.random.default_rng(0)
    right = rng.random((24, 40, 3), dtype=np.float32)
    return jnp.asarray(np.roll(right, 3, axis=1)), jnp.asarray(right)


def test_validation_and_json(toy, tmp_path):
    assert kinds("preprocess")["toy-gamma"] is toy
    with pytest.raises(ConfigError, match="parameter preprocess.gamma must be a number > 0"):
        check_params(Params().replace(preprocess=toy(gamma=0.0)))
    params = Params().replace(preprocess={"kind": "toy-gamma", "gamma": 2.0})
    assert params.preprocess == toy(gamma=2.0)
    save_params(tmp_path / "p.json", params)
    assert load_params(tmp_path / "p.json") == params


def test_the_graph_runs_it(toy):
    left, right = _pair()
    # Without superpixels, and aggregated by a box, only the cost reads the images.
    plain = Params().replace(segments=None, aggregation={"kind": "box"})
    gamma = plain.replace(preprocess=toy(gamma=2.0))
    np.testing.assert_array_equal(np.asarray(aggregated_cost(left, right, gamma, ndisp=8)),
                                  np.asarray(aggregated_cost(left ** 2.0, right ** 2.0, plain, ndisp=8)))
    identity = plain.replace(preprocess=toy(gamma=1.0))
    np.testing.assert_array_equal(np.asarray(ssw_disparity(left, right, identity, ndisp=8)),
                                  np.asarray(ssw_disparity(left, right, plain, ndisp=8)))


def test_the_command_line_knows_it(toy, run_cli, tmp_path):
    code, out, err = run_cli(["params", "--list"])
    assert code == 0, err
    assert "toy-gamma" in out and "Gamma correction of the images the cost sees" in out
    assert "exponent applied to the intensities" in out
    path = tmp_path / "toy.json"
    code, out, err = run_cli(["params", "--set", "preprocess=toy-gamma", "--set",
                              "preprocess.gamma=2.5", "-o", path])
    assert code == 0, err
    assert load_params(path).preprocess == toy(gamma=2.5)
