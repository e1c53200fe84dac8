"""Train, compare, select and calibrate the semantic head; write ``assets/semantic_head.npz``.

    python -m tools.semantics_corpus      # regenerate assets/semantics_train/generated.jsonl
    python -m tools.train_semantics       # train on assets/semantics_train/*.jsonl, select/calibrate on dev

Training data: every ``assets/semantics_train/*.jsonl`` (the independently written corpora and our generated
one; all disjoint from the evaluation sets). Rows with intent ``"none"`` teach the no-behaviour class; their
``style`` (addressee, quoted, system, ...) teaches the reason head that says why a text calls for no motion.

Options (:data:`OPTIONS`) are compared on the dev splits: ``assets/semantics_eval_v2/dev.jsonl`` (the styles
real reasoners write, with no-behaviour texts) and ``assets/semantics_eval/dev.jsonl`` (plainly worded). Each
option's softmax temperature is fitted on v2 dev (NLL over the 17 classes), then its confidence threshold:
the lowest at which the confident wrong motions on v2 dev (acted on with the wrong intent, or acted on a
no-behaviour text) stay within ``TARGET_WRONG``. The option with the best dev score (:func:`dev_score`) is
shipped. The test splits are never read here. Deterministic: fixed keys, full-batch training. Encoder features
are cached in ``.cache/semantics/`` (keyed by the texts and the feature code), so re-runs skip the encoder.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import io
import json
from pathlib import Path

import jax
import numpy as np

from jgrounding.semantics import embedded
from jgrounding.semantics import head as sh
from jgrounding.vocabulary import INTENSITIES, INTENTS

ROOT = Path(__file__).resolve().parent.parent
TRAIN_DIR = ROOT / "assets" / "semantics_train"
DEV = ROOT / "assets" / "semantics_eval_v2" / "dev.jsonl"
DEV_PLAIN = ROOT / "assets" / "semantics_eval" / "dev.jsonl"
CACHE = ROOT / ".cache" / "semantics"
TARGET_WRONG = 0.02  # confident wrong motions allowed on dev (the goal on test is 3%; a margin for the shift)
# The options compared on dev. "eq3": the first trained head's inputs (sentence embedding + Eq. (3) cue
# features), retrained on the same data; "structure": the structure-aware inputs (the sentence, its chosen,
# rejected and quoted parts pooled apart from one encoder pass, Eq. (3) cues of the chosen part, structure flags).
# Rows weigh by their file: the generated corpus less (templated), the structure corpus (the styles real
# reasoners write, and the no-behaviour kinds) more; each intent and "none" then weighs the same in total.
FILE_WEIGHTS = {"generated.jsonl": 0.3, "structure.jsonl": 2.0}
OPTIONS = {
    "eq3": dict(inputs="eq3", hidden=128, steps=400),
    "structure": dict(inputs="structure", hidden=128, steps=400),
    "structure-wide": dict(inputs="structure", hidden=256, steps=800, dropout=0.3),
    "structure-x5": dict(inputs="structure", hidden=128, steps=400, seeds=(0, 1, 2, 3, 4)),
}
# How a no-behaviour style reads to a person (the reason head's classes; unknown styles read as their name).
REASON_TEXT = {
    "addressed_other": "words addressed to someone else",
    "quoted": "quoted words, not a request to the trunk",
    "background": "background talk (TV, radio or other people)",
    "system": "a system or log line",
    "instruction_other": "an instruction for another person",
    "not_understood": "the reasoner did not understand",
    "chitchat": "chit-chat: no behaviour requested",
    "question": "a question that moving cannot answer",
    "none": "no behaviour requested",
}


def read_jsonl(path) -> list[dict]:
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def labels(rows) -> tuple[np.ndarray, np.ndarray]:
    intent = np.array([sh.NONE if r["intent"] == "none" else INTENTS.index(r["intent"]) for r in rows], np.int32)
    intensity = np.array(
        [
            -1 if r["intent"] == "none" or r.get("intensity") is None else INTENSITIES.index(r["intensity"])
            for r in rows
        ],
        np.int32,
    )
    return intent, intensity


def reason_classes(rows) -> list[str]:
    """The no-behaviour reasons the training rows name (their ``style``), "none" first for unnamed ones."""
    return ["none"] + sorted(
        {r["style"] for r in rows if r["intent"] == "none" and r.get("style") not in (None, "none")}
    )


def reason_labels(rows, classes) -> np.ndarray:
    return np.array([classes.index(r.get("style") or "none") if r["intent"] == "none" else -1 for r in rows], np.int32)


def load_train(train_dir=TRAIN_DIR) -> tuple[list[dict], np.ndarray]:
    """All training rows and each one's weight before class balancing ``(N,)`` (:data:`FILE_WEIGHTS`)."""
    rows, weight = [], []
    for path in sorted(Path(train_dir).glob("*.jsonl")):
        part = read_jsonl(path)
        rows += part
        weight += [FILE_WEIGHTS.get(path.name, 1.0)] * len(part)
    return rows, np.array(weight, np.float32)


