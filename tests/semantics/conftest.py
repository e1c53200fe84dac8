"""Shared fixtures of the semantics tests."""

import dataclasses
import json

import pytest

from jgrounding.semantics import features
from jgrounding.semantics import head as sh
from tools import semantic_sets, semantics_data

SITUATIONS = semantic_sets.path("train/corpora", "situations.jsonl")


@pytest.fixture(scope="module")
def head():
    """The shipped head: the tuned one (with the nearest-neighbour table made for it, where one ships)."""
    h = sh.load()
    assert h.config.inputs == "tuned", "the shipped head is the tuned one (these paths are its)"
    return h


@pytest.fixture(scope="module")
def head_with_vote(head, tmp_path_factory):
    """The shipped head with a small nearest-neighbour table made for it here (the shipped variant's form: its
    sentence vectors, the "no motion words" gate, an intensity vote; 64 training situations), so the vote's paths are tested whether
    or not a table ships (tools.semantics_knn ships one only when it passes its rule on dev)."""
    from tools import semantics_vote

    rows = [json.loads(line) for line in SITUATIONS.read_text().splitlines()[:64]]
    x = features.head_inputs(head, [r["text"] for r in rows])
    table = semantics_vote.representation("sentence", head.params, x)
    labels, intensities = semantics_data.labels(rows)
    gate = semantics_vote.gate_vector(x.shape[1] - semantics_vote.POOLED)
    meta = dict(k=10, tau=0.05, a=0.5, b=0.5, head_digest=head.meta["params_digest"], threshold=head.threshold, rows=64)
    path = sh.save_knn(tmp_path_factory.mktemp("knn") / "knn.npz", table, labels, gate, meta, intensities)
    return dataclasses.replace(head, knn=sh.load_knn(head.meta["params_digest"], path))
