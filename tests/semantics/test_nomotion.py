"""The explicit no-motion decision (issue #34): hand-written texts of each kind hold with their reason whatever
motion they name; texts the rule's phrases miss are held by the learned detector; contrast texts that choose a
motion and plain motion requests still act; the detector's file matches its data and head and retrains
deterministically; the decision reaches the Responder, the CLI and the server alike. Every text here was written
for this file (none is taken from a data file)."""

import dataclasses

import numpy as np
import pytest

from jgrounding.semantics import nomotion, structure
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENTS
from tools import train_nomotion

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
    "A visitor has just walked in and is looking straight at the robot.",
    "He is telling the robot about his weekend; show that you are following.",
]
# No motion in words the rule's phrases do not match: the learned detector holds them.
LEARNED = [
    "The technician has opened the side panel and is replacing a tendon cable.",
    "Please don't do anything for now; he's concentrating on his exam.",
    "[log] 14:02 battery at 62 %, charging",
    "System: firmware update 3.2 installed, rebooting in ten seconds.",
    "Last week the robot waved at every visitor; today nobody has come in yet.",
    "She is still filling in the form; give her a few more minutes before anything.",
]
# No motion that the detector retrained in the eighth session no longer holds (p 0.41 against its threshold 0.5375:
# the frown reads as a cue to comfort; "He is on a phone call with his bank, frowning at the screen." scores 1.00):
# jg.ground must still not act on it.
UNSURE = ["He's in the middle of a phone call with his bank, frowning at the screen."]


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


@pytest.mark.parametrize("text", LEARNED)
def test_the_detector_holds_no_motion_texts_the_rule_misses(text):
    assert nomotion.rule(text, structure.spans(text)) is None  # the rule lets it through
    hold = nomotion.check(text)
    assert hold is not None and hold.kind == nomotion.LEARNED, text
    assert hold.reason.startswith("the text calls for no motion (learned detector, p = ")
    assert nomotion.check(text, learned=False) is None


@pytest.mark.parametrize("text", UNSURE)
def test_no_motion_texts_neither_the_rule_nor_the_detector_holds_are_not_acted_on(text):
    import jgrounding as jg

    assert nomotion.check(text) is None
    g = jg.ground(text)
    # the situation's threshold holds it (the decision per kind of text says which threshold: "unsure which motion")
    assert not g.confident and g.reason.startswith("unsure which motion") and "situation" in g.reason, g


def test_the_detector_is_sure_of_motion_requests_and_kept_from_contrast_texts():
    """Plain motion requests score below its threshold; a contrast text that chooses a motion is never held by it,
    whatever it scores (the same chosen-motion guard as the rule's)."""
    d = nomotion.detector()
    p = d.probability(nomotion.sentence_vectors(MOTION))
    assert np.all(p < d.threshold), dict(zip(MOTION, p.round(3)))
    held = nomotion.sentence_vectors(LEARNED[:1])[0]  # a vector it holds
    assert d.probability(held[None])[0] >= d.threshold
    for text, _ in CONTRAST:
        assert nomotion.chosen_motion(text)
        assert nomotion.check(text, vector=held) is None


def test_the_shipped_detector_matches_its_training_data_and_head(head):
    """Its recorded digests are those of today's training rows and the shipped head (else retrain it with
    ``python -m tools.train_nomotion``), and its cross-validated false holds kept the bound it was chosen under."""
    d = nomotion.read_detector()
    rows = train_nomotion.training_rows()
    assert d.meta["data_digest"] == train_nomotion.data_digest(rows), "training data changed: retrain the detector"
    assert d.meta["head_digest"] == head.meta["params_digest"], "the head changed: retrain the detector"
    assert nomotion.detector() is not None
    assert d.arrays["w1"].shape == (384, train_nomotion.HIDDEN) and d.arrays["mean"].shape == (384,)
    assert 0.0 < d.threshold < 1.0
    assert d.meta["texts"]["no_motion"] == sum(r["label"] for r in rows) > 0
    assert train_nomotion.within_bounds(d.meta["cv"]["false_hold"])
    assert train_nomotion.CONTRAST in d.meta["cv"]["false_hold"] and "blind situation" in d.meta["cv"]["false_hold"]


def test_training_is_deterministic(tmp_path):
    """The same rows give the same detector, threshold and bytes (the tool's ``--check`` does this on the real
    data, about a minute)."""
    rng = np.random.default_rng(0)
    x = rng.standard_normal((120, 384)).astype(np.float32)
    label = (x[:, 0] > 0.5).astype(np.int32)
    source = np.array(["a", "b", "c"] * 40)
    source[label == 1] = train_nomotion.NO_MOTION
    w = train_nomotion.weights(label, source)
    first, second = (train_nomotion.fit(x, label, w) for _ in range(2))
    for k in first:
        np.testing.assert_array_equal(first[k], second[k])
    p = train_nomotion.probability(first, x)
    assert p[label == 1].mean() > p[label == 0].mean()
    t = train_nomotion.choose_threshold(p, label, source)
    assert max(train_nomotion.false_holds(p >= t, label, source).values()) <= train_nomotion.MAX_FALSE_HOLD
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    nomotion.save_detector(a, first, t, {"data_digest": "x"})
    nomotion.save_detector(b, second, t, {"data_digest": "x"})
    assert a.read_bytes() == b.read_bytes()
    np.testing.assert_allclose(nomotion.read_detector(a).probability(x[:3]), p[:3], rtol=1e-5)


