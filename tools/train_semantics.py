"""Train, compare, select and calibrate the semantic head; write ``jgrounding/assets/semantic_head.npz``.

    python -m tools.semantics_corpus      # regenerate assets/semantics/train/corpora/generated.jsonl
    python -m tools.train_semantics       # train on assets/semantics/train/corpora/*.jsonl, select/calibrate on dev

Training data: every ``assets/semantics/train/corpora/*.jsonl`` (the independently written corpora and our generated
one; all disjoint from the evaluation sets, tests/semantics/test_training_data.py) and the blind writers'
training texts of #34 (:data:`BLIND_TRAIN`: contrast texts and texts that call for no motion, in nine kinds,
situation-only and mixed texts; their frozen ``bench.jsonl`` is read only by ``python -m experiments.bench
semantics``; ``--no-blind`` leaves them out). Rows with intent ``"none"`` teach the
no-behaviour class; their
``style`` (addressee, quoted, system, ...) teaches the reason head that says why a text calls for no motion.

Options (:data:`OPTIONS`) are compared on the dev splits: ``assets/semantics/dev/v2/dev.jsonl`` (the styles
real reasoners write, with no-behaviour texts), ``assets/semantics/dev/plain/dev.jsonl`` (plainly worded) and the blind
situation hold-outs (:data:`SITUATION_DEVS`: two writers; v2 dev holds 29 situations). Each
option's softmax temperature is fitted on v2 dev and the situation hold-outs together (NLL over the 17 classes), so
are its intensity cut points (NLL of the motion texts' intensities, :func:`fit_cut_points`), then its confidence
threshold:
the lowest at which the confident wrong motions on v2 dev (acted on with the wrong intent, or acted on a
no-behaviour text) stay within ``TARGET_WRONG`` and those on the situation hold-outs (pooled) within ``SITUATION_TARGET_WRONG``. The option with the best dev score (:func:`dev_score`) is
shipped (:func:`ship_choice`: of the options within :data:`SHIP_MARGIN` of the best, the fewest encoder layers). The
test splits are never read here. Deterministic: fixed keys and seeded minibatch order. Frozen encoder features are
cached in ``.cache/semantics/`` (keyed by the texts and the encoder and span code), so re-runs skip the encoder; the
"tuned" option (top encoder layers trained with the head) takes about 10 minutes on 2 cores, the "student" (its
encoder distilled into three layers, then trained with a new head) about 20 more, each further student sharing
that distillation about 5; all are cached (:func:`cached_finetune`, :func:`cached_distill`), so
the default ``--options tuned,student-sit,student-sit-z`` (what ships now) takes about 50 minutes the first time.
A new head makes the nearest-neighbour table (``jgrounding/assets/semantic_knn.npz``) stale: it is ignored until
``python -m tools.semantics_knn --write`` rebuilds it for the new head; so is the learned no-motion detector
(``jgrounding/assets/nomotion_detector.npz``, which reads the head's sentence vectors) until
``python -m tools.train_nomotion`` retrains it.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import inspect
import io
import json
from pathlib import Path

import jax
import numpy as np

from jgrounding.semantics import calibration, cue_reducer, encoder, features
from jgrounding.semantics import head as sh
from jgrounding.vocabulary import INTENSITIES, INTENTS
from tools import semantic_sets

ROOT = Path(__file__).resolve().parent.parent
# The sets are named in assets/semantics/sets.toml (tools.semantic_sets): the training corpora's folder, the dev splits.
CORPORA = "train/corpora"
TRAIN_DIR = semantic_sets.get(CORPORA).folder
DEV = semantic_sets.path("dev/v2")
DEV_PLAIN = semantic_sets.path("dev/plain")
# Situation-only texts for selection (#34: situation-only intent is a goal, and v2 dev holds 29 situations): the
# "blind" hold-out, 256 texts written from docs/semantics_blind_brief.md by a writer who saw no code, corpus or
# evaluation set; never trained on. Its intent accuracy at each option's dev threshold is one term of the ship score
# (dev_score). tools.semantics_knn reports it as its "blind" hold-out.
SITUATION_DEV = semantic_sets.path("dev/situations_blind")
# A second writer's hold-out (eighth session), never trained on either: the calibration (temperature, cut points,
# threshold) of a head read on one writer's situations, selected on many times, was optimistic on the blind benches
# (ECE up to 0.079 and confident wrongs up to 2 % against the hold-out's 1 %). Both together are SITUATION_DEVS.
SITUATION_DEV2 = semantic_sets.path("dev/situations_blind2")
SITUATION_DEVS = (SITUATION_DEV, SITUATION_DEV2)
# Texts a student's distillation reads beside the training texts (labels unused: distillation matches the teacher's
# token states): the vote's 1,024 situations and the 1,024 of the unshipped second situations corpus, so that the
# student learns the teacher's reading of situations on more of them than the training corpora hold.
DISTILL_EXTRA = tuple(path for s in semantic_sets.select(reader="distillation") for path in s.files)
CACHE = ROOT / ".cache" / "semantics"
TARGET_WRONG = 0.02  # confident wrong motions allowed on dev (the goal on test is 3%; a margin for the shift)
# ... and on the blind situation hold-outs (SITUATION_DEVS, pooled). #34's goal on the frozen blind benches is 1 %, and the
# situation benches came out at 1.6-2.0 % with the hold-out at 2 % (seventh session, decided before its retrain):
# holding still is the safe failure, and with an MLLM configured an unsure text is asked of it instead.
SITUATION_TARGET_WRONG = 0.01
# The options compared on dev. "eq3": the first trained head's inputs (sentence embedding + Eq. (3) cue
# features), retrained on the same data; "structure": the structure-aware inputs (the sentence, its chosen,
# rejected and quoted parts pooled apart from one encoder pass, Eq. (3) cues of the chosen part, structure flags).
# Rows weigh by their file: the generated corpus less (templated), the structure corpus (the styles real
# reasoners write, and the no-behaviour kinds) more; each intent and "none" then weighs the same in total.
# (situations_blind.jsonl: the vote-only rows of assets/semantics/train/vote/, for a head retrained with them through
# --train-dir, as docs/how_it_works.md reports; the shipped head is not trained on them.)
FILE_WEIGHTS = {"generated.jsonl": 0.3, "structure.jsonl": 2.0, "situations.jsonl": 2.0, "situations_blind.jsonl": 2.0}
# The blind writers' training splits (#34): the contrast and no-motion texts of v3 (two writers), w3 and w4, s3's
# situation-only and mixed texts, and the situation-only texts of eleven more writers (s5-s9, s12, s13, s15-s18,
# written for training only: assets/semantics/train/situations_blind/), each file weighing as the structure corpus. The
# benches (bench.jsonl) stay frozen. tools.train_nomotion reads the same files.
BLIND_TRAIN = tuple(path for s in semantic_sets.select(reader="training") if s.name != CORPORA for path in s.files)
# Two more writers' situations (eighth session, 320 each, assets/semantics/train/situations_detector/): the head retrained with them
# in BLIND_TRAIN scored 0.923 on dev against the recalibrated head's 0.918, but without a vote (none passed its rule
# for it) it lost to the recalibrated head with its vote on dev as users call it (docs/how_it_works.md), so the head
# is not trained on them and this module still rebuilds the shipped head. The no-motion detector, trained beside
# that retrain, reads them as motion texts (tools.train_nomotion: BLIND_TRAIN + UNSHIPPED_TRAIN).
UNSHIPPED_TRAIN = semantic_sets.files("train/situations_detector")
BLIND_WEIGHT = 2.0
OPTIONS = {
    "eq3": dict(inputs="eq3", hidden=128, steps=400),
    "structure": dict(inputs="structure", hidden=128, steps=400),
    "structure-wide": dict(inputs="structure", hidden=256, steps=800, dropout=0.3),
    # End to end: the encoder's top 3 layers trained with the head (minibatch AdamW, 8 epochs; the lower 3 layers
    # stay frozen, so their token states are computed once). Inputs as "structure", without the Eq. (3)
    # similarities (they live in the frozen encoder's space).
    "tuned": dict(inputs="tuned", hidden=128, tuned_layers=3, epochs=8),
    # A faster encoder (#34 item 4): the "tuned" option's six layers (the teacher, trained in the same run; a re-run
    # reads both from the cache, cached_finetune) distilled into three of them (MiniLM layers 1, 3, 5: every other
    # one, ending with the tuned top layer) on the training texts' final token states (DISTILL_STEPS), then all three trained with a new
    # head as "tuned" trains its top three. Shipped when its dev score is within SHIP_MARGIN of the best.
    "student": dict(inputs="tuned", hidden=128, tuned_layers=3, epochs=8, encoder_layers=(1, 3, 5)),
    # The student distilled on the training texts and DISTILL_EXTRA's situations (situation-only intent fell with
    # the first student: blind hold-out 0.672 alone against the teacher's 0.777); "-slow": then trained with a
    # quarter of the encoder's learning rate, so that it drifts less from what it distilled.
    "student-sit": dict(
        inputs="tuned", hidden=128, tuned_layers=3, epochs=8, encoder_layers=(1, 3, 5), distill_extra=True
    ),
    # "student-sit" whose intensity scorer has a hidden layer (64 GELU units) instead of a linear score: a
    # situation's intensity is how strong the situation is for the behaviour it calls for, which a linear score of
    # the pooled vectors may read less well (situation intensity exact was 0.68-0.75 on the frozen benches against
    # 0.80; a second reader, a language model given only the vocabulary, agrees with the writer on 0.844).
    "student-sit-z": dict(
        inputs="tuned", hidden=128, tuned_layers=3, epochs=8, encoder_layers=(1, 3, 5), distill_extra=True, z_hidden=64
    ),
    "student-sit-slow": dict(
        inputs="tuned", hidden=128, tuned_layers=3, epochs=8, encoder_layers=(1, 3, 5), distill_extra=True, enc_lr=5e-6
    ),
}
# The options a default run compares: those of the run that made the shipped head (the others stay available, and
# results/semantics_dev_options.json keeps only the options of the last run).
DEFAULT_OPTIONS = ("tuned", "student-sit", "student-sit-z")
DISTILL_STEPS = 1500  # AdamW steps of DISTILL_BATCH texts (cosine schedule, warm-up 5 %); about 10 min on 2 cores
DISTILL_BATCH = 32
DISTILL_LR = 2e-4
# The ship rule: of the options whose dev score is within SHIP_MARGIN of the best, the one whose encoder runs the
# fewest layers (speed is a goal of #34); ties by score, then by the options' order.
SHIP_MARGIN = 0.01
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
    # the blind writers' kinds (#34)
    "rules_out": "the text rules the motion out",
    "freeze_order": "an order to keep still",
    "observed_activity": "activity that asks nothing of the robot",
    "media_or_readaloud": "media or words read aloud",
    "system_or_meta": "a system or log line",
    "not_now_wait": "nothing to respond to yet",
    "maintenance_handling": "the trunk is being handled or serviced",
    "past_or_hypothetical": "a past or hypothetical motion, not a request",
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


def train_files(train_dir=TRAIN_DIR, blind=BLIND_TRAIN) -> dict[str, tuple[Path, float]]:
    """The training files by name (a corpus file by its name, a blind split by its folder and name) with their
    weights (:data:`FILE_WEIGHTS`, :data:`BLIND_WEIGHT`), in reading order."""
    files = {path.name: (path, FILE_WEIGHTS.get(path.name, 1.0)) for path in sorted(Path(train_dir).glob("*.jsonl"))}
    for path in blind:
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"blind training split {path} missing (run its folder's split.py)")
        files[f"{path.parent.name}/{path.name}"] = (path, BLIND_WEIGHT)
    return files


def load_train(train_dir=TRAIN_DIR, blind=BLIND_TRAIN) -> tuple[list[dict], np.ndarray]:
    """All training rows and each one's weight before class balancing ``(N,)`` (:func:`train_files`)."""
    rows, weight = [], []
    for path, w in train_files(train_dir, blind).values():
        part = read_jsonl(path)
        rows += part
        weight += [w] * len(part)
    return rows, np.array(weight, np.float32)


