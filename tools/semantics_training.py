"""How ``python -m tools.train_semantics`` trains the semantic head's options: the head on frozen encoder features
(:func:`fit`), the encoder's top layers with it (:func:`finetune`), a student encoder distilled from the tuned one
(:func:`distill`), each cached in ``.cache/semantics/`` by what it was trained from, so a re-run skips it."""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import io
import json
from pathlib import Path

import jax
import numpy as np

from jgrounding.semantics import cue_reducer, encoder, features
from jgrounding.semantics import head as sh
from tools.semantics_data import ROOT, distill_texts, labels, reason_classes, reason_labels

CACHE = ROOT / ".cache" / "semantics"
# The options compared on dev. "eq3": the first trained head's inputs (sentence embedding + Eq. (3) cue
# features), retrained on the same data; "structure": the structure-aware inputs (the sentence, its chosen,
# rejected and quoted parts pooled apart from one encoder pass, Eq. (3) cues of the chosen part, structure flags).
OPTIONS = {
    "eq3": dict(inputs="eq3", hidden=128, steps=400),
    "structure": dict(inputs="structure", hidden=128, steps=400),
    "structure-wide": dict(inputs="structure", hidden=256, steps=800, dropout=0.3),
    # End to end: the encoder's top 3 layers trained with the head (minibatch AdamW, 8 epochs; the lower 3 layers
    # stay frozen, so their token states are computed once). Inputs as "structure", without the Eq. (3)
    # similarities (they live in the frozen encoder's space).
    "tuned": dict(inputs="tuned", hidden=128, tuned_layers=3, epochs=8),
    # A faster encoder: the "tuned" option's six layers (the teacher, trained in the same run; a re-run
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
DISTILL_STEPS = 1500  # AdamW steps of DISTILL_BATCH texts (cosine schedule, warm-up 5 %); about 10 min on 2 cores
DISTILL_BATCH = 32
DISTILL_LR = 2e-4


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

    from jgrounding.semantics import structure

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
