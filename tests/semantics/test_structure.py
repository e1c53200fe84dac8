"""Structure-aware grounding (#24): spans and flags, pooled features, batched grounding, the reason for holding
still, the compilation cache and the training tool's pieces (tiny data, no long training)."""

import json
from pathlib import Path

import jax
import numpy as np
import pytest

import jgrounding as jg
from jgrounding import semantics
from jgrounding.semantics import cue_reducer, encoder, features, structure
from jgrounding.semantics import head as sh
from tools import semantics_calibration


def _flags(text):
    return dict(zip(structure.FLAGS, structure.analyse(text).flags))


@pytest.mark.parametrize(
    "text, rejected, chosen",
    [
        ("Rather than a big hug, just give a small wave.", "Rather than a big hug", "give a small wave"),
        ("Don't back away; lean in and listen.", "Don't back away", "lean in and listen"),
        ("Give them space instead of hugging them.", "instead of hugging them", "Give them space"),
        ("It is tempting to celebrate wildly, but a calm nod is enough.", "celebrate wildly", "a calm nod"),
    ],
)
def test_contrast_splits_the_rejected_from_the_chosen_reaction(text, rejected, chosen):
    st = structure.analyse(text)
    assert rejected in st.rejected_text(text)
    assert chosen in st.chosen_text(text) and rejected not in st.chosen_text(text)
    assert _flags(text)["has_rejected"] == 1.0


def test_plain_text_has_no_spans_and_chooses_everything():
    text = "Wave hello to the user."
    st = structure.analyse(text)
    assert st.rejected == () and st.quoted == () and st.chosen_text(text) == text


def test_quotes_addressee_logs_and_not_understood_are_flagged():
    q = structure.analyse('He said "wave at me" to his friend.')
    assert [('He said "wave at me" to his friend.')[a:b] for a, b in q.quoted] == ["wave at me"]
    assert _flags('He said "wave at me" to his friend.')["reported_speech"] == 1.0
    assert structure.analyse("It's the user's turn, isn't it").quoted == ()  # apostrophes are not quotes
    assert _flags("Sam, can you pass me the salt?")["vocative"] == 1.0
    assert _flags("Yes, pass me the salt.")["vocative"] == 0.0
    assert _flags("[12:03:44] INFO battery=87% heartbeat ok")["log_line"] > 0.5
    assert _flags("Sorry, I did not catch that, could you repeat?")["not_understood"] == 1.0
    assert _flags("Wave hello.")["log_line"] == 0.0


def test_pooled_sentence_is_the_sentence_embedding_and_spans_pool_their_tokens():
    texts = ["Rather than a big hug, just give a small wave.", 'Say "hello" to the user.']
    x = features.structure_features(texts)
    assert x.shape == (2, features.INPUTS["structure"].width)
    np.testing.assert_allclose(x[:, :384], encoder.embed(texts), atol=1e-5)
    rejected, quoted = x[:, 2 * 384 : 3 * 384], x[:, 3 * 384 : 4 * 384]
    assert np.linalg.norm(rejected[0]) == pytest.approx(1, abs=1e-4) and not rejected[1].any()
    assert np.linalg.norm(quoted[1]) == pytest.approx(1, abs=1e-4) and not quoted[0].any()
    # A text pooled alone gets the same features as in a batch (padding rows and buckets do not leak).
    np.testing.assert_allclose(features.structure_features(texts[:1]), x[:1], atol=1e-4)


def test_ground_many_matches_ground_one_by_one():
    texts = ["Wave hello to the user!", "[12:03:44] INFO battery=87%", "Rather than hugging, just nod slightly."]
    many = jg.ground_many(texts)
    for t, g in zip(texts, many):
        one = jg.ground(t, escalate=False)
        assert (g.intent, g.intensity, g.confident, g.reason) == (one.intent, one.intensity, one.confident, one.reason)
        assert g.confidence == pytest.approx(one.confidence, abs=1e-3)
    assert [g.intent for g in jg.ground_many(texts, backend="cues")] == [
        jg.ground(t, backend="cues").intent for t in texts
    ]