def _code_digest() -> str:
    h = hashlib.sha256()
    for name in ("structure.py", "encoder.py"):
        h.update((ROOT / "jgrounding" / "semantics" / name).read_bytes())
    return h.hexdigest()[:16]


def cached_structure_features(texts: list[str], cache_dir=CACHE) -> np.ndarray:
    """:func:`jgrounding.semantics.features.structure_features` of ``texts``; the encoder's part goes through a cache keyed by the
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
        x = features.pooled_embeddings([texts[i] for i in idx], [structs[i] for i in idx])
        known.update(zip(missing, x))
        buf = io.BytesIO()
        keys = sorted(known)
        np.savez(buf, keys=np.array(keys), x=np.stack([known[k] for k in keys]))
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, buf.getvalue())
    return features.structure_features_from(texts, structs, np.stack([known[k] for k in key]))


def inputs(kind: str, xs: np.ndarray, texts: list[str]) -> np.ndarray:
    """The head's input features of one option (:data:`jgrounding.semantics.features.INPUTS`: ``eq3`` or
    ``structure``) from the structure features (no second encoder pass: the sentence pooling is the embedding)."""
    if kind == "structure":
        return xs
    emb = xs[:, : features.EMBED_DIM]
    return np.concatenate([emb, np.stack([cue_reducer.cue_features(r, t) for r, t in zip(emb, texts)])], 1)


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
        "ece": calibration.expected_calibration_error(conf, ok),
    }


def calibrate_threshold(
    p_m, p_z, rows, target=TARGET_WRONG, situations=None, situation_target=SITUATION_TARGET_WRONG
) -> float:
    """The lowest threshold (0.025 steps) whose confident wrong motions on ``rows`` stay within ``target``, and,
    with ``situations`` (``(p_m, p_z, rows)`` of the :data:`SITUATION_DEVS` hold-outs), on those within
    ``situation_target``: v2 dev holds 29 situations, too few to see the situations a head acts on wrongly."""
    for t in np.round(np.arange(0.1, 0.976, 0.025), 3):
        if selective(p_m, p_z, rows, t)["confident_wrong"] <= target and (
            situations is None or selective(*situations, t)["confident_wrong"] <= situation_target
        ):
            return float(t)
    return 0.975


CUT_STEP = 0.25  # the step of fit_cut_points' grid of shifts (recalibrate recovers a shift from rounded meta by it)


def fit_cut_points(params, x, rows, grid=np.arange(-1.5, 1.501, CUT_STEP)) -> tuple[np.ndarray, np.ndarray]:
    """The ordinal intensity's cut points fitted on dev, as temperature is for the intent: the trained cut points
    shifted (each by a value of ``grid``, kept increasing) to minimise the NLL of the intensities of ``rows``' motion
    texts. The intensity score itself is unchanged. Returns (fitted cut points ``(3,)``, shifts ``(3,)``)."""
    import itertools

    _, z = labels(rows)
    keep = z >= 0
    s, z = np.asarray(sh.intensity_score(params, x), np.float64)[keep], z[keep]
    theta = np.asarray(sh.thresholds(params), np.float64)
    best, shift = np.inf, np.zeros(3)
    for d in itertools.product(grid, repeat=3):  # the zero shift is on the grid: ties keep the trained points
        t = theta + np.array(d)
        if np.any(np.diff(t) <= 0.05):
            continue
        nll = -np.mean(sh.ordinal_log_probs(s, t, xp=np)[np.arange(len(z)), z])
        if nll < best - 1e-9:
            best, shift = nll, np.array(d)
    return theta + shift, shift


def dev_score(r: dict, plain: dict, situations: dict | None = None) -> float:
    """Mean of the v2-dev intent accuracy on motion texts, intensity exact, share of motion acted on, share of
    no-behaviour texts held, and the plainly worded dev intent accuracy (so it cannot fall unseen); with
    ``situations`` (the ship rule's score: the :data:`SITUATION_DEVS` hold-outs at the same threshold), its intent
    accuracy too."""
    terms = [r["intent_motion"], r["intensity_exact"], r["coverage_motion"], r["none_held"], plain["intent_motion"]]
    if situations is not None:
        terms.append(situations["intent_motion"])
    return float(np.mean([t for t in terms if t == t]))


def fit(x, rows, row_weight, inputs, hidden, steps=400, z_hidden=0, dropout=0.1, seeds=(0,), reasons=None):
    """Train one head on features ``x`` of ``rows`` weighted ``row_weight`` (an ensemble of one head per seed
    when ``seeds`` holds several: :func:`head.stack`); returns (params, config)."""
    seed = seeds[0]
    why = reason_labels(rows, reasons) if reasons else None
    cfg = sh.HeadConfig(
        hidden=hidden,
        z_hidden=z_hidden,
        steps=steps,
        dropout=dropout,
        seed=seed,
        inputs=inputs,
        num_reasons=len(reasons) if reasons else 0,
    )
    intent, intensity = labels(rows)
    w = _class_balanced(rows, row_weight, reasons or reason_classes(rows))
    members = [
        jax.tree.map(np.asarray, sh.train(jax.random.key(s), x, intent, intensity, w.astype(np.float32), cfg, why)[0])
        for s in seeds
    ]
    return (members[0] if len(members) == 1 else sh.stack(members)), cfg


def distill(
    teacher: dict, encoder_layers: tuple[int, ...], texts: list[str], steps: int = DISTILL_STEPS, progress: bool = True
) -> tuple[dict, list]:
    """A student encoder of the teacher's layers ``encoder_layers`` (embeddings shared and frozen), trained to
    reproduce the teacher's final token states (mean squared error over real tokens) on ``texts``: AdamW with a
    cosine schedule over ``steps`` batches of :data:`DISTILL_BATCH` texts of similar length, from a fixed seed.
    Returns (the student's encoder params, float32; the loss every 100 steps ``[(step, loss)]``)."""
    import time

    import jax.numpy as jnp
    import optax

    from jgrounding.semantics import encoder

    teacher = jax.tree.map(lambda x: jnp.asarray(x, jnp.float32), teacher)
    pick = np.array(encoder_layers)
    frozen = {k: v for k, v in teacher.items() if k != "layers"}
    trained = jax.tree.map(lambda x: x[pick], teacher["layers"])
    opt = optax.adamw(optax.warmup_cosine_decay_schedule(0.0, DISTILL_LR, steps // 20, steps), weight_decay=0.01)
    state = opt.init(trained)

    @jax.jit
    def step(trained, state, ids, mask):
        target = jax.lax.stop_gradient(encoder.token_states(teacher, ids, mask))
        m = mask[..., None].astype(jnp.float32)

        def loss(layers_):
            out = encoder.token_states(dict(frozen, layers=layers_), ids, mask)
            return (((out - target) ** 2) * m).sum() / (m.sum() * out.shape[-1])

        value, grad = jax.value_and_grad(loss)(trained)
        updates, state = opt.update(grad, state, trained)
        return optax.apply_updates(trained, updates), state, value

    enc = encoder.tokenizer().encode_batch(texts)
    order = np.argsort([len(e.ids) for e in enc], kind="stable")
    batches = [order[i : i + DISTILL_BATCH] for i in range(0, len(order) - DISTILL_BATCH + 1, DISTILL_BATCH)]
    rng = np.random.default_rng(0)
    losses, t0 = [], time.perf_counter()
    for s in range(steps):
        chunk = [enc[i] for i in batches[rng.integers(len(batches))]]
        ids, mask = encoder.pad_rows(chunk, encoder.bucket_length(max(len(e.ids) for e in chunk)), len(chunk))
        trained, state, value = step(trained, state, ids, mask)
        if s % 100 == 0 or s == steps - 1:
            losses.append((s, float(value)))
            if progress:
                print(
                    f"    distil: step {s + 1}/{steps} token-state MSE {float(value):.5f} "
                    f"({time.perf_counter() - t0:.0f} s)",
                    flush=True,
                )
    return dict(frozen, layers=jax.tree.map(np.asarray, trained)), losses


def finetune(
    rows,
    row_weight,
    reasons,
    hidden=128,
    tuned_layers=3,
    epochs=8,
    enc_lr=2e-5,
    head_lr=3e-3,
    seed=0,
    encoder_layers=(),
    start=None,
    z_hidden=0,
):
    """Train the encoder's top ``tuned_layers`` layers and the head together (the "tuned" and "student" options).

    The encoder is the frozen MiniLM (``encoder_layers``: the layers it keeps, all by default), or ``start``: a
    distilled student's params (:func:`distill`) whose layers are ``encoder_layers``. The lower layers are frozen:
    their token states are computed once, then minibatches of 64 texts of similar length (shuffled, seeded) run the
    top layers, pool the four spans, and train on the head's loss. Returns (head params, float16 deltas of the top
    layers :func:`head.top_deltas`, config)."""
    import jax.numpy as jnp
    import optax

    from jgrounding.semantics import encoder, structure

    cfg = sh.HeadConfig(
        hidden=hidden,
        z_hidden=z_hidden,
        inputs="tuned",
        tuned_layers=tuned_layers,
        num_reasons=len(reasons),
        seed=seed,
        steps=0,
        encoder_layers=encoder_layers,
    )
    texts = [r["text"] for r in rows]
    structs = [structure.analyse(t) for t in texts]
    extras = np.stack([features.tuned_extras(t, st) for t, st in zip(texts, structs)])
    if start is not None:
        base = jax.device_put(start)
    else:
        base = dict(encoder.load_params(), layers=jax.device_put(sh.base_layers(cfg)))
    low = dict(base, layers=jax.tree.map(lambda a: a[:-tuned_layers], base["layers"]))
    top = jax.tree.map(lambda a: a[-tuned_layers:], base["layers"])

    @jax.jit
    def lower(params, ids, mask):
        x = params["word"][ids] + params["pos"][: ids.shape[1]][None] + params["type"][0][None, None]
        x = encoder.layer_norm(x, params["ln"])
        bias = (1.0 - mask[:, None, None, :].astype(jnp.float32)) * -1e9
        return jax.lax.scan(lambda h, p: (encoder.block(h, bias, p), None), x, params["layers"])[0]

    enc = encoder.tokenizer().encode_batch(texts)
    states, pools = [None] * len(texts), [None] * len(texts)
    order = np.argsort([len(e.ids) for e in enc], kind="stable")
    for start in range(0, len(texts), 64):
        idx = order[start : start + 64]
        length = encoder.bucket_length(max(len(enc[i].ids) for i in idx))
        ids, mask = encoder.pad_rows([enc[i] for i in idx], length, 64)
        h = np.asarray(lower(low, ids, mask))
        for r, i in enumerate(idx):
            n = len(enc[i].ids)
            st = structs[i]
            states[i] = h[r, :n]
            pools[i] = encoder.span_pools(enc[i], [("except", st.rejected), st.rejected, st.quoted], n)

    def batch(idx):
        length = encoder.bucket_length(max(len(states[i]) for i in idx))
        h = np.zeros((len(idx), length, encoder.HIDDEN), np.float32)
        m = np.zeros((len(idx), length), np.int32)
        pw = np.zeros((len(idx), features.NUM_POOLS, length), np.float32)
        for r, i in enumerate(idx):
            n = len(states[i])
            h[r, :n], m[r, :n], pw[r, :, :n] = states[i], 1, pools[i]
        return h, m, pw

    def top_features(top, h, m, pw, extra):
        bias = (1.0 - m[:, None, None, :].astype(jnp.float32)) * -1e9
        x = jax.lax.scan(lambda hh, p: (encoder.block(hh, bias, p), None), h, top)[0]
        pooled = jnp.einsum("bpl,bld->bpd", pw, x) / jnp.maximum(pw.sum(-1, keepdims=True), 1e-9)
        pooled = pooled / jnp.sqrt(jnp.sum(pooled**2, -1, keepdims=True) + 1e-12)  # smooth at an empty pool
        return jnp.concatenate([pooled.reshape(pooled.shape[0], -1), extra], 1)

    intent, intensity = labels(rows)
    why = reason_labels(rows, reasons)
    w = _class_balanced(rows, row_weight, reasons).astype(np.float32)

    def loss(params, key, h, m, pw, extra, it, iz, ww, wy):
        x = top_features(params["top"], h, m, pw, extra)
        return sh.loss(params["head"], key, x, it, iz, ww, cfg.dropout, wy, cfg.reason_weight)

    opt = optax.multi_transform(
        {"top": optax.adamw(enc_lr, weight_decay=cfg.l2), "head": optax.adamw(head_lr, weight_decay=cfg.l2)},
        {"top": "top", "head": "head"},
    )

    @jax.jit
    def step(params, state, key, *batch_args):
        value, grads = jax.value_and_grad(loss)(params, key, *batch_args)
        updates, state = opt.update(grads, state, params)
        return optax.apply_updates(params, updates), state, value

    params = {"top": top, "head": sh.init(jax.random.key(seed), cfg, cfg.num_features)}
    state = opt.init(params)
    rng = np.random.default_rng(seed)
    lengths = np.array([len(x) for x in states])
    for epoch in range(epochs):
        order = np.argsort(lengths + rng.uniform(0, 3, len(lengths)), kind="stable")
        batches = [order[i : i + 64] for i in range(0, len(order), 64)]
        rng.shuffle(batches)
        total = 0.0
        for b, idx in enumerate(batches):
            if len(idx) < 64:
                idx = np.concatenate([idx, order[: 64 - len(idx)]])
            h, m, pw = batch(idx)
            key = jax.random.key(seed * 100003 + epoch * 1009 + b)
            args = (h, m, pw, extras[idx], intent[idx], intensity[idx], w[idx], why[idx])
            params, state, value = step(params, state, key, *args)
            total += float(value)
        print(f"    tuned: epoch {epoch + 1}/{epochs} loss {total / len(batches):.3f}", flush=True)
    return jax.tree.map(np.asarray, params["head"]), sh.top_deltas(params["top"], cfg), cfg


def ship_choice(scored: dict) -> str:
    """The option shipped, of ``{name: (dev score, HeadConfig)}`` in the options' order: among those within
    :data:`SHIP_MARGIN` of the best score, the one whose encoder runs the fewest layers; then the higher score,
    then the first."""
    top = max(score for score, _ in scored.values())
    near = [k for k, (score, _) in scored.items() if score >= top - SHIP_MARGIN - 1e-12]
    return min(near, key=lambda k: (scored[k][1].num_encoder_layers, -scored[k][0], list(scored).index(k)))


def cached_finetune(name, rows, row_weight, reasons, teacher=None):
    """:func:`finetune` of option ``name`` (a "student" first distilled from ``teacher``, :func:`distill`), through
    a cache in ``.cache/semantics/`` keyed by the training rows, their weights, the option, the distillation
    settings, the teacher and the code that trains and reads them (:func:`finetune`, :func:`distill` and the
    encoder's modules), so a re-run (or a run that adds an option)
    skips the minutes of training. Returns (head params, top-layer deltas, config)."""
    from jgrounding.io import write_atomic

    opt = {k: v for k, v in OPTIONS[name].items() if k not in ("inputs", "distill_extra")}
    extra = distill_texts() if OPTIONS[name].get("distill_extra") else []
    h = hashlib.sha256(
        json.dumps(
            [
                name,
                opt,
                [r["text"] for r in rows],
                [r["intent"] for r in rows],
                [r.get("intensity") for r in rows],
                [r.get("style") for r in rows],
                np.asarray(row_weight).tolist(),
                reasons,
                [DISTILL_STEPS, DISTILL_BATCH, DISTILL_LR],
                extra,
            ]
        ).encode()
    )
    for code in ("structure.py", "encoder.py", "head.py", "features.py"):
        h.update((ROOT / "jgrounding" / "semantics" / code).read_bytes())
    h.update((inspect.getsource(finetune) + inspect.getsource(distill)).encode())
    if teacher is not None:
        _hash_arrays(h, teacher)
    path = CACHE / f"finetune-{name}-{h.hexdigest()[:16]}.npz"
    if path.exists():
        print(f"  {name}: trained before, read from {path.relative_to(ROOT)}", flush=True)
        with np.load(path) as f:
            params = {k.split("/", 1)[1]: f[k] for k in f.files if k.startswith("param/")}
            deltas = sh.unflatten({k.split("/", 1)[1]: f[k] for k in f.files if k.startswith("top/")})
            cfg = sh.HeadConfig.from_dict(json.loads(str(f["config"])))
        return params, deltas, cfg
    start = None
    if teacher is not None:
        texts = sorted({r["text"] for r in rows} | set(extra))
        start = cached_distill(teacher, opt["encoder_layers"], texts, name)
    params, deltas, cfg = finetune(rows, row_weight, reasons, **opt, start=start)
    buf = io.BytesIO()
    arrays = {f"param/{k}": np.asarray(v) for k, v in params.items()}
    arrays |= {f"top/{k}": np.asarray(v) for k, v in sh.flatten(deltas).items()}
    np.savez(buf, **arrays, config=json.dumps(dataclasses.asdict(cfg)))
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, buf.getvalue())
    return params, deltas, cfg


def _hash_arrays(h, tree) -> None:
    """Feed every leaf of ``tree``, as float32 bytes, to the hash ``h`` (the caches' keys of a teacher)."""
    for leaf in jax.tree.leaves(tree):
        h.update(np.asarray(leaf, np.float32).tobytes())


def distill_texts() -> list[str]:
    """The texts of :data:`DISTILL_EXTRA` (labels unused)."""
    return [r["text"] for path in DISTILL_EXTRA for r in read_jsonl(path)]


def cached_distill(teacher: dict, encoder_layers: tuple[int, ...], texts: list[str], name: str = "student") -> dict:
    """:func:`distill` through a cache in ``.cache/semantics/`` keyed by the teacher, the layers, the texts, the
    settings and the code, so that options sharing a distillation (``student-sit``, ``student-sit-slow``) run it
    once. Returns the student's encoder params."""
    from jgrounding.io import write_atomic

    h = hashlib.sha256(json.dumps([list(encoder_layers), texts, [DISTILL_STEPS, DISTILL_BATCH, DISTILL_LR]]).encode())
    h.update(inspect.getsource(distill).encode())
    h.update((ROOT / "jgrounding" / "semantics" / "encoder.py").read_bytes())
    _hash_arrays(h, teacher)
    path = CACHE / f"distill-{h.hexdigest()[:16]}.npz"
    if path.exists():
        print(f"  {name}: distilled before, read from {path}", flush=True)
        with np.load(path) as f:
            return sh.unflatten({k: f[k] for k in f.files})
    t = hashlib.sha256()
    _hash_arrays(t, teacher)
    print(
        f"  {name}: distilling the tuned encoder into its layers {encoder_layers} on {len(texts)} texts "
        f"({DISTILL_STEPS} steps; cache key {path.stem}, teacher {t.hexdigest()[:16]})",
        flush=True,
    )
    student, _ = distill(teacher, encoder_layers, texts, steps=DISTILL_STEPS)
    buf = io.BytesIO()
    np.savez(buf, **{k: np.asarray(v) for k, v in sh.flatten(student).items()})
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, buf.getvalue())
    return student


def _class_balanced(rows, row_weight, reasons) -> np.ndarray:
    """Row weights: each intent (and "none") weighs the same in total; within it rows weigh as their file does,
    and within "none" each kind of no-behaviour text (its reason) weighs the same. Mean 1."""
    intent, _ = labels(rows)
    w = np.asarray(row_weight, np.float64).copy()
    kind = reason_labels(rows, reasons)
    for k in np.unique(kind[intent == sh.NONE]):
        sel = (intent == sh.NONE) & (kind == k)
        w[sel] /= w[sel].sum()
    for c in np.unique(intent):
        w[intent == c] /= w[intent == c].sum()
    return w / w.mean()


def _probs(params, x, temperature=1.0):
    return tuple(np.asarray(a) for a in sh.predict(params, x, temperature))


def calibrate(params, dev, plain, situations) -> dict:
    """Fit a trained head's calibration and score it: ``dev``, ``plain``, ``situations`` are ``(features, rows)``
    of v2 dev, the plainly worded dev split and the situation hold-outs (:data:`SITUATION_DEVS`; rows may be empty).

    On v2 dev and the situation hold-outs together (situations are where the confidence and the intensity were off
    on the blind benches, and v2 dev holds 29 of them): the intensity cut points (:func:`fit_cut_points`, shifted
    from the trained ones), then the softmax temperature (NLL of the 17 classes); then the confidence threshold
    (:func:`calibrate_threshold`) and the ship score (:func:`dev_score`). Returns the calibrated params (``_params``)
    and what the report and the shipped meta hold."""
    (xd, dev), (xp, plain), (xsit, sit) = dev, plain, situations
    trained_cuts = np.asarray(sh.thresholds(params), np.float64)
    xc, cal_rows = (np.concatenate([xd, xsit]), dev + sit) if sit else (xd, dev)
    cuts, shifts = fit_cut_points(params, xc, cal_rows)
    params = calibration.with_cut_points(params, cuts)
    temperature = calibration.fit_temperature(lambda t: _probs(params, xc, t)[0], labels(cal_rows)[0])
    pm, pz = _probs(params, xd, temperature)
    ps = (*_probs(params, xsit, temperature), sit) if sit else None
    threshold = calibrate_threshold(pm, pz, dev, situations=ps)
    r = selective(pm, pz, dev, threshold)
    rp = selective(*_probs(params, xp, temperature), plain, threshold)
    rs = selective(*ps, threshold) if sit else None
    return dict(
        temperature=temperature,
        cut_points={"trained": trained_cuts.round(4).tolist(), "fitted on dev": cuts.round(4).tolist()},
        cut_point_shifts=shifts.tolist(),
        threshold=threshold,
        dev=r,
        dev_plain=rp,
        situations=rs,
        score=dev_score(r, rp, rs),
        _params=params,
        _xd=xd,
    )


def print_option(name: str, c: dict) -> None:
    """One line of an option's calibrated dev results (:func:`calibrate`)."""
    r, rp, rs = c["dev"], c["dev_plain"], c["situations"]
    print(
        f"  {name:15s} score {c['score']:.3f} | v2 dev: intent {r['intent_motion']:.3f} exact {r['intensity_exact']:.3f}"
        f" within1 {r['intensity_within_one']:.3f} acted {r['coverage_motion']:.3f} wrong {r['confident_wrong']:.3f}"
        f" held {r['none_held']:.3f} ECE {r['ece']:.3f} (T {c['temperature']:.2f}, thr {c['threshold']:.3f},"
        f" cut point shifts {c['cut_point_shifts']})"
        f" | plain dev intent {rp['intent_motion']:.3f}"
        + (
            f" | situations intent {rs['intent_motion']:.3f} acted {rs['coverage_motion']:.3f}"
            f" wrong {rs['confident_wrong']:.3f} ECE {rs['ece']:.3f}"
            if rs
            else ""
        ),
        flush=True,
    )


def read_situations(paths=SITUATION_DEVS) -> list[dict]:
    """The rows of the situation hold-outs (:data:`SITUATION_DEVS`), in order."""
    return [r for path in paths for r in read_jsonl(path)]


def recalibrate(path: Path, dev, plain, sit, situation_files: dict) -> int:
    """``--recalibrate``: the head at ``path`` calibrated again (:func:`calibrate`, from its trained cut points) on
    the dev splits and the situation hold-outs ``sit``, written back with its old calibration in the meta. The
    params digest changes with the cut points: the vote's table and the no-motion detector need rebuilding."""
    head = sh.load(str(path))
    # the trained cut points: the shipped ones less the fitted shift (a step of fit_cut_points' grid; the meta's
    # copies are rounded to 4 decimals)
    cuts = head.meta["cut_points"]
    shift = np.round((np.array(cuts["fitted on dev"]) - np.array(cuts["trained"])) / CUT_STEP) * CUT_STEP
    params = dict(head.params)
    params = calibration.with_cut_points(params, np.asarray(sh.thresholds(params), np.float64) - shift)
    xd, xp, xs = (features.head_inputs(head, [r["text"] for r in rows]) for rows in (dev, plain, sit))
    c = calibrate(params, (xd, dev), (xp, plain), (xs, sit))
    print_option(head.meta["selected"], c)
    before = {k: head.meta[k] for k in ("temperature", "threshold", "cut_points", "params_digest")}
    meta = dict(
        head.meta,
        temperature=c["temperature"],
        threshold=c["threshold"],
        cut_points=c["cut_points"],
        dev=c["dev"],
        dev_plain=c["dev_plain"],
        dev_ece=c["dev"]["ece"],
        situation_target_wrong=SITUATION_TARGET_WRONG,
        situation_files=situation_files,
        params_digest=sh.digest(c["_params"]),
        recalibrated_from=before,
    )
    with np.load(path) as f:
        deltas = sh.unflatten({k.split("/", 1)[1]: f[k] for k in f.files if k.startswith("top/")})
    sh.save(path, c["_params"], head.config, meta, deltas)
    sh.load.cache_clear()
    print(
        f"recalibrated {path.name}: temperature {before['temperature']:.2f} -> {c['temperature']:.2f}, threshold "
        f"{before['threshold']:.3f} -> {c['threshold']:.3f}; params {before['params_digest']} -> {meta['params_digest']}"
    )
    return 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--dev", default=str(DEV))
    p.add_argument("--dev-plain", default=str(DEV_PLAIN))
    p.add_argument(
        "--situations",
        default=",".join(str(x) for x in SITUATION_DEVS),
        help="situation-only hold-outs, comma-separated: calibration, threshold and one term of the ship score "
        "('' leaves them out)",
    )
    p.add_argument(
        "--recalibrate",
        action="store_true",
        help="train nothing: fit the calibration of the head at --out again (its trained cut points, temperature, "
        "threshold) on the dev splits and --situations, and write it back",
    )
    p.add_argument("--out", default=str(sh.ASSET))
    p.add_argument("--train-dir", default=str(TRAIN_DIR), help="folder of the training *.jsonl files")
    p.add_argument("--no-blind", action="store_true", help="leave out the blind writers' training splits (BLIND_TRAIN)")
    p.add_argument(
        "--options",
        default=",".join(DEFAULT_OPTIONS),
        help=f"options to compare (default: {','.join(DEFAULT_OPTIONS)}, the run that made the shipped head; "
        f"all: {', '.join(OPTIONS)})",
    )
    p.add_argument("--report", default=str(ROOT / "results" / "semantics_dev_options.json"))
    args = p.parse_args(argv)
    chosen = args.options.split(",")
    bad = [o for o in chosen if o not in OPTIONS]
    if bad:
        raise SystemExit(f"unknown option(s) {bad}; valid options: {', '.join(OPTIONS)}")
    blind = () if args.no_blind else BLIND_TRAIN
    rows, row_weight = load_train(args.train_dir, blind)
    dev = read_jsonl(args.dev) if Path(args.dev).exists() else []
    plain = read_jsonl(args.dev_plain)
    if not dev:
        print(f"{args.dev} missing: selecting and calibrating on {args.dev_plain} alone")
        dev = plain
    sit_paths = [Path(x) for x in args.situations.split(",") if x]
    sit = read_situations(sit_paths)
    situation_files = {x.name: hashlib.sha256(x.read_bytes()).hexdigest()[:16] for x in sit_paths}
    if args.recalibrate:
        return recalibrate(Path(args.out), dev, plain, sit, situation_files)
    reasons = reason_classes(rows)
    weights = {name: w for name, (_, w) in train_files(args.train_dir, blind).items()}
    print(f"train: {len(rows)} rows; dev: {len(dev)} + plain {len(plain)} rows; file weights {weights}")
    print(f"no-behaviour reasons: {reasons}")
    texts = [r["text"] for r in rows]
    if any(OPTIONS[o]["inputs"] != "tuned" for o in chosen):  # the frozen encoder's features (cached)
        xs = cached_structure_features(texts)
        xs_dev = cached_structure_features([r["text"] for r in dev])
        xs_plain = cached_structure_features([r["text"] for r in plain])
        xs_sit = cached_structure_features([r["text"] for r in sit]) if sit else None
    results = {}
    for name in chosen:
        opt = OPTIONS[name]
        deltas = None
        if opt["inputs"] == "tuned":
            student = bool(opt.get("encoder_layers"))  # an encoder of fewer layers: distilled from "tuned"
            if student and "tuned" not in results:
                raise SystemExit(f"the {name} option distils the tuned option's encoder: --options tuned,{name}")
            teacher = None
            if student:  # the tuned option's trained encoder, in float32
                t = results["tuned"]
                teacher = dict(encoder.load_numpy(), layers=sh.merged_layers(t["_deltas"], t["_cfg"]))
            params, deltas, cfg = cached_finetune(name, rows, row_weight, reasons, teacher)
            # Dev features through the shipped path: the float16 deltas on the frozen encoder, as ground() reads them.
            tuned = sh.Head(params, cfg, 1.0, 0.5, {}, sh.with_top(deltas, cfg))
            xd = features.head_inputs(tuned, [r["text"] for r in dev])
            xp = features.head_inputs(tuned, [r["text"] for r in plain])
            xsit = features.head_inputs(tuned, [r["text"] for r in sit]) if sit else None
        else:
            xd = inputs(opt["inputs"], xs_dev, [r["text"] for r in dev])
            xp = inputs(opt["inputs"], xs_plain, [r["text"] for r in plain])
            xsit = inputs(opt["inputs"], xs_sit, [r["text"] for r in sit]) if sit else None
            params, cfg = fit(inputs(opt["inputs"], xs, texts), rows, row_weight, reasons=reasons, **opt)
        results[name] = dict(
            option=opt, **calibrate(params, (xd, dev), (xp, plain), (xsit, sit)), _cfg=cfg, _deltas=deltas
        )
        print_option(name, results[name])
    best = ship_choice({k: (v["score"], v["_cfg"]) for k, v in results.items()})
    b = results[best]
    digests = {
        name: hashlib.sha256(path.read_bytes()).hexdigest()[:16]
        for name, (path, _) in train_files(args.train_dir, blind).items()
    }
    comparison = {k: {kk: vv for kk, vv in v.items() if not kk.startswith("_")} for k, v in results.items()}
    meta = {
        "temperature": b["temperature"],
        "threshold": b["threshold"],
        "cut_points": b["cut_points"],
        "selected": best,
        "option": b["option"],
        "reasons": reasons,
        "reason_text": {k: REASON_TEXT.get(k, k.replace("-", " ")) for k in reasons},
        "train_files": digests,
        "file_weights": weights,
        "dev_file": hashlib.sha256(Path(args.dev).read_bytes()).hexdigest()[:16] if Path(args.dev).exists() else "",
        "situation_files": situation_files,
        "dev": b["dev"],
        "dev_plain": b["dev_plain"],
        "dev_ece": b["dev"]["ece"],
        "dev_ece_uncalibrated": selective(*_probs(b["_params"], b["_xd"]), dev, b["threshold"])["ece"],
        "target_wrong": TARGET_WRONG,
        "situation_target_wrong": SITUATION_TARGET_WRONG,
        "config": dataclasses.asdict(b["_cfg"]),
        "params_digest": sh.digest(b["_params"]),
        "comparison": comparison,
    }
    sh.save(args.out, b["_params"], b["_cfg"], meta, b["_deltas"])
    if args.report:
        from jgrounding.io import write_atomic

        write_atomic(args.report, json.dumps(comparison, indent=1, sort_keys=True) + "\n")
    print(f"selected {best}; temperature {b['temperature']:.2f}; threshold {b['threshold']:.3f}")
    print(f"wrote {args.out} (params {meta['params_digest']})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
