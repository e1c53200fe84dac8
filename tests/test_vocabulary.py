import numpy as np
import pytest

import jgrounding as jg
from jgrounding import vocabulary as voc


def test_vocabulary_matches_spec():
    assert len(jg.INTENTS) == 16 and len(set(jg.INTENTS)) == 16
    assert jg.INTENSITIES == ("subtle", "moderate", "pronounced", "emphatic")
    assert set(voc.INTENT_DESCRIPTIONS) == set(jg.INTENTS)


def test_names_and_indices_round_trip():
    for i, name in enumerate(jg.INTENTS):
        assert jg.intent_index(name) == i == jg.intent_index(i)
    assert jg.intent_index("Attentive Listening") == jg.INTENTS.index("attentive_listening")
    assert jg.intensity_index(np.int32(2)) == 2
    assert voc.tuple_index("farewell", "emphatic") == 1 * 4 + 3


@pytest.mark.parametrize("bad", ["dancing", 16, -1, 3.5, None, True])
def test_bad_intent_names_the_valid_choices(bad):
    with pytest.raises(ValueError, match="greeting"):
        jg.intent_index(bad)


def test_bad_intensity_names_the_valid_choices():
    with pytest.raises(ValueError, match="subtle, moderate, pronounced, emphatic"):
        jg.intensity_index("extreme")


def test_descriptions_are_distinct_per_tuple():
    texts = {voc.describe(m, z) for m in jg.INTENTS for z in jg.INTENSITIES}
    assert len(texts) == 64
