"""The one decision path (jgrounding.policy.respond): the snap onto a checkpoint's tuples, the hold-or-move
decision with its reason, and the hold through the safety gate."""

import numpy as np
import pytest

from jgrounding import safety
from jgrounding.config import NUM_STEPS
from jgrounding.policy import respond
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENSITIES, INTENTS


def _g(intent="greeting", intensity="emphatic", confident=True, reason=""):
    scores = tuple(0.9 if m == intent else 0.01 for m in INTENTS)
    return Grounding(intent, intensity, 0.9, "embedded", confident, reason, scores)


LAB = frozenset({(INTENTS.index("greeting"), 0), (INTENTS.index("greeting"), 1), (INTENTS.index("nodding"), 2)})


def test_every_tuple_known_changes_nothing():
    g = _g()
    assert respond.snap(g, None, None) == (g, None)


def test_another_intensity_of_a_learned_intent_snaps_to_the_nearest_and_stays_confident():
    g, note = respond.snap(_g(intensity="emphatic"), LAB, "lab")
    assert (g.intent, g.intensity, g.confident) == ("greeting", INTENSITIES[1], True)
    assert "nearest" in note and "lab" in note


def test_an_unlearned_intent_is_named_and_not_confident():
    g, note = respond.snap(_g(intent="refusing"), LAB, "lab")
    assert (g.intent_index, g.intensity_index) in LAB and not g.confident
    assert "refusing" in note and "never learned" in g.reason
    assert g.reason.endswith("it knows greeting/subtle, greeting/moderate, nodding/pronounced")  # what it can do


def test_decision_holds_an_unconfident_grounding_with_its_reason_unless_forced():
    held = respond.Decision("greeting", "subtle", _g(confident=False), hold=True, reason="low confidence")
    assert held.message().startswith("holding still: low confidence; the trunk stays at rest")
    assert "0.50" in held.message(np.full(4, 0.5, np.float32))  # says what it really holds
    forced = respond.Decision("greeting", "subtle", _g(confident=False), hold=False, reason="low confidence")
    assert forced.forced and forced.message() is None
    assert not respond.Decision("greeting", "subtle").forced


@pytest.fixture(scope="module")
def responder():
    return respond.Responder()


def test_hold_keeps_the_current_command_through_the_gate(responder):
    start = np.array([0.2, 0.0, 0.4, 0.1], np.float32)
    u = responder.hold(start, num_samples=3)
    assert u.shape == (3, NUM_STEPS, 4) and safety.is_safe(u)
    np.testing.assert_allclose(u, np.broadcast_to(start, u.shape))
    assert responder.hold().shape == (NUM_STEPS, 4) and not responder.hold().any()


def test_a_given_tuple_always_moves_and_a_call_needs_a_text_or_an_intent(responder):
    d = responder.decide(intent="nodding")
    assert (d.intent, d.intensity, d.hold, d.grounding) == ("nodding", "moderate", False, None)
    with pytest.raises(ValueError, match="greeting"):
        responder.decide()