def _code_digest() -> str:
    h = hashlib.sha256()
    for name in ("structure.py", "encoder.py"):
        h.update((ROOT / "jgrounding" / "semantics" / name).read_bytes())
    return h.hexdigest()[:16]


def cached_structure_features(texts: list[str], cache_dir=CACHE) -> np.ndarray:
    """:func:`embedded.structure_features` of ``texts``; the encoder's part goes through a cache keyed by the
    encoder and span code and the text (cue features and flags are recomputed: they are cheap)."""
    from jgrounding.io import write_atomic
    from jgrounding.semantics import structure

    path = Path(cache_dir) / f"pooled-{_code_digest()}.npz"
    known: dict[str, np.ndarray] = {}
    if path.exists():
        with np.load(path) as f:
            known = dict(zip(f["keys"].tolist(), f["x"]))
    key = [hashlib.sha256(t.encode()).hexdigest() for t in texts]
    structs = [structure.analyse(t) for t in texts]
    missing = {k: i for i, k in enumerate(key) if k not in known}
    if missing:
        print(f"  encoding {len(missing)} texts (cache: {len(known)})", flush=True)
        idx = list(missing.values())
        x = embedded.pooled_embeddings([texts[i] for i in idx], [structs[i] for i in idx])
        known.update(zip(missing, x))
        buf = io.BytesIO()
        keys = sorted(known)
        np.savez(buf, keys=np.array(keys), x=np.stack([known[k] for k in keys]))
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, buf.getvalue())
    return embedded.structure_features_from(texts, structs, np.stack([known[k] for k in key]))


def inputs(kind: str, xs: np.ndarray, texts: list[str]) -> np.ndarray:
    """The head's input features of one option from the structure features (no second encoder pass)."""
    if kind == "structure":
        return xs
    emb = xs[:, : sh.EMBED_DIM]
    return np.concatenate([emb, np.stack([embedded.cue_features(r, t) for r, t in zip(emb, texts)])], 1)


def selective(p_m: np.ndarray, p_z: np.ndarray, rows, threshold: float) -> dict:
    """Selective-grounding metrics of one split at one threshold (acted on: not "none" and confidence >= it)."""
    m, z, conf = sh.decide(p_m, p_z)
    intent, intensity = labels(rows)
    motion = intent != sh.NONE
    act = (np.argmax(p_m, 1) != sh.NONE) & (conf >= threshold)
    ok = m == intent
    n = len(rows)
    return {
        "intent_motion": float(ok[motion].mean()) if motion.any() else float("nan"),
        "intensity_exact": float(np.mean(z[motion] == intensity[motion])) if motion.any() else float("nan"),
        "intensity_within_one": float(np.mean(np.abs(z[motion] - intensity[motion]) <= 1))
        if motion.any()
        else float("nan"),
        "coverage_motion": float(act[motion].mean()) if motion.any() else float("nan"),
        "acted_accuracy": float(ok[act & motion].mean()) if (act & motion).any() else float("nan"),
        "confident_wrong": float(np.sum(act & ~ok) / n),
        "none_held": float(np.mean(~act[~motion])) if (~motion).any() else float("nan"),
        "ece": sh.expected_calibration_error(conf, ok),
    }