def test_situation_only_texts_have_a_looser_false_hold_bound_than_every_other_source():
    """A held situation is the safe failure (the trunk holds still); a text that names or chooses a motion, held
    by mistake, is a refusal to obey: the threshold keeps the latter at 1 % and the former at 5 %."""
    label = np.array([1] * 10 + [0] * 100 + [0] * 100)
    source = np.array([train_nomotion.NO_MOTION] * 10 + ["blind situation"] * 100 + ["blind contrast"] * 100)
    p = np.concatenate([np.full(10, 0.97), np.linspace(0.0, 0.96, 100), np.linspace(0.0, 0.5, 100)])
    t = train_nomotion.choose_threshold(p, label, source)
    fh = train_nomotion.false_holds(p >= t, label, source)
    assert 0.01 < fh["blind situation"] <= 0.05 and fh["blind contrast"] == 0
    assert train_nomotion.choose_threshold(p, label, np.where(source == "blind situation", "x.jsonl", source)) > t


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
    # The tuple and the reducer's scores are kept; a rule's hold is sure, so no confidence in acting is left.
    assert held.confidence == 0.0
    assert dataclasses.replace(held, confident=True, reason="", no_motion="", confidence=g.confidence) == g
    assert nomotion.apply("Wave hello!", g) is g


def test_a_learned_hold_keeps_the_reason_of_a_reducer_that_did_not_act():
    g = Grounding("greeting", "moderate", 0.97, "embedded", True, "", tuple(0.01 for _ in INTENTS))
    text = LEARNED[2]  # a log line
    assert nomotion.apply(text, g).reason.startswith("the text calls for no motion (learned detector, p = ")
    unsure = dataclasses.replace(g, confident=False, reason="a system or log line (reads as no behaviour, p = 0.99)")
    held = nomotion.apply(text, unsure)
    assert held.no_motion == nomotion.LEARNED
    p = float(held.reason.split("learned detector, p = ")[1][:4])
    assert held.confidence == pytest.approx(g.confidence * (1 - p), abs=0.006)  # p is printed to 2 places
    assert held.reason.startswith(
        "a system or log line (reads as no behaviour, p = 0.99); the text calls for no motion"
    )


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


def test_a_learned_hold_is_the_same_from_ground_ground_many_every_backend_and_the_responder():
    import jgrounding as jg
    from jgrounding.policy.respond import Responder

    text = LEARNED[0]
    g = jg.ground(text)
    assert not g.confident and g.no_motion == nomotion.LEARNED
    assert "the text calls for no motion (learned detector, p = " in g.reason
    assert [h.no_motion for h in jg.ground_many([text, "Wave hello!"])] == [nomotion.LEARNED, ""]
    assert jg.ground(text, backend="cues").no_motion == nomotion.LEARNED  # the cue reducer gets the same decision
    assert [h.no_motion for h in jg.ground_many([text], backend="cues")] == [nomotion.LEARNED]
    d = Responder().decide(text)
    assert d.hold and d.message().startswith("holding still: ")
    assert "the text calls for no motion (learned detector" in d.message()


def test_cli_and_server_agree_on_a_no_motion_text(tmp_path):
    """The CLI and the server share the Responder: the same text holds in both, with the same reason."""
    from jgrounding import serving
    from jgrounding.apps import cli, export
    from jgrounding.client import Client

    run = serving.Running(serving.Server(serving.Policy(None, warm=False)))
    try:
        client = Client(run.url)
        texts = ["Grandpa to his grandson: 'Come here and give me a big hug!'", LEARNED[0], "Wave hello!"]
        for i, text in enumerate(texts):
            out = tmp_path / str(i)
            assert cli.main([text, "--seed", "3", "--samples", "2", "--no-render", "--out", str(out)]) == 0
            header, _ = export.read_command_stream_csv(out / "commands.csv")
            reply = client.sample(text, num_samples=2, seed=3)
            assert reply["hold_still"] == bool(header.get("hold_still")) == (i < 2), text
            np.testing.assert_allclose(reply["u"], np.load(out / "samples.npy"), atol=1e-6, err_msg=text)
            if i == 0:
                assert reply["message"].startswith("holding still: the words are addressed to or meant for")
            if i == 1:
                assert "the text calls for no motion (learned detector" in reply["message"]
    finally:
        run.stop()


def test_another_detector_or_threshold_is_one_argument_and_the_default_is_the_shipped_decision():
    """tools.nomotion_frontier reads the decision at other thresholds through check/apply's ``learned_detector``: the
    shipped one at its own threshold decides as the default does, at threshold 0 it holds every text no chosen
    motion protects, above 1 it holds none (the rule still does)."""
    import dataclasses

    import jgrounding as jg
    from jgrounding.semantics import embedded

    d = nomotion.detector()
    texts = [
        LEARNED[0],
        MOTION[0],
        CONTRAST[0][0],
        "Grandma dozing in her armchair, cat on her lap, rain on the window.",
    ]
    from jgrounding.semantics import decision

    at_point = decision.detector_at(decision.point())  # jg.ground's detector: the operating point's threshold
    for text in texts:  # each alone, as jg.ground grounds it (a batch pads to another bucket: other roundings)
        (g,), (v,) = embedded.ground_embedded_vectors([text])
        same = nomotion.apply(text, g, vector=v, learned_detector=dataclasses.replace(d, threshold=d.threshold))
        assert same == nomotion.apply(text, g, vector=v)
        # jg.ground is the act/hold decision, whose no-motion part is apply with the point's detector threshold
        assert jg.ground(text).no_motion == nomotion.apply(text, g, vector=v, learned_detector=at_point).no_motion
        never = nomotion.check(text, vector=v, learned_detector=dataclasses.replace(d, threshold=1.01))
        assert never is None or never.kind != nomotion.LEARNED
        always = nomotion.check(text, vector=v, learned_detector=dataclasses.replace(d, threshold=0.0))
        assert (always is None) == bool(nomotion.chosen_motion(text)), text
