"""The explicit no-motion decision (issue #34): hand-written texts of each kind hold with their reason whatever
motion they name; contrast texts that choose a motion still act; the decision reaches the Responder, the CLI and
the server alike. Every text here was written for this file (none is taken from a data file)."""

import dataclasses

import pytest

from jgrounding.semantics import nomotion
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENTS

HOLD = {
    "rules_out": [
        "No need to wave at him, he's already out of the door. Leave it.",
        "A hug would be too much here, she has only just met the robot. Nothing for the trunk to do.",
        "I thought about a nod, but nobody asked anything. No movement.",
        "Celebrating isn't called for, the goal was an own goal by her team. Skip it.",
        "No waving, no nodding, no leaning in. Let it be.",
    ],
    "freeze_order": [
        "Freeze! The technician's fingers are between the segments.",
        "Do not move: a full glass is balanced on the base and even a gentle pat would tip it over.",
        "Hold position until the photographer is done; a wave would blur the picture.",
        "Stay completely still, the toddler is leaning on the trunk and a comforting stroke could startle her.",
    ],
    "addressed_other": [
        "Voicemail playing on the speaker: 'Hi, it's Tom, just saying hello, call me back!'",
        "Grandpa to his grandson: 'Come here and give me a big hug!'",
        "The two students high-five each other after the quiz; none of it is for the robot.",
        "The user on the phone says 'yes, yes, absolutely, see you tomorrow' to her manager.",
        "He keeps nodding along on a conference call, eyes on the screen.",
        "Two nurses chatting with each other by the window about the weekend.",
    ],
    "observed_activity": [
        "A man at the next table is knitting and humming to himself.",
        "Someone is vacuuming the corridor outside, headphones on.",
        "She's typing an email, shoulders hunched, not looking up.",
    ],
    "not_now": [
        "She's on an important phone call. Wait until she's off before any greeting.",
        "He said he needs one minute to finish the form. Just wait.",
    ],
    "handling": ["Calibration mode: the engineer will bend the tip by hand and log each angle."],
}
CONTRAST = [
    ("Don't wave; just nod slightly.", "nodding"),
    ("Instead of a hug, give her a gentle pat on the shoulder.", "comforting"),
    ("Rather than pointing at the door, beckon him over with a clear curl of the tip.", "beckoning"),
    ("Skip the celebration and lean in to listen closely.", "attentive_listening"),
    ("No need for a big wave, a small nod is enough.", "nodding"),
    ("Not the wild swinging, the baby is asleep. Tiny bouncy sways only.", "playful_swing"),
    ("Stay still for a second, then give a small wave goodbye.", "farewell"),
    ("Freeze the celebration; the trunk should back away slowly, she looks frightened.", "withdrawal"),
]
MOTION = [
    "User seems sad; respond calmly with a gentle touch",
    "Wave hello!",
    "The child is crying on the sofa; comfort her softly.",
    "She just got the job! Celebrate with a big trumpet.",
]


@pytest.mark.parametrize("kind,text", [(k, t) for k, texts in HOLD.items() for t in texts])
def test_the_rule_holds_each_kind(kind, text):
    hold = nomotion.check(text)
    assert hold is not None, text
    assert hold.kind == kind, (text, hold)
    assert hold.reason.startswith(nomotion.REASONS[kind])


@pytest.mark.parametrize("text,_intent", CONTRAST)
def test_contrast_texts_that_choose_a_motion_act(text, _intent):
    assert nomotion.check(text) is None, (text, nomotion.check(text))
    assert nomotion.chosen_motion(text)


@pytest.mark.parametrize("text", MOTION)
def test_plain_motion_texts_are_not_held(text):
    assert nomotion.check(text) is None


def test_the_motion_words_inside_what_is_ruled_out_do_not_override_the_hold():
    """A text that names the motion it rules out, quoted or beside 'leave it', holds; the same motion chosen
    outside the ruled-out part acts."""
    assert nomotion.check("She said 'give me a hug' to her brother, not to us.") is not None
    assert nomotion.check("A big hug would be lovely, but she's on crutches. Leave it.") is not None
    assert nomotion.check("A big hug would be lovely, but she's on crutches; a gentle pat on the arm instead.") is None


def test_apply_holds_a_confident_grounding_with_the_reason():
    g = Grounding("greeting", "moderate", 0.97, "embedded", True, "", tuple(0.01 for _ in INTENTS))
    text = "No need to wave at him, he's already out of the door. Leave it."
    held = nomotion.apply(text, g)
    assert not held.confident and held.no_motion == "rules_out"
    assert held.reason.startswith("the text rules the motion out (")
    assert dataclasses.replace(held, confident=True, reason="", no_motion="") == g  # the tuple is kept
    assert nomotion.apply("Wave hello!", g) is g


def test_ground_and_the_responder_hold_with_the_reason():
    import jgrounding as jg
    from jgrounding.policy.respond import Responder

    text = "Stay completely still, the toddler is leaning on the trunk and a comforting stroke could startle her."
    g = jg.ground(text)
    assert not g.confident and g.no_motion == "freeze_order" and "keep still" in g.reason
    assert [h.no_motion for h in jg.ground_many([text, "Wave hello!"])] == ["freeze_order", ""]
    assert jg.ground(text, backend="cues").no_motion == "freeze_order"
    d = Responder().decide(text)
    assert d.hold and d.message().startswith("holding still: the text orders the trunk to keep still")
    assert not Responder().decide(text, force=True).hold  # forcing still drives it
    contrast = jg.ground("Instead of a hug, give her a gentle pat on the shoulder.")
    assert contrast.no_motion == "" and contrast.intent == "comforting"


def test_cli_and_server_agree_on_a_no_motion_text(tmp_path):
    """The CLI and the server share the Responder: the same text holds in both, with the same reason."""
    import numpy as np

    from jgrounding import serving
    from jgrounding.apps import cli, export
    from jgrounding.client import Client

    run = serving.Running(serving.Server(serving.Policy(None, warm=False)))
    try:
        client = Client(run.url)
        for i, text in enumerate(["Grandpa to his grandson: 'Come here and give me a big hug!'", "Wave hello!"]):
            out = tmp_path / str(i)
            assert cli.main([text, "--seed", "3", "--samples", "2", "--no-render", "--out", str(out)]) == 0
            header, _ = export.read_command_stream_csv(out / "commands.csv")
            reply = client.sample(text, num_samples=2, seed=3)
            assert reply["hold_still"] == bool(header.get("hold_still")) == (i == 0), text
            np.testing.assert_allclose(reply["u"], np.load(out / "samples.npy"), atol=1e-6, err_msg=text)
            if i == 0:
                assert reply["message"].startswith("holding still: the words are addressed to or meant for")
    finally:
        run.stop()