def calibrate_threshold(p_m, p_z, rows, target=TARGET_WRONG) -> float:
    """The lowest threshold (0.025 steps) whose confident wrong motions on ``rows`` stay within ``target``."""
    for t in np.round(np.arange(0.1, 0.976, 0.025), 3):
        if selective(p_m, p_z, rows, t)["confident_wrong"] <= target:
            return float(t)
    return 0.975


def dev_score(r: dict, plain: dict) -> float:
    """Mean of the v2-dev intent accuracy on motion texts, intensity exact, share of motion acted on, share of
    no-behaviour texts held, and the plainly worded dev intent accuracy (so it cannot fall unseen)."""
    terms = [r["intent_motion"], r["intensity_exact"], r["coverage_motion"], r["none_held"], plain["intent_motion"]]
    return float(np.mean([t for t in terms if t == t]))


def fit(x, rows, row_weight, inputs, hidden, steps=400, z_hidden=0, dropout=0.1, seeds=(0,), reasons=None):
    """Train one head on features ``x`` of ``rows`` weighted ``row_weight`` (an ensemble of one head per seed
    when ``seeds`` holds several: :func:`head.stack`); returns (params, config)."""
    seed = seeds[0]
    why = reason_labels(rows, reasons) if reasons else None
    cfg = sh.HeadConfig(
        hidden=hidden,
        z_hidden=z_hidden,
        use_eq3=True,
        steps=steps,
        dropout=dropout,
        seed=seed,
        inputs="structure" if inputs == "structure" else "",
        num_reasons=len(reasons) if reasons else 0,
    )
    intent, intensity = labels(rows)
    # Each intent (and "none") weighs the same in total; within it rows weigh as their file does, and within
    # "none" each kind of no-behaviour text (its reason: junk and interface commands, addressee, log line...)
    # weighs the same, so the many written kinds do not drown the few generated ones.
    w = np.asarray(row_weight, np.float64).copy()
    kind = reason_labels(rows, reasons or reason_classes(rows))
    for k in np.unique(kind[intent == sh.NONE]):
        sel = (intent == sh.NONE) & (kind == k)
        w[sel] /= w[sel].sum()
    for c in np.unique(intent):
        w[intent == c] /= w[intent == c].sum()
    w = w / w.mean()
    members = [
        jax.tree.map(np.asarray, sh.train(jax.random.key(s), x, intent, intensity, w.astype(np.float32), cfg, why)[0])
        for s in seeds
    ]
    return (members[0] if len(members) == 1 else sh.stack(members)), cfg


