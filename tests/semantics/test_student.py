"""The distilled student encoder (#34 item 4; tools/train_semantics.py's "student" option): it starts as the
teacher's chosen layers, its final states are the encoder's own (the pooled sentence vector matches
encoder.encode_ids), and a few distillation steps lower the loss without touching the frozen embeddings."""

import hashlib
import sys
from pathlib import Path

import jax
import numpy as np

from jgrounding.semantics import encoder

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository root holds tools/
from tools import semantics_data  # noqa: E402
from tools import semantics_training as st  # noqa: E402
from tools import train_semantics as ts  # noqa: E402

TEXTS = [f"Please {w} the guest at the door, {a}." for w in ("greet", "hug", "wave at") for a in ("gently", "now")]


def test_states_pool_to_the_encoders_sentence_vector():
    params = encoder.load_params()
    ids, mask = encoder.tokenize(["Give a small hello wave."])
    x = np.asarray(encoder.token_states(params, ids, mask))
    m = mask[..., None].astype(np.float32)
    pooled = (x * m).sum(1) / m.sum(1)
    pooled /= np.linalg.norm(pooled, axis=-1, keepdims=True)
    np.testing.assert_allclose(pooled, np.asarray(encoder.encode_ids(params, ids, mask)), atol=1e-5)


def test_the_student_starts_as_the_chosen_layers_and_a_few_steps_lower_the_loss(monkeypatch):
    monkeypatch.setattr(st, "DISTILL_BATCH", 4)
    teacher = encoder.load_numpy()
    first, _ = st.distill(teacher, (2, 5), TEXTS[:4], steps=1, progress=False)
    student, losses = st.distill(teacher, (2, 5), TEXTS[:4], steps=40, progress=False)
    assert losses[-1][1] < losses[0][1]
    np.testing.assert_array_equal(np.asarray(student["word"]), teacher["word"])
    assert np.asarray(student["layers"]["q"]["w"]).shape[0] == 2
    # It starts from the chosen layers: one AdamW step moves each weight by about the learning rate at most.
    moved = np.abs(np.asarray(first["layers"]["q"]["w"]) - teacher["layers"]["q"]["w"][[2, 5]]).max()
    assert 0 < moved <= 2 * st.DISTILL_LR


def test_a_distillation_is_cached_and_read_back(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(st, "DISTILL_BATCH", 4)
    monkeypatch.setattr(st, "DISTILL_STEPS", 3)
    monkeypatch.setattr(st, "CACHE", tmp_path)
    teacher = encoder.load_numpy()
    first = st.cached_distill(teacher, (1, 4), TEXTS[:4])
    assert len(list(tmp_path.glob("distill-*.npz"))) == 1
    second = st.cached_distill(teacher, (1, 4), TEXTS[:4])
    assert "distilled before" in capsys.readouterr().out
    for a, b in zip(jax.tree.leaves(first), jax.tree.leaves(second)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    st.cached_distill(teacher, (1, 4), TEXTS[1:5])  # other texts: another distillation
    assert len(list(tmp_path.glob("distill-*.npz"))) == 2


def test_the_extra_distillation_texts_are_situations_without_motion_labels_used():
    texts = semantics_data.distill_texts()
    assert len(texts) == 2048 and len(set(texts)) > 2000
    held = {r["text"] for r in ts.read_situations(ts.SITUATION_DEVS)}
    assert not held & set(texts)  # the situation selection set is never distilled on


def test_recalibrating_the_shipped_head_on_its_own_sets_gives_back_its_calibration(tmp_path, capsys):
    """``tools.train_semantics --recalibrate`` (calibrate again, train nothing) on the situation hold-outs the shipped
    head was calibrated on gives its temperature, threshold and cut points back, and the same probabilities."""
    from jgrounding.semantics import head as sh

    shipped = sh.load()
    # the hold-outs it was calibrated on, as its meta records them (file name: sha256 prefix), are SITUATION_DEVS
    paths = list(ts.SITUATION_DEVS)
    digests = [hashlib.sha256(path.read_bytes()).hexdigest()[:16] for path in paths]
    assert list(shipped.meta["situation_files"].values()) == digests
    out = tmp_path / "head.npz"
    out.write_bytes(Path(sh.ASSET).read_bytes())
    assert ts.main(["--recalibrate", "--situations", ",".join(map(str, paths)), "--out", str(out)]) == 0
    again = sh.load(str(out))
    assert (again.meta["temperature"], again.meta["threshold"]) == (
        shipped.meta["temperature"],
        shipped.meta["threshold"],
    )
    assert again.meta["cut_points"] == shipped.meta["cut_points"]
    for name in shipped.params:
        np.testing.assert_allclose(np.asarray(again.params[name]), np.asarray(shipped.params[name]), rtol=1e-6)
    assert again.meta["recalibrated_from"]["params_digest"] == shipped.meta["params_digest"]
    assert "recalibrated head.npz" in capsys.readouterr().out
