"""The nearest-neighbour vote over the training texts, blended into the tuned head's intent (#24)."""

import dataclasses
import json

import numpy as np
import pytest

from jgrounding.semantics import embedded, features
from jgrounding.semantics import head as sh
from jgrounding.vocabulary import INTENTS
from tools import semantic_sets, semantics_data, semantics_knn, semantics_vote, train_semantics

SITUATIONS = semantic_sets.path("train/corpora", "situations.jsonl")  # the rows of conftest's head_with_vote table

NAMES_AN_ACTION = [
    "Nod.",
    "The user looks sad; comfort them gently.",
    "Rather than waving wildly, just give a small nod to show you heard them.",
]


def test_a_shipped_table_is_the_shipped_heads_and_passed_its_rule(head):
    # tools.semantics_knn --write ships a table only when the vote passes its rule on dev for the shipped head,
    # and removes one made for an earlier head; the head it was made for is the only one that reads it.
    if not sh.KNN_ASSET.exists():
        assert head.knn is None and sh.load_knn(head.meta["params_digest"]) is None
        return
    with np.load(sh.KNN_ASSET) as f:
        meta = json.loads(str(f["meta"]))
        table, labels = f["table"], f["labels"]
    assert meta["digest"] == sh.knn_digest(table, labels) == head.knn["meta"]["digest"]
    assert meta["head_digest"] == head.meta["params_digest"]
    assert table.shape == (meta["rows"], features.EMBED_DIM) and labels.max() <= sh.NONE
    np.testing.assert_allclose(np.linalg.norm(table.astype(np.float32), axis=1), 1.0, atol=2e-3)
    assert head.threshold == meta["threshold"] and head.knn_k == meta["k"]
    assert meta["dev_score"] > meta["head_alone"]["score"]  # it shipped under the ship rule


def test_the_table_rows_hold_the_vote_only_rows_that_the_head_never_trained_on():
    # The table's rows: the training corpora, then the vote-only situations (assets/semantics/train/vote/), in
    # tools.semantics_knn.table_rows' order. The head's trainer must not read the vote-only rows.
    # The blind writers' training splits follow (the head trains on them; only the "+blind" table holds them).
    rows, files = semantics_knn.table_rows()
    vote_only = np.isin(files, [p.name for p in semantics_knn.VOTE_ROWS])
    blind = np.char.startswith(files.astype(str), "blind/")
    assert vote_only.sum() == 1024 and (files != "generated.jsonl")[vote_only].all()
    corpora, _ = train_semantics.load_train(blind=())
    assert len(corpora) == len(rows) - vote_only.sum() - blind.sum()
    assert blind.sum() == sum(len(train_semantics.read_jsonl(p)) for p in train_semantics.BLIND_TRAIN)
    assert blind[-blind.sum() :].all()
    trained, _ = train_semantics.load_train()
    assert not {r["text"] for r in trained} & {r["text"] for r, v in zip(rows, vote_only) if v}


def _unit_rows(seed: int, n: int) -> np.ndarray:
    table = np.random.default_rng(seed).normal(size=(n, features.EMBED_DIM))
    return table / np.linalg.norm(table, axis=1, keepdims=True)


def _refused_once_reversed(path, key: str) -> None:
    """Reverse one array of a saved table: loading it must fail on its digest."""
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files}
    arrays[key] = arrays[key][::-1].copy()
    np.savez(path, **arrays)
    with pytest.raises(ValueError, match="digest"):
        sh.load_knn("x", path)


def test_a_table_for_another_head_is_not_used_and_a_tampered_one_is_refused(tmp_path):
    table = _unit_rows(0, 6)
    path = sh.save_knn(
        tmp_path / "knn.npz", table, np.arange(6), np.zeros(4), dict(k=2, tau=0.05, a=0.5, head_digest="x")
    )
    assert sh.load_knn("another head", path) is None
    assert sh.load_knn("x", path)["meta"]["k"] == 2
    _refused_once_reversed(path, "labels")


def test_a_table_with_an_intensity_vote_loads_it_and_its_labels_are_in_the_digest(tmp_path):
    table = _unit_rows(1, 5)
    meta = dict(k=2, tau=0.05, a=0.5, b=0.4, head_digest="x")
    z = np.array([0, 3, -1, 2, 1])
    path = sh.save_knn(tmp_path / "knn.npz", table, np.arange(5), np.zeros(4), meta, intensities=z)
    arrays = sh.load_knn("x", path)["arrays"]
    onehot_z = np.asarray(arrays["onehot_z"])
    np.testing.assert_array_equal(onehot_z[[0, 1, 3, 4]], np.eye(4)[[0, 3, 2, 1]])
    assert not onehot_z[2].any() and float(arrays["b"]) == pytest.approx(0.4)  # no label: no intensity vote
    _refused_once_reversed(path, "intensities")
    # b = 0 (or no intensities): the table carries no intensity vote
    path = sh.save_knn(tmp_path / "k0.npz", table, np.arange(5), np.zeros(4), dict(meta, b=0.0), intensities=z)
    assert "onehot_z" not in sh.load_knn("x", path)["arrays"]


