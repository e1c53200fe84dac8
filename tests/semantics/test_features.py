"""The head's named input pipelines (jgrounding.semantics.features), the cue words of spec C
(jgrounding.semantics.cues) and the intent conditioning (jgrounding.semantics.conditioning)."""

import json

import numpy as np
import pytest

from jgrounding.semantics import conditioning, cues, encoder, features, structure
from jgrounding.semantics import head as sh
from jgrounding.vocabulary import INTENTS, NUM_INTENTS
from tools import semantic_sets

OLD_HEAD = semantic_sets.path("bench/head_v1")
TEXTS = ["Rather than a big hug, just give a small wave.", "WAVE HELLO NOW!!"]


@pytest.mark.parametrize("name", list(features.INPUTS))
def test_every_pipeline_computes_its_registered_width(name):
    cfg = sh.HeadConfig(inputs=name)
    head = sh.Head({}, cfg, 1.0, 0.5, {})  # the frozen encoder: what the non-tuned pipelines read
    x = features.head_inputs(head, TEXTS)
    assert x.shape == (len(TEXTS), cfg.num_features) and x.dtype == np.float32
    assert np.all(np.isfinite(x))


def test_widths_by_hand():
    # 384 the embedding; 16 Eq. (3) intent scores + 4 degree cues; 4 poolings; 16 + 16 named or scored intents.
    assert features.EMBED_DIM == encoder.HIDDEN == 384
    assert features.INPUTS["embedding"].width == 384
    assert features.INPUTS["eq3"].width == 384 + 16 + 4
    assert features.INPUTS["structure"].width == 4 * 384 + 20 + 16 + structure.NUM_FLAGS
    assert features.INPUTS["tuned"].width == 4 * 384 + 16 + 4 + 16 + structure.NUM_FLAGS
    assert features.TUNED_FLAGS_START == 2 * NUM_INTENTS + 4


def test_an_unknown_pipeline_names_the_valid_ones():
    with pytest.raises(ValueError, match="embedding, eq3, structure, tuned"):
        sh.HeadConfig(inputs="sentence")


def test_older_head_files_name_their_pipeline_by_use_eq3():
    assert sh.HeadConfig.from_dict({"use_eq3": True, "hidden": 8}).inputs == "eq3"
    assert sh.HeadConfig.from_dict({"use_eq3": False}).inputs == "embedding"
    assert sh.HeadConfig.from_dict({"use_eq3": True, "inputs": ""}).inputs == "eq3"
    assert sh.HeadConfig.from_dict({"use_eq3": True, "inputs": "tuned"}).inputs == "tuned"
    with np.load(OLD_HEAD) as f:  # the first head, read by bench semantics (a development file: not shipped)
        assert sh.HeadConfig.from_dict(json.loads(str(f["config"]))).inputs == "eq3"


def test_tuned_extras_put_the_flags_where_the_vote_reads_them():
    text = "[log] 12:00 user said hello"
    st = structure.analyse(text)
    x = features.tuned_extras(text, st)
    assert x.shape == (features.TUNED_EXTRAS,)
    np.testing.assert_array_equal(x[features.TUNED_FLAGS_START :], st.flags)


def test_every_intent_has_cue_phrases_and_a_lexical_pattern():
    assert set(cues.CUES) == set(cues.LEXICAL) == set(INTENTS)
    assert all(len(p) >= 4 for p in cues.CUES.values())
    assert sorted(cues.DEGREE) == [0, 1, 2, 3]  # subtle .. emphatic


def test_intent_conditioning_embeds_each_intents_label_and_description():
    assert conditioning.intent_text("attentive_listening").startswith("attentive listening: ")
    e = conditioning.intent_embeddings()
    assert e.shape == (NUM_INTENTS, 384) and e.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(e, axis=1), 1.0, atol=1e-5)
