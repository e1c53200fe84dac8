"""The encoder-distillation trial (experiments/distill_encoder.py, issue #34 item 4): its student is the teacher's
chosen layers, its final states are the encoder's own (the pooled sentence vector matches encoder.pool_ids), and a
few steps on a handful of texts lower the distillation loss without touching the frozen embeddings."""

import numpy as np

from experiments import distill_encoder as de
from jgrounding.semantics import encoder


def test_the_student_is_the_teachers_chosen_layers():
    teacher = encoder.load_numpy()
    student = de.student_of(teacher, 3)
    np.testing.assert_array_equal(np.asarray(student["layers"]["q"]["w"]), teacher["layers"]["q"]["w"][[1, 3, 5]])
    assert student["word"] is teacher["word"]


def test_states_pool_to_the_encoders_sentence_vector():
    params = encoder.load_params()
    ids, mask = encoder.tokenize(["Give a small hello wave."])
    x = np.asarray(encoder.token_states(params, ids, mask))
    m = mask[..., None].astype(np.float32)
    pooled = (x * m).sum(1) / m.sum(1)
    pooled /= np.linalg.norm(pooled, axis=-1, keepdims=True)
    np.testing.assert_allclose(pooled, np.asarray(encoder.encode_ids(params, ids, mask)), atol=1e-5)


def test_a_few_steps_lower_the_loss_and_keep_the_embeddings(monkeypatch):
    monkeypatch.setattr(de, "BATCH", 4)
    texts = [f"Please {w} the guest at the door, {a}." for w in ("greet", "hug", "wave at") for a in ("gently", "now")]
    teacher = encoder.load_numpy()
    student, losses = de.distill(teacher, 2, 40, texts[:4], progress=False)
    assert losses[-1][1] < losses[0][1]
    np.testing.assert_array_equal(np.asarray(student["word"]), teacher["word"])
    assert np.asarray(student["layers"]["q"]["w"]).shape[0] == 2