def test_the_vote_moves_a_situation_toward_its_neighbours_intent(head_with_vote):
    # Situations of the table that the vote's gate lets through (they name no motion) are their own nearest
    # neighbours: the blend moves the one the head is least sure of toward the intent it is labelled.
    rows = [json.loads(line) for line in open(SITUATIONS).read().splitlines()[:64]]
    texts = [r["text"] for r in rows]
    voted = semantics_vote.no_motion_words(features.head_inputs(head_with_vote, texts))
    assert voted.sum() >= 8
    alone = dataclasses.replace(head_with_vote, knn=None)
    p_alone = embedded.predict_tuned_many(alone, texts)[0]
    p_vote = embedded.predict_tuned_many(head_with_vote, texts)[0]
    label = np.array([INTENTS.index(r["intent"]) if r["intent"] != "none" else sh.NONE for r in rows])
    mine = np.arange(len(rows))
    k = int(mine[voted][np.argmin(p_alone[voted, label[voted]])])
    assert p_vote[k, label[k]] > p_alone[k, label[k]] + 0.02
    np.testing.assert_allclose(p_vote[~voted], p_alone[~voted], atol=1e-6)  # the gate: no vote
    np.testing.assert_allclose(p_vote.sum(1), 1.0, atol=1e-5)


def test_texts_that_name_an_action_keep_the_head_alone(head_with_vote):
    alone = dataclasses.replace(head_with_vote, knn=None)
    for a, b in zip(
        embedded.predict_tuned_many(head_with_vote, NAMES_AN_ACTION),
        embedded.predict_tuned_many(alone, NAMES_AN_ACTION),
    ):
        np.testing.assert_allclose(a, b, atol=1e-6)


def _random_vote(seed: int, rows: int, queries: int):
    """A random unit table, its labels, unit queries and head distributions."""
    rng = np.random.default_rng(seed)
    table = rng.normal(size=(rows, 8)).astype(np.float32)
    table /= np.linalg.norm(table, axis=1, keepdims=True)
    labels = rng.integers(0, sh.NUM_CLASSES, rows)
    q = rng.normal(size=(queries, 8)).astype(np.float32)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    p = rng.dirichlet(np.ones(sh.NUM_CLASSES), queries).astype(np.float32)
    return table, labels, q, p


def test_shipped_blend_equals_the_dev_comparison():
    """sh.knn_blend (in the compiled program) is the vote tools.semantics_knn compared on dev."""
    table, labels, q, p = _random_vote(1, 50, 5)
    extras = np.zeros((5, 3), np.float32)
    extras[1, 0] = 1.0  # names an action: no vote
    knn = dict(table=table, onehot=np.eye(sh.NUM_CLASSES, dtype=np.float32)[labels], gate=np.array([1.0, 0, 0]))
    knn |= dict(tau=np.float32(0.05), a=np.float32(0.4))
    pz = np.full((5, 4), 0.25, np.float32)
    got, got_z = (np.asarray(a) for a in sh.knn_blend(knn, p, pz, q, extras, 7))
    np.testing.assert_array_equal(got_z, pz)  # no intensity vote in this table
    want = 0.6 * p + 0.4 * semantics_vote.knn_vote(q, table, labels, 7, 0.05)
    want[1] = p[1]
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_the_intensity_vote_blends_the_labelled_neighbours_intensities_for_the_gated_texts():
    """The intensity vote: the same k neighbours (weights exp((sim - best) / tau)), those with an intensity label,
    blended with weight b into the head's intensity for the texts the gate lets through; a text whose
    neighbours hold no intensity label, or that the gate stops, keeps the head's."""
    table, labels, q, p = _random_vote(3, 30, 6)
    rng = np.random.default_rng(3)
    z = rng.integers(-1, 4, 30)
    extras = np.zeros((6, 2), np.float32)
    extras[4, 0] = 1.0  # names an action: no vote
    pz = rng.dirichlet(np.ones(4), 6).astype(np.float32)
    knn = dict(table=table, onehot=np.eye(sh.NUM_CLASSES, dtype=np.float32)[labels], gate=np.array([1.0, 0.0]))
    knn |= dict(tau=np.float32(0.05), a=np.float32(0.5), b=np.float32(0.3))
    knn["onehot_z"] = np.eye(5, dtype=np.float32)[z][:, :4]
    _, got = sh.knn_blend(knn, p, pz, q, extras, 4)
    sim = q @ table.T
    top = np.argsort(-sim, 1)[:, :4]
    s = np.take_along_axis(sim, top, 1)
    w = np.exp((s - s[:, :1]) / 0.05)
    want = pz.astype(np.float64).copy()
    for i in range(6):
        vote = np.zeros(4)
        for j in range(4):
            if z[top[i, j]] >= 0:
                vote[z[top[i, j]]] += w[i, j]
        if i != 4 and vote.sum() > 0:
            want[i] = 0.7 * pz[i] + 0.3 * vote / vote.sum()
    np.testing.assert_allclose(np.asarray(got), want, atol=1e-5)
    assert not np.allclose(want, pz)  # the vote moved some text


