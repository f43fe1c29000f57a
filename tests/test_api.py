"""The public API's conventions, checked over every public function of every module.

As in dm-pix's ``api_test.py``: array arguments are positional, every option (a parameter with
a default value) is keyword-only, so a call reads ``f(left, right, radius=4)`` and options can
be added or reordered without breaking callers.
"""

import importlib
import inspect
import pkgutil

import numpy as np
import pytest

import sswjax
from sswjax.api.auto_range import estimate_range

# The command line takes argv, not arrays and options; its functions are not API.
_NOT_API = "sswjax.cli"


def _public_functions():
    names = ["sswjax"] + [info.name for info in pkgutil.walk_packages(sswjax.__path__, "sswjax.")]
    for module_name in names:
        if module_name.startswith(_NOT_API) or any(part.startswith("_")
                                                    for part in module_name.split(".")):
            continue
        module = importlib.import_module(module_name)
        for name, value in vars(module).items():
            if name.startswith("_") or not inspect.isfunction(value):
                continue
            if value.__module__ != module_name:  # re-exported: checked where it is defined
                continue
            yield f"{module_name}.{name}", value


PUBLIC = dict(_public_functions())


def test_the_api_is_not_empty():
    assert len(PUBLIC) > 50
    assert "sswjax.api.match.match" in PUBLIC


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_options_are_keyword_only(name):
    signature = inspect.signature(PUBLIC[name])
    positional_with_default = [
        parameter.name
        for parameter in signature.parameters.values()
        if parameter.kind in (parameter.POSITIONAL_ONLY, parameter.POSITIONAL_OR_KEYWORD)
        and parameter.default is not parameter.empty
    ]
    assert not positional_with_default, (
        f"{name} takes options positionally: {positional_with_default}; make them keyword-only")


def test_top_level_reexports_the_public_api():
    for name in sswjax.__all__:
        assert hasattr(sswjax, name)
    for name in ("match", "match_with_confidence", "ssw_disparity", "aggregated_cost", "Params",
                 "preset", "load_params", "save_params", "ShapeBuckets", "ExecutionPlan"):
        assert name in sswjax.__all__


def test_match_estimates_the_range_when_ndisp_is_none(tiny):
    """ndisp=None: the range of sswjax.api.auto_range.estimate_range, then the same map as
    when that range is given; min_disp cannot go with it. (The estimate's coarse pass is its
    own, whatever the parameters: the map here is conftest's cheap method's.)"""
    rng = np.random.default_rng(3)
    right = rng.random((96, 192, 3), dtype=np.float32)
    left = np.roll(right, 20, axis=1)
    params = tiny.params
    found = estimate_range(left, right)
    estimated = sswjax.match(left, right, None, params=params)
    given = sswjax.match(left, right, found.ndisp, min_disp=found.min_disp, params=params)
    np.testing.assert_array_equal(estimated, given)
    assert abs(float(np.median(estimated[:, 40:])) - 20) <= 0.5
    with pytest.raises(ValueError, match="min_disp"):
        sswjax.match(left, right, None, min_disp=3, params=params)
