"""The library designs' code words as data (jgrounding/library/code_words.py): each stored file is exactly what
its writer renders from the code it holds, and the designs read the same numbers."""

import numpy as np
import pytest

from jgrounding.library import code_words, designs, primitives
from jgrounding.vocabulary import INTENTS


@pytest.mark.parametrize("version", code_words.VERSIONS)
def test_each_stored_code_is_its_own_rendering_byte_for_byte(version):
    words = code_words.load(version)
    assert words.code.shape[0] == len(INTENTS) and words.code.shape[-2:] == (4, 4)
    assert code_words.render(version, words.code, words.num_variants) == code_words.path(version).read_text()
    assert (words.num_variants is None) == (version == 3)


def test_the_designs_read_the_stored_codes():
    np.testing.assert_array_equal(primitives.CODE, code_words.load(3).code)
    for version in (4, 5):
        design = designs.get(version)
        words = code_words.load(version)
        np.testing.assert_array_equal(design.code, words.code)
        assert design.num_variants.tolist() == [words.num_variants[m] for m in INTENTS]


def test_an_unknown_version_and_a_wrong_shape_are_refused():
    with pytest.raises(ValueError, match="valid"):
        code_words.load(6)
    with pytest.raises(ValueError, match="4, 4"):
        code_words.render(4, np.zeros((16, 3, 4, 4, 3)))
