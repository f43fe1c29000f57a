"""Bad input through the Python API: ``ValueError`` or ``TypeError`` with the CLI's message.

The API rows of the table in ``docs/bad-input.md``; the image checks of ``sswjax.match`` are in
``test_graph.py::test_match_rejects_bad_images``.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

import sswjax
from sswjax import ConfigError, Params, check_params

NDISP = 8


def test_api_rejects_bad_params_and_empty_images(texture):
    left = texture(0)
    for changes, message in [
        ({"cost.tad_truncation": float("nan")},
         "parameter cost.tad_truncation must be finite in float32 (the graph's dtype), got nan"),
        ({"cost.census_weight": -0.5},
         "parameter cost.census_weight must be a number >= 0, got -0.5"),
        ({"cost.census_width": 8}, "parameter cost.census_width must be an odd integer in [1, 15], "
                                   "got 8"),
        ({"aggregation.radius": 2.5},
         "parameter aggregation.radius must be an integer in [1, 50], got 2.5"),
        ({"cost.tad_weight": np.ones(2)},
         "parameter cost.tad_weight must be a scalar, got shape (2,)"),
        ({"fill.median_radius": 6},
         "parameter fill.median_radius must be in [0, 5] with fill.median 'square', got 6"),
        ({"fill.median": "mean"},
         "parameter fill.median must be one of 'square', 'separable', got 'mean'"),
    ]:
        with pytest.raises(ConfigError) as info:
            sswjax.match(left, left, NDISP, params=Params().replace(**changes))
        assert str(info.value) == message
    # the old flat names are refused (files of them: sswjax params --upgrade)
    with pytest.raises(ConfigError, match=r"^unknown parameter 'fill_radius': name a stage "):
        Params().replace(fill_radius=20)
    message = (r"^params must be a sswjax.Params \(see sswjax.preset and sswjax.load_params\), "
               r"got dict$")
    with pytest.raises(TypeError, match=message):
        sswjax.match(left, left, NDISP, params={"tad_truncation": 0.1})
    with pytest.raises(ValueError, match=r"^left image is empty, got shape \(24, 0, 1\)$"):
        sswjax.match(np.zeros((24, 0), np.uint8), left, NDISP)
    with pytest.raises(ValueError, match=r"^ndisp must be an integer, got 8.0$"):
        sswjax.match(left, left, 8.0)
    # valid NumPy and JAX scalars pass the check (match would recompile for them: not run here)
    params = Params().replace(**{"cost.tad_weight": np.float32(0.05),
                                 "cost.census_weight": jax.numpy.float32(0.8)})
    assert check_params(params) is params
