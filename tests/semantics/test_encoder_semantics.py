"""The JAX MiniLM encoder and the embedded semantic reducer (Sec. III-A)."""

from pathlib import Path

import numpy as np
import pytest

import jgrounding as jg
from jgrounding import semantics
from jgrounding.semantics import encoder

REF = Path(__file__).resolve().parents[1] / "data" / "minilm_reference.npz"


def test_encoder_reproduces_reference_embeddings():
    ref = np.load(REF)
    emb = encoder.embed(list(ref["sentences"]))
    assert emb.shape == (len(ref["sentences"]), 384)
    np.testing.assert_allclose(emb, ref["embeddings"], atol=1e-4)


def test_embeddings_are_unit_and_batch_independent():
    texts = ["hello there", "a much longer sentence about a robot trunk waving at people " * 3]
    both = encoder.embed(texts)
    np.testing.assert_allclose(np.linalg.norm(both, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(encoder.embed(texts[:1]), both[:1], atol=1e-5)


def test_shipped_intent_embeddings_match_a_fresh_computation():
    np.testing.assert_allclose(semantics.intent_embeddings(), semantics.compute_intent_embeddings(), atol=1e-5)


@pytest.mark.parametrize(
    "text, intent",
    [
        ("User seems sad; respond calmly with a gentle touch.", "comforting"),
        ("They are leaving now, wave goodbye.", "farewell"),
        ("The user said I'm too close; back away and give them space.", "withdrawal"),
        ("Agree with the user by nodding.", "nodding"),
    ],
)
def test_clear_responses_ground_to_their_intent(text, intent):
    g = jg.ground(text)
    assert g.intent == intent and g.backend == "embedded" and g.confident


def test_intensity_follows_degree_cues():
    low = jg.ground("Slightly nod, barely moving, to acknowledge.")
    high = jg.ground("Nod enthusiastically with full energy!!")
    assert low.intensity_index < high.intensity_index
    assert low.intensity == "subtle" and high.intensity == "emphatic"


@pytest.mark.parametrize("text", ["asdkjh qwpoeiru zxmcnv", "???", "これは日本語の文です", "x" * 5000])
def test_degenerate_text_is_flagged_not_crashing(text):
    g = jg.ground(text)
    assert g.intent in jg.INTENTS and g.intensity in jg.INTENSITIES
    assert not g.confident and g.reason


@pytest.mark.parametrize("bad, exc", [("", ValueError), ("   ", ValueError), (None, TypeError), (3, TypeError)])
def test_invalid_text_raises(bad, exc):
    with pytest.raises(exc):
        jg.ground(bad)


def test_unknown_backend_names_the_choices():
    with pytest.raises(ValueError, match="embedded, cues, mllm"):
        jg.ground("hello", backend="gpt")
