"""The act/hold decision per kind of text (jgrounding/semantics/decision.py): the kinds, an order's confidence, the
operating point and its fallback, the costs, and that jg.ground is the decision at the shipped point."""

import dataclasses
import json

import pytest

import jgrounding as jg
from jgrounding.semantics import decision, embedded
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENTS


def _g(intent="greeting", p=0.5, others=None, confident=True, reason="") -> Grounding:
    scores = [0.0] * len(INTENTS)
    scores[INTENTS.index(intent)] = p
    for m, q in (others or {}).items():
        scores[INTENTS.index(m)] = q
    return Grounding(intent, "moderate", p, "embedded", confident, reason, tuple(scores))


@pytest.mark.parametrize(
    "text, intent, kind",
    [
        ("wave back enthusiastically!", "greeting", "order"),
        ("Give a small nod to show you are listening.", "nodding", "order"),
        ("a tiny nod", "nodding", "order"),
        ("Don't hug her; just nod.", "nodding", "order"),
        ("a tiny nod", "refusing", "chosen"),  # the clause names a nod, the head read another intent
        ("The user looks sad after a long day.", "comforting", "situation"),
    ],
)
def test_kind_of_text(text, intent, kind):
    assert decision.kind(text, intent)[0] == kind


def test_an_orders_confidence_is_the_heads_reading_among_the_gestures_it_names():
    g = _g("greeting", 0.4, {"farewell": 0.3, "withdrawal": 0.2, "beckoning": 0.1})
    named = decision.named_intents("wave back")
    assert named == {"greeting", "farewell", "beckoning"}
    assert decision.order_confidence(g, named) == pytest.approx(0.4 / 0.8)
    assert decision.order_confidence(g, set()) == 0.0


def test_the_point_checks_its_kinds_and_range_and_round_trips(tmp_path):
    with pytest.raises(ValueError, match="order, chosen, situation"):
        decision.OperatingPoint({"order": 0.5}, 0.5)
    with pytest.raises(ValueError, match="detector"):
        decision.OperatingPoint(dict.fromkeys(decision.KINDS, 0.5), 2.0)
    p = decision.OperatingPoint({"order": 0.6, "chosen": 0.9, "situation": 0.8}, 0.55, {"head_digest": "x"})
    path = tmp_path / "point.json"
    path.write_text(p.to_json())
    assert decision.read_point(path) == p
    assert json.loads(p.to_json())["costs"] == decision.COSTS
    with pytest.raises(FileNotFoundError, match="nomotion_frontier --write"):
        decision.read_point(tmp_path / "missing.json")


def test_the_costs_rank_a_wrong_motion_above_an_unwanted_one_above_a_miss():
    c = decision.COSTS
    assert c["held_motion"] < c["acted_no_motion"] < c["acted_wrong"]
    assert decision.cost(True, False, False) == c["held_motion"]
    assert decision.cost(True, True, True) == 0.0 and decision.cost(False, False, False) == 0.0
    assert decision.cost(False, True, False) == c["acted_no_motion"]
    assert decision.cost(True, True, False) == c["acted_wrong"]
    assert set(decision.COST_REASONS) == set(c)


def test_the_shipped_point_is_fitted_for_the_shipped_head():
    from jgrounding.semantics import head

    p = decision.point()
    assert p.meta["head_digest"] == head.load().meta["params_digest"] and "fallback" not in p.meta


def test_a_point_for_another_head_falls_back_to_one_threshold(monkeypatch, tmp_path):
    other = decision.OperatingPoint(dict.fromkeys(decision.KINDS, 0.1), 0.1, {"head_digest": "another"})
    path = tmp_path / "point.json"
    path.write_text(other.to_json())
    monkeypatch.setattr(decision, "POINT_ASSET", path)
    decision.point.cache_clear()
    try:
        with pytest.warns(UserWarning, match="another"):
            p = decision.point()
        assert p == decision.fallback_point() and len(set(p.thresholds.values())) == 1
    finally:
        decision.point.cache_clear()


TEXTS = (
    "wave back enthusiastically!",
    "Give a small nod to show you are listening.",
    "please stay still, the nurse is checking you",
    "wave back!",
    "nod",
    "User seems sad; respond calmly",
    "asdf qwer zxcv",
    "The user drops their keys and sighs.",
)


def test_jg_ground_is_the_decision_at_the_shipped_point_and_a_point_changes_only_the_threshold():
    for text in TEXTS:
        (g,), v = embedded.ground_embedded_vectors([text], threshold=0.0)
        assert jg.ground(text) == decision.decide(text, g, vector=v[0])
        never = decision.OperatingPoint(dict.fromkeys(decision.KINDS, 1.01), decision.point().detector)
        held = decision.decide(text, g, vector=v[0], p=never)
        assert not held.confident and held.reason  # no kind acts at 1.01, and each hold says why


def test_an_order_moves_a_ruled_out_or_still_text_holds_and_a_low_reading_says_which_kind():
    acts = jg.ground("wave back enthusiastically!"), jg.ground("Give a small nod to show you are listening.")
    assert [(g.intent, g.confident) for g in acts] == [("greeting", True), ("nodding", True)]
    still = jg.ground("please stay still, the nurse is checking you")
    assert not still.confident and still.no_motion == "freeze_order"
    nod = jg.ground("nod")  # the head reads a bare order as no behaviour; the order overrides that
    assert nod.confident and nod.intent == "nodding"
    low = decision.decide("wave back!", _g("greeting", 0.4, {"farewell": 0.4}), p=decision.point())
    assert not low.confident and "a text that names its motion" in low.reason and low.reason.startswith("unsure")


def test_other_backends_keep_their_own_threshold():
    g = dataclasses.replace(_g("nodding", 0.2), backend="cues")
    assert decision.decide("The user looks sad.", g, per_kind=False, p=decision.point()) == g
