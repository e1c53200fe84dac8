"""The trained semantic head: ordinal intensity, the bounded decision, calibration, confidence gating."""

import io

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jgrounding as jg
from jgrounding.semantics import calibration, features
from jgrounding.semantics import head as sh
from tools import semantics_calibration


def test_ordinal_probabilities_are_a_distribution_with_ordered_cuts():
    params = sh.init(jax.random.key(0), sh.HeadConfig(hidden=0, inputs="embedding"))
    params["z_gaps"] = jnp.array([-3.0, 2.0])  # softplus keeps even a negative gap positive
    theta = np.asarray(sh.thresholds(params))
    assert np.all(np.diff(theta) > 0)
    x = jax.random.normal(jax.random.key(1), (5, features.EMBED_DIM))
    p = np.exp(np.asarray(sh.intensity_log_probs(params, x)))
    np.testing.assert_allclose(p.sum(1), 1.0, atol=1e-5)


def test_decision_is_a_vocabulary_tuple_and_none_only_lowers_confidence():
    p_intent = np.zeros((1, sh.NUM_CLASSES))
    p_intent[0, sh.NONE], p_intent[0, 3] = 0.7, 0.2  # "none" is the most likely class
    p_intent[0, 5] = 0.1
    m, z, conf = sh.decide(p_intent, np.array([[0.1, 0.2, 0.6, 0.1]]))
    assert (m[0], z[0]) == (3, 2) and conf[0] == pytest.approx(0.2)


def test_ece_by_hand():
    # Bin [0.9, 1.0): confidences 0.95, 0.95, right once -> |0.5 - 0.95| * 2/4;
    # bin [0.5, 0.6): 0.55, 0.55, both right -> |1 - 0.55| * 2/4.  ECE = 0.225 + 0.225.
    assert calibration.expected_calibration_error([0.95, 0.95, 0.55, 0.55], [1, 0, 1, 1]) == pytest.approx(0.45)


def test_shipped_head_loads_with_calibration():
    head = sh.load()
    assert 0.0 < head.threshold < 1.0 and head.temperature > 0
    assert sh.digest(head.params) == head.meta["params_digest"]


@pytest.mark.parametrize("text", ["jkl;", "Ctrl-C", "print the invoice"])
def test_junk_is_not_confident(text):
    g = jg.ground(text)
    assert g.intent in jg.INTENTS and not g.confident and g.reason


def test_refusal_and_agreement_without_their_names():
    assert jg.ground("No, you may not have that.").intent == "refusing"
    assert jg.ground("Yes, that sounds good to me.").intent == "nodding"


def test_cli_holds_still_below_threshold_unless_forced(tmp_path, capsys):
    from jgrounding.apps import cli

    assert cli.main(["jkl;", "--no-render", "--samples", "2", "--out", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "holding still: " + jg.ground("jkl;").reason in out  # the reason a person can read
    assert not np.load(tmp_path / "a" / "samples.npy").any()  # every tendon at rest: no motion
    assert cli.main(["jkl;", "--force", "--no-render", "--samples", "2", "--out", str(tmp_path / "b")]) == 0
    assert "driving it anyway" in capsys.readouterr().out
    assert np.load(tmp_path / "b" / "samples.npy").any()


def test_interactive_loop_emits_no_motion_for_junk(tmp_path):
    from jgrounding.apps import interact

    out = io.StringIO()
    interact.main(["--out", str(tmp_path)], stdin=io.StringIO("jkl;\n:history\n:force\n:quit\n"), stdout=out)
    text = out.getvalue()
    before_force = text.split("forcing")[0]
    assert "holding still: " + jg.ground("jkl;").reason in before_force and "tendons:" not in before_force
    assert "(empty)" in before_force  # nothing was driven, so nothing entered the history
    assert "tendons:" in text.split("forcing")[1] and (tmp_path / "turn001.png").exists()


def test_low_confidence_escalates_to_a_configured_mllm():
    from test_mllm import FakeServer  # same folder (pytest puts it on the path)

    with FakeServer(['{"intent": "resting", "intensity": "subtle"}']) as s:
        low = jg.ground("Maybe move a bit?", url=s.url)  # unsure, and not a text that calls for no motion
        high = jg.ground("Wave hello to the user!", url=s.url)
        kept = jg.ground("Maybe move a bit?", url=s.url, escalate=False)
    assert low.backend == "mllm (escalated)" and "escalated" in low.reason and low.intent == "resting"
    assert high.backend == "embedded" and high.confident and kept.backend == "embedded"
    assert len(s.requests) == 1  # only the low-confidence text was asked


def test_cut_points_set_on_a_head_are_the_ones_it_reads():
    params = sh.init(jax.random.key(0), sh.HeadConfig(hidden=0, inputs="embedding"))
    moved = calibration.with_cut_points(params, [-1.0, 0.5, 2.5])
    np.testing.assert_allclose(np.asarray(sh.thresholds(moved)), [-1.0, 0.5, 2.5], atol=1e-5)
    x = jax.random.normal(jax.random.key(1), (4, features.EMBED_DIM))
    s = sh.intensity_score(moved, x)  # the numpy form of the ordinal model equals the jax one
    np.testing.assert_allclose(
        sh.ordinal_log_probs(np.asarray(s, np.float64), np.array([-1.0, 0.5, 2.5]), xp=np),
        np.asarray(sh.intensity_log_probs(moved, x)),
        atol=1e-5,
    )
    with pytest.raises(ValueError, match="strictly increasing"):
        calibration.with_cut_points(params, [0.0, 0.0, 1.0])


def test_cut_points_fitted_on_dev_move_toward_the_labels():

    params = sh.init(jax.random.key(0), sh.HeadConfig(hidden=0, inputs="embedding"))
    x = jax.random.normal(jax.random.key(2), (400, features.EMBED_DIM))
    s = np.asarray(sh.intensity_score(params, x), np.float64)
    theta = np.asarray(sh.thresholds(params), np.float64)
    # Labels drawn from cut points 0.75 higher than the trained ones: every level is reached later.
    rng = np.random.default_rng(0)
    p = np.exp(sh.ordinal_log_probs(s, theta + 0.75, xp=np))
    z = np.array([rng.choice(4, p=row / row.sum()) for row in p])
    rows = [{"intent": "nodding", "intensity": jg.INTENSITIES[k]} for k in z]
    rows.append({"intent": "none", "intensity": None})  # no-behaviour rows carry no intensity: skipped
    cuts, shift = semantics_calibration.fit_cut_points(
        params, np.concatenate([np.asarray(x), np.zeros((1, features.EMBED_DIM))]), rows
    )
    assert np.all(shift > 0) and np.all(np.abs(shift - 0.75) <= 0.5)
    np.testing.assert_allclose(cuts, theta + shift)