def test_ground_many_checks_its_input():
    with pytest.raises(TypeError, match="sequence of strings"):
        jg.ground_many("one text")
    with pytest.raises(ValueError, match="empty"):
        jg.ground_many(["fine", " "])
    with pytest.raises(ValueError, match="embedded, cues"):
        jg.ground_many(["fine"], backend="mllm")
    assert jg.ground_many([]) == []


@pytest.mark.parametrize(
    "text, why",
    [
        ("[2024-05-01 12:03:44] WARN motor_driver: temperature=71C, retrying in 500ms", "system or log line"),
        ("Sorry, I couldn't make out what they said; the audio was garbled.", "did not understand"),
    ],
)
def test_no_behaviour_holds_still_and_says_why(text, why):
    g = jg.ground(text, escalate=False)
    assert not g.confident and "no behaviour" in g.reason and why in g.reason


def test_contrast_picks_the_chosen_reaction():
    g = jg.ground("Rather than a big hug, just give them a small wave hello.", escalate=False)
    assert g.intent == "greeting"


def test_low_confidence_reason_names_what_was_understood():
    from jgrounding.semantics import decision

    texts = ["hmm, maybe something", "do the thing with the stuff over there, I guess"]
    for text, g in zip(texts, jg.ground_many(texts)):
        if not g.confident and "no behaviour" not in g.reason:
            # the threshold is its kind of text's (the operating point's), no longer the head's one threshold
            k = decision.kind(text, g.intent)[0]
            assert g.intent.replace("_", " ") in g.reason and f"{decision.point().thresholds[k]:.2f}" in g.reason
            assert decision.KIND_WORDS[k] in g.reason


def test_shipped_head_is_structure_aware_with_reasons():
    head = sh.load()
    assert head.config.inputs in ("structure", "tuned") and head.config.num_reasons == len(head.meta["reasons"])
    assert set(head.meta["reason_text"]) == set(head.meta["reasons"])
    assert head.meta["comparison"] and head.meta["selected"] in head.meta["comparison"]


def test_shipped_cue_prototypes_match_a_fresh_computation():
    fresh = cue_reducer.compute_prototypes()
    e, owner, inten = cue_reducer.prototypes()
    np.testing.assert_allclose(e, fresh["prototypes"], atol=1e-5)
    np.testing.assert_array_equal(owner, fresh["owner"])
    np.testing.assert_allclose(inten, fresh["intensities"], atol=1e-5)


