"""The held-out rule that chose the presets' values (:mod:`sswjax.evaluation.selection`), and
the scoring's average over scenes it is fed with (:func:`sswjax.evaluation.runner.scene_average`)."""

import math

import pytest

from sswjax.evaluation.metrics import weighted_average
from sswjax.evaluation.runner import SCORINGS, scene_average
from sswjax.evaluation.selection import choose, held_out_choices, relative_errors

# "a" is best on trainingQ, "b" on KITTI and "c" on Middlebury 2001 (bad 2.0; trainingQ's the
# mean of its weighted nonocc and all).
ERRORS = {"a": {"trainingQ": 11.0, "KITTI2012": 12.0, "Middlebury2001": 2.0},
          "b": {"trainingQ": 13.0, "KITTI2012": 10.0, "Middlebury2001": 2.1},
          "c": {"trainingQ": 13.0, "KITTI2012": 12.0, "Middlebury2001": 1.0}}
ONE_EACH = {name: [name] for name in ("trainingQ", "KITTI2012", "Middlebury2001")}


def test_the_choice_is_the_lowest_mean_error_relative_to_the_best():
    assert relative_errors(ERRORS, ["KITTI2012", "Middlebury2001"]) == pytest.approx(
        {"a": (1.2 + 2.0) / 2, "b": (1.0 + 2.1) / 2, "c": (1.2 + 1.0) / 2})
    assert choose(ERRORS, ["KITTI2012", "Middlebury2001"]) == "c"   # 1.2 + 1.0 beats b's 1.0 + 2.1
    assert choose(ERRORS, ["trainingQ"]) == "a"


def test_each_fold_chooses_on_the_other_sets():
    folds = {fold.held_out: fold for fold in held_out_choices(ERRORS, ONE_EACH)}
    assert list(folds) == ["trainingQ", "KITTI2012", "Middlebury2001"]
    assert folds["trainingQ"].chosen == "c"
    assert folds["trainingQ"].errors == {"trainingQ": 13.0}
    assert (folds["trainingQ"].best, folds["trainingQ"].best_errors) == ("a", {"trainingQ": 11.0})
    assert folds["KITTI2012"].chosen == "c"       # 13/11 + 1.0 < 1.0 + 2.0
    assert folds["Middlebury2001"].chosen == "b"  # 13/11 + 1.0 < 1.0 + 1.2


def test_a_set_may_weigh_several_thresholds():
    # On bad 2.0 alone "x" wins KITTI; over 2.0, 1.0 and 0.5 "y" does, and so is chosen when
    # trainingQ is held out.
    errors = {"x": {"Q 2": 10.0, "Q 1": 20.0, "K 2": 4.0, "K 1": 12.0, "K 0.5": 30.0},
              "y": {"Q 2": 10.0, "Q 1": 20.0, "K 2": 4.4, "K 1": 10.0, "K 0.5": 25.0}}
    groups = {"Q": ["Q 2", "Q 1"], "K": ["K 2", "K 1", "K 0.5"]}
    assert choose(errors, ["K 2"]) == "x"
    (held_q, held_k) = held_out_choices(errors, groups)
    assert (held_q.held_out, held_q.chosen) == ("Q", "y")
    assert held_q.errors == {"Q 2": 10.0, "Q 1": 20.0}
    assert held_k.best == "y"  # the best on K's three thresholds together


@pytest.mark.parametrize("errors, criteria, message", [
    ({}, ["K"], "no configuration to choose from"),
    ({"a": {"K": 1.0}}, [], "no criterion to choose on"),
    ({"a": {"K": 1.0}, "b": {"M": 1.0}}, ["K"], "configuration 'b' has no error for 'K'"),
    ({"a": {"K": math.nan}}, ["K"], "configuration 'a' has a non-finite error for 'K': nan"),
    ({"a": {"K": -1.0}}, ["K"], "configuration 'a' has a negative error for 'K': -1.0"),
    ({"a": {"K": 0.0}, "b": {"K": 1.0}}, ["K"],
     "the lowest error on 'K' is 0: errors relative to it are undefined"),
])
def test_the_rule_refuses_what_it_cannot_rank(errors, criteria, message):
    with pytest.raises(ValueError, match="^" + message.replace("(", r"\(").replace(")", r"\)")
                       + "$"):
        choose(errors, criteria)


def test_holding_out_needs_two_disjoint_sets():
    with pytest.raises(ValueError, match="^leaving one data set out needs two data sets or more$"):
        held_out_choices(ERRORS, {"trainingQ": ["trainingQ"]})
    with pytest.raises(ValueError, match="^criterion 'KITTI2012' is in two data sets: "
                                         "'trainingQ' and 'KITTI2012'$"):
        held_out_choices(ERRORS, {"trainingQ": ["trainingQ", "KITTI2012"],
                                  "KITTI2012": ["KITTI2012"]})
    with pytest.raises(ValueError, match="^data set 'KITTI2012' has no criterion$"):
        held_out_choices(ERRORS, {"trainingQ": ["trainingQ"], "KITTI2012": []})


def test_scene_average_is_the_scorings_average():
    values = {"Teddy": 10.0, "Vintage": 40.0}
    middeval3 = SCORINGS["middeval3"]
    assert scene_average(values, middeval3) == weighted_average(values) != 25.0
    assert scene_average(values, SCORINGS["kitti"]) == 25.0
    # a scene without an official weight (a user's own MiddEval3-layout folder): the plain mean
    assert scene_average({"Teddy": 10.0, "Mine": 40.0}, middeval3) == 25.0
