"""Train the learned no-motion detector and write ``jgrounding/assets/nomotion_detector.npz``.

    python -m tools.train_nomotion            # train, choose the threshold by cross-validation, write the file
    python -m tools.train_nomotion --check    # train again and compare with the shipped file, byte for byte

The hand-written rule of :mod:`jgrounding.semantics.nomotion` holds what its phrases match and misses other
wording; the detector learns the same decision from examples. Data (nothing else is read):

- **no motion** (label 1): the texts with intent ``none`` of ``assets/semantics/train/v3/train.jsonl`` (two blind
  writers' nine kinds) and ``assets/semantics/train/w3/train.jsonl`` (a third blind writer's, the same kinds);
  never their ``bench.jsonl``, which only ``python -m experiments.bench_semantics`` reads;
- **no motion, detector only** (label 1): the texts with intent ``none`` of
  ``assets/semantics/train/nomotion_detector/*/train.jsonl`` (more blind writers, the same nine kinds),
  which the head is not trained on (:data:`DETECTOR_ONLY`); their contrast texts are motion texts as below;
- **motion** (label 0): those files' contrast texts ("don't X; just Y": they choose a motion), the situation-only
  and mixed texts of ``assets/semantics/train/s3/train.jsonl`` (a fourth blind writer's; each style its own source)
  and every motion text of ``assets/semantics/train/corpora/*.jsonl``, the head's own training corpora (their ``none``
  rows are not used).

Features: the shipped head's sentence vector (the tuned encoder's whole-text pooling, computed by the same
program ``jg.ground`` runs, :func:`jgrounding.semantics.embedded.predict_tuned_many`). Model: standardized inputs,
one hidden layer of :data:`HIDDEN` GELU units, one logit; full-batch AdamW on the weighted cross-entropy (no-motion
texts half the weight, the contrast texts and the head's motion texts a quarter each), from a fixed key. Texts
that choose a motion (:func:`jgrounding.semantics.nomotion.chosen_motion`) are never held by it, so they are left
out of training and count as not held below.

Threshold: out-of-fold probabilities of :data:`FOLDS`-fold cross-validation (folds stratified by source); the
lowest threshold on a grid of :data:`STEP` at which the held-out folds hold at most :data:`MAX_FALSE_HOLD` of the
motion texts of *every* source (the contrast texts and each corpus file apart, so that the templated corpus
cannot hide false holds on the situations; :data:`MAX_FALSE_HOLD_SITUATION` of the blind situation-only texts,
:func:`max_false_hold`). The detector shipped is then trained on all the rows. Deterministic:
the same data, head and code give the same file (``--check``); the file records the data's digest and the head's.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from jgrounding.semantics import nomotion, structure
from tools import semantic_sets
from tools.semantics_corpus import normalized
from tools.semantics_data import BLIND_TRAIN, TRAIN_DIR, UNSHIPPED_TRAIN  # the corpora, the blind writers' splits

# The blind writers' files the detector reads, in order: the head's (BLIND_TRAIN) and two writers' situations that the
# shipped head is not trained on (UNSHIPPED_TRAIN: motion texts here).
DETECTOR_BLIND = BLIND_TRAIN + UNSHIPPED_TRAIN

ROOT = Path(__file__).resolve().parent.parent
HIDDEN = 64
WEIGHT_DECAY = 0.1
LEARNING_RATE = 3e-3
STEPS = 600
SEED = 0
FOLDS = 5
MAX_FALSE_HOLD = 0.01  # at most this share of each source's motion texts held on the held-out folds
# Situation-only texts (no motion word: a scene the writer judged to call for one) may be held up to this share:
# writers disagree on whether a scene asks anything of the robot ("people still tapping at their laptops" is
# resting to one, activity that asks nothing to another), and a held situation is the safe failure (the trunk holds
# still), while a text that names or chooses a motion held by mistake is a plain refusal to obey.
MAX_FALSE_HOLD_SITUATION = 0.05
SITUATION_SOURCES = ("blind situation",)  # the sources that bound applies to (s3's situation-only training texts)
STEP = 0.0025  # the threshold grid
# Source names of the blind writers' texts: one source per kind, every writer's together (the false-hold bound is
# per source, and one writer's 192 contrast texts would make it "at most one text").
CONTRAST = "blind contrast"
NO_MOTION = "blind no motion"
EXTRA_NO_MOTION = "detector-only no motion"  # the no-motion texts of DETECTOR_ONLY (a source of their own)
# Blind writers' no-motion and contrast texts that only the detector learns from (the head is not trained on them, so
# tools.train_semantics still rebuilds the shipped head): one folder per writer, its raw files converted by
# assets/semantics/train/nomotion_detector/convert.py.
DETECTOR_ONLY = semantic_sets.files("train/nomotion_detector")


def max_false_hold(source: str) -> float:
    """The bound on one source's held-out false holds (:data:`MAX_FALSE_HOLD`, or
    :data:`MAX_FALSE_HOLD_SITUATION` for situation-only texts)."""
    return MAX_FALSE_HOLD_SITUATION if source in SITUATION_SOURCES else MAX_FALSE_HOLD


def blind_source(row: dict) -> str:
    """The source of a blind writer's training row: :data:`NO_MOTION`, :data:`CONTRAST`, or ``"blind <style>"``
    for the other motion styles (s3's situation-only and mixed texts)."""
    if row["intent"] == "none":
        return NO_MOTION
    return CONTRAST if row["style"] == "contrast" else f"blind {row['style']}"


def read_jsonl(path) -> list[dict]:
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def training_rows(blind=None, train_dir=TRAIN_DIR, detector_only=None) -> list[dict]:
    """The rows the detector learns from: ``{"text", "label", "source"}``, label 1 for no motion (see the
    module docstring), in file order. ``blind``: the blind writers' ``train.jsonl`` files (default :data:`DETECTOR_BLIND`);
    ``detector_only``: the files only the detector reads (default :data:`DETECTOR_ONLY`)."""
    blind = DETECTOR_BLIND if blind is None else blind
    detector_only = DETECTOR_ONLY if detector_only is None else detector_only
    rows = [
        {
            "text": r["text"],
            "label": int(r["intent"] == "none"),
            "source": blind_source(r),
        }
        for path in blind
        for r in read_jsonl(path)
    ]
    seen = {normalized(r["text"]) for r in rows}  # a detector-only text the head's files hold already is not repeated
    rows += [
        {
            "text": r["text"],
            "label": int(r["intent"] == "none"),
            "source": EXTRA_NO_MOTION if r["intent"] == "none" else blind_source(r),
        }
        for path in detector_only
        for r in read_jsonl(path)
        if normalized(r["text"]) not in seen
    ]
    for path in sorted(Path(train_dir).glob("*.jsonl")):
        rows += [
            {"text": r["text"], "label": 0, "source": path.name} for r in read_jsonl(path) if r["intent"] != "none"
        ]
    if not any(r["label"] for r in rows) or all(r["label"] for r in rows):
        raise ValueError(f"training data needs no-motion and motion texts: {list(blind)}, {train_dir}")
    return rows


def data_digest(rows) -> str:
    """Digest of the training rows (texts, labels, sources, in order), recorded in the detector's file."""
    h = hashlib.sha256()
    for r in rows:
        h.update(json.dumps([r["text"], r["label"], r["source"]], ensure_ascii=False).encode() + b"\n")
    return h.hexdigest()[:16]


def weights(label: np.ndarray, source: np.ndarray) -> np.ndarray:
    """Row weights ``(N,)``, mean 1: no-motion texts half of the total, contrast texts and the corpora's motion
    texts a quarter each, uniform inside each part."""
    w = np.zeros(len(label))
    parts = [
        (label == 1, 0.5),
        ((label == 0) & (source == CONTRAST), 0.25),
        ((label == 0) & ~(source == CONTRAST), 0.25),
    ]
    for mask, share in parts:
        if mask.any():
            w[mask] = share / mask.sum()
    return (w * len(label) / w.sum()).astype(np.float32)


def fit(x: np.ndarray, label: np.ndarray, weight: np.ndarray, seed: int = SEED) -> dict:
    """Train one detector on ``x`` ``(N, 384)``: standardization, then the MLP by full-batch AdamW (:data:`STEPS`
    steps in one ``lax.scan``). Returns :class:`jgrounding.semantics.nomotion.Detector`'s arrays (numpy)."""
    import jax
    import jax.numpy as jnp
    import optax

    mean = x.mean(0).astype(np.float32)
    scale = (x.std(0) + 1e-6).astype(np.float32)
    z = jnp.asarray((x - mean) / scale, jnp.float32)
    y, w = jnp.asarray(label, jnp.float32), jnp.asarray(weight / weight.sum(), jnp.float32)
    k1, k2 = jax.random.split(jax.random.PRNGKey(seed))
    glorot = jax.nn.initializers.glorot_normal()
    params = {
        "w1": glorot(k1, (x.shape[1], HIDDEN)),
        "b1": jnp.zeros(HIDDEN),
        "w2": glorot(k2, (HIDDEN, 1)),
        "b2": jnp.zeros(1),
    }
    opt = optax.adamw(LEARNING_RATE, weight_decay=WEIGHT_DECAY)

    def loss(p):
        logit = (jax.nn.gelu(z @ p["w1"] + p["b1"]) @ p["w2"] + p["b2"])[:, 0]
        return jnp.sum(w * optax.sigmoid_binary_cross_entropy(logit, y))

    @jax.jit
    def train(p):
        def step(carry, _):
            p, s = carry
            grads = jax.grad(loss)(p)
            updates, s = opt.update(grads, s, p)
            return (optax.apply_updates(p, updates), s), None

        return jax.lax.scan(step, (p, opt.init(p)), None, length=STEPS)[0][0]

    trained = {k: np.asarray(v, np.float32) for k, v in train(params).items()}
    return {"mean": mean, "scale": scale, **trained}


def probability(arrays: dict, x: np.ndarray) -> np.ndarray:
    """p(no motion) of ``x`` as the shipped decision computes it (:meth:`nomotion.Detector.probability`)."""
    return nomotion.Detector(arrays, 1.0, {}).probability(x)


def folds(source: np.ndarray, k: int = FOLDS, seed: int = SEED) -> np.ndarray:
    """A fold index ``(N,)`` per row, stratified by source (each source's rows shuffled, then dealt round)."""
    rng = np.random.default_rng(seed)
    out = np.zeros(len(source), int)
    for s in sorted(set(source.tolist())):
        idx = np.flatnonzero(source == s)
        rng.shuffle(idx)
        out[idx] = np.arange(len(idx)) % k
    return out


def out_of_fold(x, label, source, gate) -> np.ndarray:
    """Each row's probability from the detector trained without its fold; 0 for rows the gate keeps from it
    (they choose a motion)."""
    fold, p = folds(source), np.zeros(len(label))
    for f in range(FOLDS):
        train, test = (fold != f) & ~gate, (fold == f) & ~gate
        arrays = fit(x[train], label[train], weights(label[train], source[train]))
        p[test] = probability(arrays, x[test])
    return p


def false_holds(held: np.ndarray, label: np.ndarray, source: np.ndarray) -> dict:
    """The share of motion texts held, per source."""
    return {s: float(held[(source == s) & (label == 0)].mean()) for s in sorted(set(source[label == 0].tolist()))}


def within_bounds(false_hold: dict) -> bool:
    """Whether every source's share of motion texts held is within its bound (:func:`max_false_hold`)."""
    return all(v <= max_false_hold(s) + 1e-12 for s, v in false_hold.items())


def choose_threshold(p, label, source) -> float:
    """The lowest threshold on the grid at which no source's motion texts are held more than its bound
    (:func:`max_false_hold`)."""
    for t in np.round(np.arange(STEP, 1.0, STEP), 4):
        if within_bounds(false_holds(p >= t, label, source)):
            return float(t)
    raise ValueError(
        f"no threshold holds at most {MAX_FALSE_HOLD} of every source's motion texts "
        f"({MAX_FALSE_HOLD_SITUATION} of {', '.join(SITUATION_SOURCES)})"
    )


def train_detector(rows) -> tuple[dict, float, dict]:
    """Cross-validate, choose the threshold, train on every row: (arrays, threshold, meta)."""
    from jgrounding.semantics import head as semantic_head

    head = semantic_head.load()
    if not head.config.features.one_program:
        raise ValueError("the detector reads the tuned head's sentence vectors; the shipped head is not a tuned one")
    texts = [r["text"] for r in rows]
    label = np.array([r["label"] for r in rows], np.int32)
    source = np.array([r["source"] for r in rows])
    print(
        f"{len(rows)} texts: {label.sum()} no motion, {(source == CONTRAST).sum()} contrast, "
        f"{((label == 0) & ~(source == CONTRAST)).sum()} other motion texts (corpora, blind situations and mixed); encoding",
        flush=True,
    )
    x = nomotion.sentence_vectors(texts)
    gate = np.array([nomotion.chosen_motion(t) is not None for t in texts])
    p = out_of_fold(x, label, source, gate)
    threshold = choose_threshold(p, label, source)
    held = p >= threshold
    rule = np.array([nomotion.rule(t, st) is not None for t, st in zip(texts, map(structure.spans, texts))])
    either = (held | rule) & ~gate
    arrays = fit(x[~gate], label[~gate], weights(label[~gate], source[~gate]))
    meta = {
        "head_digest": head.meta["params_digest"],
        "data_digest": data_digest(rows),
        "features": "the shipped head's sentence vector (384)",
        "model": {
            "hidden": HIDDEN,
            "weight_decay": WEIGHT_DECAY,
            "learning_rate": LEARNING_RATE,
            "steps": STEPS,
            "seed": SEED,
        },
        "texts": {
            "no_motion": int(label.sum()),
            "contrast": int((source == CONTRAST).sum()),
            "corpus_motion": int(((label == 0) & ~(source == CONTRAST)).sum()),
            "trained_on": int((~gate).sum()),
            "chosen_motion": int(gate.sum()),
        },
        "cv": {
            "folds": FOLDS,
            "max_false_hold": MAX_FALSE_HOLD,
            "max_false_hold_situation": {s: MAX_FALSE_HOLD_SITUATION for s in SITUATION_SOURCES},
            "no_motion_held": round(float(held[label == 1].mean()), 4),
            "no_motion_held_with_rule": round(float(either[label == 1].mean()), 4),
            "no_motion_held_with_rule_by_source": {
                s: round(float(either[(label == 1) & (source == s)].mean()), 4)
                for s in sorted(set(source[label == 1].tolist()))
            },
            "false_hold": {s: round(v, 4) for s, v in false_holds(held, label, source).items()},
            "false_hold_with_rule": {s: round(v, 4) for s, v in false_holds(either, label, source).items()},
        },
    }
    return arrays, threshold, meta


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(nomotion.DETECTOR_ASSET), help="where to write the detector")
    ap.add_argument("--check", action="store_true", help="train and compare with --out byte for byte; write nothing")
    args = ap.parse_args(argv)
    arrays, threshold, meta = train_detector(training_rows())
    cv = meta["cv"]
    print(
        f"threshold {threshold:.4f}: held-out no-motion texts held {cv['no_motion_held']:.3f} "
        f"({cv['no_motion_held_with_rule']:.3f} with the rule; by source "
        + ", ".join(f"{s} {v:.3f}" for s, v in cv["no_motion_held_with_rule_by_source"].items())
        + "); motion texts held per source "
        + ", ".join(f"{s} {v:.4f}" for s, v in cv["false_hold"].items())
    )
    out = Path(args.out)
    if args.check:
        tmp = out.with_name(f".{out.name}.check")
        try:
            nomotion.save_detector(tmp, arrays, threshold, meta)
            same = out.exists() and tmp.read_bytes() == out.read_bytes()
        finally:
            tmp.unlink(missing_ok=True)
        print(f"{out}: {'identical' if same else 'DIFFERS from the retrained detector'}")
        return 0 if same else 1
    print(f"wrote {nomotion.save_detector(out, arrays, threshold, meta)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