def test_shipped_blend_applies_the_fitted_temperature_to_every_text():
    """With a blend temperature in the table (fitted on dev by tools.semantics_knn), every text's blended
    distribution is sharpened as the dev comparison sharpened it, the texts that skip the vote included."""
    table, labels, q, p = _random_vote(2, 40, 4)
    extras = np.zeros((4, 2), np.float32)
    extras[2, 1] = 1.0  # names an action: no vote, but the temperature still applies
    knn = dict(table=table, onehot=np.eye(sh.NUM_CLASSES, dtype=np.float32)[labels], gate=np.array([1.0, 1.0]))
    knn |= dict(tau=np.float32(0.05), a=np.float32(0.7), temperature=np.float32(0.6))
    pz = np.full((4, 4), 0.25, np.float32)
    got = np.asarray(sh.knn_blend(knn, p, pz, q, extras, 5)[0])
    blend = 0.3 * p + 0.7 * semantics_vote.knn_vote(q, table, labels, 5, 0.05)
    blend[2] = p[2]
    np.testing.assert_allclose(got, semantics_vote.sharpen(blend, 0.6), atol=1e-5)
    knn["gate"] = np.zeros(2, np.float32)  # an empty gate: every text votes
    got = np.asarray(sh.knn_blend(knn, p, pz, q, extras, 5)[0])
    blend = 0.3 * p + 0.7 * semantics_vote.knn_vote(q, table, labels, 5, 0.05)
    np.testing.assert_allclose(got, semantics_vote.sharpen(blend, 0.6), atol=1e-5)


def test_a_situation_temperature_sharpens_only_the_texts_the_gate_lets_through(tmp_path):
    """With a ``situation_temperature`` (tools.semantics_knn --situation-temperature), the gated texts' blend is
    sharpened again; the texts the gate stops keep the blend (here the head) untouched. It round-trips through
    save_knn / load_knn, and a meta without one (the shipped table's) loads none."""
    table, labels, q, p = _random_vote(4, 40, 5)
    extras = np.zeros((5, 2), np.float32)
    extras[3, 0] = 1.0  # names an action: no vote, no situation temperature
    knn = dict(table=table, onehot=np.eye(sh.NUM_CLASSES, dtype=np.float32)[labels], gate=np.array([1.0, 1.0]))
    knn |= dict(tau=np.float32(0.05), a=np.float32(0.5), situation_temperature=np.float32(0.7))
    pz = np.full((5, 4), 0.25, np.float32)
    got = np.asarray(sh.knn_blend(knn, p, pz, q, extras, 5)[0])
    blend = 0.5 * p + 0.5 * semantics_vote.knn_vote(q, table, labels, 5, 0.05)
    want = semantics_vote.sharpen(blend, 0.7)
    want[3] = p[3]
    np.testing.assert_allclose(got, want, atol=1e-5)
    meta = dict(k=5, tau=0.05, a=0.5, head_digest="x")
    path = sh.save_knn(
        tmp_path / "t.npz", _unit_rows(4, 6), np.arange(6), np.zeros(2), meta | {"situation_temperature": 0.7}
    )
    assert float(sh.load_knn("x", path)["arrays"]["situation_temperature"]) == pytest.approx(0.7)
    path = sh.save_knn(
        tmp_path / "n.npz", _unit_rows(4, 6), np.arange(6), np.zeros(2), meta | {"situation_temperature": 1.0}
    )
    assert "situation_temperature" not in sh.load_knn("x", path)["arrays"]