def test_compilation_cache_folder_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("JGROUNDING_CACHE", str(tmp_path))
    assert encoder.cache_dir() == tmp_path / "jax"
    monkeypatch.setenv("JGROUNDING_CACHE", "off")
    assert encoder.cache_dir() is None
    monkeypatch.delenv("JGROUNDING_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert encoder.cache_dir() == tmp_path / "xdg" / "jgrounding" / "jax"


def test_training_is_deterministic_and_calibration_meets_its_target(tmp_path):
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root holds tools/
    from tools import train_semantics as ts

    rng = np.random.default_rng(0)
    rows = [{"text": "t", "intent": jg.INTENTS[i % 16], "intensity": jg.INTENSITIES[i % 4]} for i in range(48)]
    rows += [{"text": "n", "intent": "none", "intensity": None, "style": "system"} for _ in range(8)]
    x = rng.normal(size=(len(rows), 16)).astype(np.float32)
    x[np.arange(48), np.arange(48) % 16] += 4.0  # a separable signal
    reasons = ts.reason_classes(rows)
    assert reasons == ["none", "system"]
    opt = dict(inputs="eq3", hidden=8, steps=30)
    p1, cfg = ts.fit(x, rows, np.ones(len(rows)), reasons=reasons, **opt)
    p2, _ = ts.fit(x, rows, np.ones(len(rows)), reasons=reasons, **opt)
    assert sh.digest(p1) == sh.digest(p2) and cfg.num_reasons == 2
    pm, pz = (np.asarray(a) for a in sh.predict(p1, x, 1.0))
    t = semantics_calibration.calibrate_threshold(pm, pz, rows, target=0.05)
    assert ts.selective(pm, pz, rows, t)["confident_wrong"] <= 0.05
    path = sh.save(tmp_path / "head.npz", p1, cfg, {"temperature": 1.0, "threshold": t})
    with np.load(path) as f:
        assert {k.split("/", 1)[1] for k in f.files if k.startswith("param/")} == set(p1)


def test_the_threshold_keeps_the_situations_confident_wrongs_within_the_budget_too():
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from tools import train_semantics as ts

    def probs(right: list[bool], conf: float):
        pm = np.full((len(right), sh.NUM_CLASSES), (1 - conf) / (sh.NUM_CLASSES - 1))
        for i, ok in enumerate(right):
            pm[i, 0 if ok else 1] = conf
        return pm, np.full((len(right), 4), 0.25)

    dev = [{"text": "t", "intent": jg.INTENTS[0], "intensity": "subtle"}] * 50
    pm, pz = probs([True] * 50, 0.6)  # dev: every text right at 0.6
    sit_rows = [{"text": "s", "intent": jg.INTENTS[0], "intensity": "subtle"}] * 20
    spm, spz = probs([True] * 18 + [False] * 2, 0.7)  # situations: 10 % wrong at 0.7
    assert semantics_calibration.calibrate_threshold(pm, pz, dev) == 0.1
    t = semantics_calibration.calibrate_threshold(pm, pz, dev, situations=(spm, spz, sit_rows))
    assert t == 0.725 and ts.selective(spm, spz, sit_rows, t)["confident_wrong"] == 0
    # the situations' budget is its own (ts.SITUATION_TARGET_WRONG): 1 wrong of 20 (5 %) passes a 5 % one
    spm[19] = spm[0]  # the second wrong situation is now right: 1 of 20 wrong at 0.7
    assert (
        semantics_calibration.calibrate_threshold(pm, pz, dev, situations=(spm, spz, sit_rows), situation_target=0.05)
        == 0.1
    )
    assert (
        semantics_calibration.calibrate_threshold(pm, pz, dev, situations=(spm, spz, sit_rows), situation_target=0.01)
        == 0.725
    )


def test_semantics_module_exports_ground_many():
    assert semantics.ground_many is jg.ground_many


def test_tuned_layers_ship_as_float16_deltas_on_the_frozen_encoder():
    cfg = sh.HeadConfig(inputs="tuned", tuned_layers=2)
    base = encoder.load_params()
    top = jax.tree.map(lambda a: np.asarray(a[-2:]) + 0.01, base["layers"])
    deltas = sh.top_deltas(top, cfg)
    assert all(d.dtype == np.float16 for d in jax.tree.leaves(deltas))
    merged = sh.with_top(deltas, cfg)
    np.testing.assert_allclose(np.asarray(merged["layers"]["q"]["b"][-2:]), top["q"]["b"], atol=1e-5)
    np.testing.assert_array_equal(
        np.asarray(merged["layers"]["q"]["b"][:-2]), np.asarray(base["layers"]["q"]["b"][:-2])
    )
    # The matrices as grounding reads them: the float32 merge stored as encoder.MATRIX_STORAGE (int8 + scales).
    q = jax.tree.map(np.asarray, merged["layers"]["q"])
    assert q["w"].dtype == np.int8
    w = encoder.float_matrices(dict(layers={"q": q}))["layers"]["q"]["w"]
    step = np.abs(np.concatenate([np.asarray(base["layers"]["q"]["w"][:-2]), top["q"]["w"]])).max(-2) / 127
    assert np.all(np.abs(w[-2:] - top["q"]["w"]) <= step[-2:, None] / 2 + 1e-5)
    stored = encoder.stored_matrices(dict(layers={"q": {"w": np.asarray(base["layers"]["q"]["w"][:-2]), "b": 0}}))
    np.testing.assert_array_equal(q["w"][:-2], stored["layers"]["q"]["w"])
    flat = sh.flatten(deltas)
    assert "q/w" in flat and sh.unflatten(flat).keys() == deltas.keys()


def test_a_student_keeps_its_chosen_layers_all_shipped_as_deltas():
    cfg = sh.HeadConfig.from_dict(dict(inputs="tuned", tuned_layers=3, encoder_layers=[1, 3, 5]))
    assert cfg.encoder_layers == (1, 3, 5) and cfg.num_encoder_layers == 3
    base = encoder.load_numpy()["layers"]
    trained = jax.tree.map(lambda a: a[[1, 3, 5]] + 0.01, base)
    merged = sh.with_top(sh.top_deltas(trained, cfg), cfg)
    assert np.asarray(merged["layers"]["q"]["b"]).shape == (3, encoder.HIDDEN)
    np.testing.assert_allclose(np.asarray(merged["layers"]["q"]["b"]), trained["q"]["b"], atol=1e-5)
    ids, mask = encoder.tokenize(["Give a small hello wave."])
    assert np.asarray(encoder.token_states(merged, ids, mask)).shape == (1, ids.shape[1], encoder.HIDDEN)
    assert encoder.matmul_flops(16, layers=3) * 2 == encoder.matmul_flops(16)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(encoder_layers=(3, 1)), "increasing"),
        (dict(encoder_layers=(6,)), "0..5"),
        (dict(encoder_layers=(5,), tuned_layers=2), "tuned_layers"),
    ],
)
def test_a_bad_layer_choice_is_refused_with_the_valid_range(kw, match):
    with pytest.raises(ValueError, match=match):
        sh.HeadConfig(inputs="tuned", **kw)


