"""experiments.bench_acting on texts of its own (the frozen benches are read only by running it): the groups, the
figures and the table of one read, and the two decisions it compares from one pass."""

import pytest

import jgrounding as jg
from experiments import bench_acting as ba
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENTS


def _item(intent, style):
    return {"text": "x", "intent": intent, "intensity": "moderate", "style": style}


def _g(intent, acted):
    return Grounding(intent, "moderate", 0.9, "embedded", acted, "" if acted else "held", (0.0,) * len(INTENTS))


def test_groups_and_figures_count_each_outcome_once():
    items = [
        _item("nodding", "contrast"),  # acted right
        _item("nodding", "mixed"),  # acted wrong
        _item("greeting", "situation"),  # held
        _item("greeting", "situation"),  # acted right
        _item("none", "rules_out"),  # held
        _item("none", "freeze_order"),  # acted on: a no-motion text
    ]
    assert [ba.group(it) for it in items] == ["outright", "outright", "situation", "situation", "none", "none"]
    preds = [
        _g("nodding", True),
        _g("refusing", True),
        _g("greeting", False),
        _g("greeting", True),
        _g("nodding", False),
        _g("nodding", True),
    ]
    f = ba.figures(items, preds)
    assert f["outright"] == {"n": 2, "acted_right": 0.5, "held": 0.0, "acted_wrong": 0.5}
    assert f["situation"] == {"n": 2, "acted_right": 0.5, "held": 0.5, "acted_wrong": 0.0}
    assert f["none"] == {"n": 2, "held": 0.5} and f["explicit_acted"] == 1.0 and f["acted_wrong"] == 0.25
    assert f["cost"] == pytest.approx((5 + 1 + 3) / 6)  # a wrong intent, a held motion, a no-motion text acted on
    met = ba.goals_met(f)
    assert met == {"outright": False, "situation": False, "none_held": False, "acted_wrong": False}
    table = ba.table({"before": f, "after": f})
    assert table.count("\n") == 11 and "| explicit motion requests acted on | 2 | 1.000 | 1.000 | |" in table


def test_before_is_one_threshold_and_after_is_jg_ground():
    nod = "Give a small nod to show you are listening."
    before, after = ba.before_and_after(nod)
    assert not before.confident and "calibrated threshold" in before.reason  # 0.77 < the head's one threshold
    assert after == jg.ground(nod) and after.confident
    still = "please stay still, the nurse is checking you"
    assert [g.no_motion for g in ba.before_and_after(still)] == ["freeze_order", "freeze_order"]
