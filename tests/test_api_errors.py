"""Bad input through the Python API: ``ValueError`` or ``TypeError`` with the CLI's message.

The API rows of the README table "Bad input: what the user sees"; the image checks of
``sswjax.match`` are in ``test_pipeline.py::test_match_rejects_bad_images``.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

import sswjax
from sswjax import Params
from sswjax.params import check_params

NDISP = 8


def test_api_rejects_bad_params_and_empty_images(texture):
    left = texture(0)
    for params, message in [
        (Params().replace(tad_truncation=float("nan")),
         "parameter tad_truncation must be a finite number > 0, got nan"),
        (Params().replace(census_weight=-0.5),
         "parameter census_weight must be a finite number >= 0, got -0.5"),
        (Params().replace(census_width=8), "parameter census_width must be odd, got 8"),
        (Params().replace(aggregation_radius=2.5),
         "parameter aggregation_radius must be an integer, got 2.5"),
        (Params().replace(tad_weight=np.ones(2)), "parameter tad_weight must be a scalar, got shape (2,)"),
        (Params().replace(fill_radius=6),
         "parameter fill_radius must be in [0, 5] with fill_median 'square', got 6"),
        (Params().replace(fill_median="mean"),
         "parameter fill_median must be one of ('square', 'separable'), got 'mean'"),
    ]:
        with pytest.raises(ValueError) as info:
            sswjax.match(left, left, NDISP, params=params)
        assert str(info.value) == message
    message = r"^params must be a sswjax.Params \(see sswjax.load_params\), got dict$"
    with pytest.raises(TypeError, match=message):
        sswjax.match(left, left, NDISP, params={"tad_truncation": 0.1})
    with pytest.raises(ValueError, match=r"^left image is empty, got shape \(24, 0, 1\)$"):
        sswjax.match(np.zeros((24, 0), np.uint8), left, NDISP)
    with pytest.raises(ValueError, match=r"^ndisp must be an integer, got 8.0$"):
        sswjax.match(left, left, 8.0)
    # valid NumPy and JAX scalars pass the check (match would recompile for them: not run here)
    params = Params().replace(tad_weight=np.float32(0.05), census_weight=jax.numpy.float32(0.8))
    assert check_params(params) is params
