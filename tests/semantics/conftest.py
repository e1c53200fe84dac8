"""Shared fixtures of the semantics tests."""

import pytest

from jgrounding.semantics import head as sh


@pytest.fixture(scope="module")
def head():
    """The shipped head: the tuned one, with its nearest-neighbour table."""
    h = sh.load()
    assert h.config.inputs == "tuned", "the shipped head is the tuned one (these paths are its)"
    assert h.knn is not None, (
        "the shipped head comes with its nearest-neighbour table (jgrounding/assets/semantic_knn.npz)"
    )
    return h
