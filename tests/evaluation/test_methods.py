"""The catalogue of methods (ablations, the aggregators as methods, peers), and every part of the
registry run through the whole graph once."""

import functools

import numpy as np
import pytest

import sswjax
from sswjax.cli.app import build_parser
from sswjax.config import kinds
from sswjax.evaluation.methods import (PEERS, VARIANTS, BucketedSSW, make_method, method_names,
                                       method_summaries, variant_changes)


def test_method_names_are_the_aggregators_variants_and_peers():
    assert method_names() == (*kinds("aggregation"), *VARIANTS, *PEERS)
    summaries = method_summaries()
    assert set(summaries) == set(method_names())
    assert all(text and "\n" not in text for text in summaries.values())


@pytest.mark.parametrize("name", list(kinds("aggregation")))
def test_each_aggregator_is_a_method(name):
    method = make_method(name)
    assert isinstance(method, functools.partial) and method.func is sswjax.match
    params = method.keywords["params"]
    assert params.aggregation.kind == name and sswjax.check_params(params) is params
    # the paper's method as the base: superpixels only where the aggregation reads them
    paper = make_method(name, params=sswjax.preset("paper")).keywords["params"]
    assert (paper.segments is not None) == (name == "ssw")
    bucketed = make_method(name, buckets=sswjax.ShapeBuckets())
    assert isinstance(bucketed, BucketedSSW) and bucketed.params == params


def test_variant_changes():
    assert variant_changes("ssw") == {}
    assert variant_changes("mf") == {"aggregation": "mf"}
    assert variant_changes("ssw-noseg") == {"segments": None}
    with pytest.raises(KeyError):
        variant_changes("sgbm")
    paper = sswjax.preset("paper")
    for name in VARIANTS:
        sswjax.check_params(paper.replace(**variant_changes(name)))
    with pytest.raises(ValueError, match="unknown method 'nope'"):
        make_method("nope")


def test_cli_help_lists_every_method():
    evaluate = build_parser()._subparsers._group_actions[0].choices["evaluate"]
    text = evaluate.format_help()
    for name in method_names():
        assert name in text


# Every non-default part alone, and several together (the defaults run everywhere else).
_PAPER = sswjax.Params().replace(**{"segments.n_segments": 24})
STAGE_CASES = {
    **{f"fill-{kind}": _PAPER.replace(fill=kind) for kind in kinds("fill") if kind != "background"},
    **{f"optimizer-{kind}": _PAPER.replace(optimizer=kind) for kind in kinds("optimizer")},
    **{f"aggregation-{kind}": _PAPER.replace(aggregation=kind, segments=None)
       for kind in kinds("aggregation") if kind != "ssw"},
    "preprocess-lcn": _PAPER.replace(preprocess="lcn"),
    "plane-sgm-lcn": _PAPER.replace(fill="plane", optimizer="sgm", preprocess="lcn"),
}


@pytest.mark.parametrize("name", list(STAGE_CASES))
def test_every_part_runs_in_the_graph(name):
    rng = np.random.default_rng(5)
    right = rng.random((32, 48, 3), dtype=np.float32)
    left = np.roll(right, 3, axis=1)
    disparity = sswjax.match(left, right, 8, params=STAGE_CASES[name])
    assert disparity.shape == (32, 48) and np.isfinite(disparity).all()
    assert np.median(disparity[:, 10:]) == pytest.approx(3, abs=0.01)