def test_the_situation_temperature_is_fitted_on_the_gated_hold_out_texts_only():
    # Gated texts whose blend is right but underconfident: the fitted temperature sharpens (< 1); the texts the
    # gate stops (confidently wrong here) do not enter the fit.
    rng = np.random.default_rng(5)
    intents = rng.integers(0, len(INTENTS), 60)
    pm = np.full((60, sh.NUM_CLASSES), 0.3 / (sh.NUM_CLASSES - 1), np.float32)
    pm[np.arange(60), intents] = 0.7
    gated = np.arange(60) < 40
    pm[~gated] = np.roll(pm[~gated], 1, axis=1)  # wrong, confidently: would call for a softer temperature
    rows = [
        dict(text=f"t{i}", intent=INTENTS[c], intensity="moderate", style="situation") for i, c in enumerate(intents)
    ]
    t = semantics_vote.fit_situation_temperature(pm, gated, rows)
    assert t < 1.0
    assert semantics_vote.fit_situation_temperature(pm, np.ones(60, bool), rows) > t


def test_a_tighter_confident_wrong_budget_never_lowers_the_threshold_nor_adds_wrong_motions():
    rng = np.random.default_rng(0)
    rows = [{"intent": INTENTS[i % 16], "intensity": "moderate", "style": "situation"} for i in range(200)]
    rows += [{"intent": "none", "intensity": None, "style": "none"} for _ in range(40)]
    intent, _ = semantics_data.labels(rows)
    logits = rng.normal(0, 1, (len(rows), sh.NUM_CLASSES))
    logits[np.arange(len(rows)), intent] += rng.uniform(0, 4, len(rows))  # mostly right, some confidently wrong
    pm = np.exp(logits) / np.exp(logits).sum(1, keepdims=True)
    pz = np.full((len(rows), 4), 0.25)
    r = semantics_vote.evaluate(pm, pz, rows, pm, pz, rows, False, budgets=semantics_vote.BUDGETS)
    b = [r["budgets"][t] for t in semantics_vote.BUDGETS]  # loosest first
    assert r["budgets"][train_semantics.TARGET_WRONG]["threshold"] == r["threshold"]
    assert [x["threshold"] for x in b] == sorted(x["threshold"] for x in b)
    assert [x["dev"]["confident_wrong"] for x in b] == sorted((x["dev"]["confident_wrong"] for x in b), reverse=True)
    for target, x in r["budgets"].items():
        assert x["dev"]["confident_wrong"] <= target or x["threshold"] == 0.975
    assert "budget 0.010: thr" in semantics_vote.budget_line(r)


def test_the_vote_written_is_the_best_dev_score_that_passes_the_rule_the_earlier_on_a_tie():
    assert semantics_vote.best_passing([0.92, 0.93, 0.95], [True, True, False]) == 1
    assert semantics_vote.best_passing([0.927, 0.927, 0.93], [True, True, False]) == 0  # a tie: the earlier
    assert semantics_vote.best_passing([0.9, 0.9], [False, False]) is None
    assert [c["b"] for c in semantics_knn.CHOICES] == [0.0, 0.5, 0.0, 0.5]  # each table without, then with


def test_a_votes_threshold_adds_no_confident_wrong_over_the_heads_on_dev():
    """vote_target: a vote's dev budget is the head's own confident-wrong rate where that is below TARGET_WRONG, so the
    threshold evaluate() fits for it meets the ship rule's 'no more confident wrongs' instead of failing it."""
    assert semantics_vote.vote_target({"dev": {"confident_wrong": 0.006}}) == 0.006
    assert semantics_vote.vote_target({"dev": {"confident_wrong": 0.05}}) == train_semantics.TARGET_WRONG
    rng = np.random.default_rng(1)
    rows = [{"intent": INTENTS[i % 16], "intensity": "moderate", "style": "situation"} for i in range(200)]
    intent, _ = semantics_data.labels(rows)
    logits = rng.normal(0, 1, (len(rows), sh.NUM_CLASSES))
    logits[np.arange(len(rows)), intent] += rng.uniform(0, 4, len(rows))
    pm = np.exp(logits) / np.exp(logits).sum(1, keepdims=True)
    pz = np.full((len(rows), 4), 0.25)
    loose = semantics_vote.evaluate(pm, pz, rows, pm, pz, rows, False)
    tight = semantics_vote.evaluate(pm, pz, rows, pm, pz, rows, False, target=0.005)
    assert tight["dev"]["confident_wrong"] <= 0.005 < loose["dev"]["confident_wrong"]
    assert tight["threshold"] > loose["threshold"]