def _probs(params, x, temperature=1.0):
    return tuple(np.asarray(a) for a in sh.predict(params, x, temperature))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--dev", default=str(DEV))
    p.add_argument("--dev-plain", default=str(DEV_PLAIN))
    p.add_argument("--out", default=str(sh.ASSET))
    p.add_argument("--options", default=",".join(OPTIONS), help=f"options to compare ({', '.join(OPTIONS)})")
    p.add_argument("--report", default=str(ROOT / "results" / "semantics_dev_options.json"))
    args = p.parse_args(argv)
    chosen = args.options.split(",")
    bad = [o for o in chosen if o not in OPTIONS]
    if bad:
        raise SystemExit(f"unknown option(s) {bad}; valid options: {', '.join(OPTIONS)}")
    rows, row_weight = load_train()
    dev = read_jsonl(args.dev) if Path(args.dev).exists() else []
    plain = read_jsonl(args.dev_plain)
    if not dev:
        print(f"{args.dev} missing: selecting and calibrating on {args.dev_plain} alone")
        dev = plain
    reasons = reason_classes(rows)
    print(f"train: {len(rows)} rows; dev: {len(dev)} + plain {len(plain)} rows; file weights {FILE_WEIGHTS}")
    print(f"no-behaviour reasons: {reasons}")
    texts = [r["text"] for r in rows]
    xs = cached_structure_features(texts)
    xs_dev = cached_structure_features([r["text"] for r in dev])
    xs_plain = cached_structure_features([r["text"] for r in plain])
    dev_intent, _ = labels(dev)
    results = {}
    for name in chosen:
        opt = OPTIONS[name]
        x = inputs(opt["inputs"], xs, texts)
        xd = inputs(opt["inputs"], xs_dev, [r["text"] for r in dev])
        xp = inputs(opt["inputs"], xs_plain, [r["text"] for r in plain])
        params, cfg = fit(x, rows, row_weight, reasons=reasons, **opt)
        temperature = sh.fit_temperature(lambda t: _probs(params, xd, t)[0], dev_intent)
        pm, pz = _probs(params, xd, temperature)
        threshold = calibrate_threshold(pm, pz, dev)
        r = selective(pm, pz, dev, threshold)
        rp = selective(*_probs(params, xp, temperature), plain, threshold)
        score = dev_score(r, rp)
        results[name] = dict(
            option=opt,
            temperature=temperature,
            threshold=threshold,
            dev=r,
            dev_plain=rp,
            score=score,
            _params=params,
            _cfg=cfg,
        )
        print(
            f"  {name:15s} score {score:.3f} | v2 dev: intent {r['intent_motion']:.3f} exact {r['intensity_exact']:.3f}"
            f" within1 {r['intensity_within_one']:.3f} acted {r['coverage_motion']:.3f} wrong {r['confident_wrong']:.3f}"
            f" held {r['none_held']:.3f} ECE {r['ece']:.3f} (T {temperature:.2f}, thr {threshold:.3f})"
            f" | plain dev intent {rp['intent_motion']:.3f}",
            flush=True,
        )
    best = max(results, key=lambda k: results[k]["score"])  # first of equals: the options' order breaks ties
    b = results[best]
    digests = {
        path.name: hashlib.sha256(path.read_bytes()).hexdigest()[:16] for path in sorted(TRAIN_DIR.glob("*.jsonl"))
    }
    comparison = {k: {kk: vv for kk, vv in v.items() if not kk.startswith("_")} for k, v in results.items()}
    meta = {
        "temperature": b["temperature"],
        "threshold": b["threshold"],
        "selected": best,
        "option": b["option"],
        "reasons": reasons,
        "reason_text": {k: REASON_TEXT.get(k, k.replace("-", " ")) for k in reasons},
        "train_files": digests,
        "file_weights": FILE_WEIGHTS,
        "dev_file": hashlib.sha256(Path(args.dev).read_bytes()).hexdigest()[:16] if Path(args.dev).exists() else "",
        "dev": b["dev"],
        "dev_plain": b["dev_plain"],
        "dev_ece": b["dev"]["ece"],
        "dev_ece_uncalibrated": selective(
            *_probs(b["_params"], inputs(b["option"]["inputs"], xs_dev, [r["text"] for r in dev])), dev, b["threshold"]
        )["ece"],
        "target_wrong": TARGET_WRONG,
        "config": dataclasses.asdict(b["_cfg"]),
        "params_digest": sh.digest(b["_params"]),
        "comparison": comparison,
    }
    sh.save(args.out, b["_params"], b["_cfg"], meta)
    if args.report:
        from jgrounding.io import write_atomic

        write_atomic(args.report, json.dumps(comparison, indent=1, sort_keys=True) + "\n")
    print(f"selected {best}; temperature {b['temperature']:.2f}; threshold {b['threshold']:.3f}")
    print(f"wrote {args.out} (params {meta['params_digest']})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