def test_ship_rule_takes_the_fewest_layers_within_the_margin():
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from tools import train_semantics as ts

    six, three = (
        sh.HeadConfig(inputs="tuned", tuned_layers=3),
        sh.HeadConfig(inputs="tuned", tuned_layers=3, encoder_layers=(1, 3, 5)),
    )
    assert (
        ts.ship_choice({"tuned": (0.90, six), "student": (0.90 - semantics_calibration.SHIP_MARGIN / 2, three)})
        == "student"
    )
    assert (
        ts.ship_choice({"tuned": (0.90, six), "student": (0.90 - 2 * semantics_calibration.SHIP_MARGIN, three)})
        == "tuned"
    )
    assert ts.ship_choice({"eq3": (0.80, six), "tuned": (0.90, six)}) == "tuned"


def test_the_ship_score_counts_the_situation_hold_out_as_one_more_term():
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

    r = dict(intent_motion=0.9, intensity_exact=0.8, coverage_motion=0.9, none_held=0.9)
    plain = dict(intent_motion=1.0)
    assert semantics_calibration.dev_score(r, plain) == pytest.approx(0.9)
    assert semantics_calibration.dev_score(r, plain, dict(intent_motion=0.6)) == pytest.approx(0.85)
    # a better situation reader outranks a worse one with the same dev figures
    assert semantics_calibration.dev_score(r, plain, dict(intent_motion=0.8)) > semantics_calibration.dev_score(
        r, plain, dict(intent_motion=0.6)
    )


def test_a_default_training_run_compares_the_options_of_the_shipped_heads_run():
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from tools import train_semantics as ts

    assert set(ts.DEFAULT_OPTIONS) <= set(ts.OPTIONS)
    assert sh.load().meta["selected"] in ts.DEFAULT_OPTIONS
    report = json.loads((ts.ROOT / "results" / "semantics_dev_options.json").read_text())
    assert sorted(report) == sorted(ts.DEFAULT_OPTIONS)
