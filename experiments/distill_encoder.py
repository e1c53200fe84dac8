"""A speed lever of issue #34 item 4, tried and reported: the shipped head's encoder with fewer layers, distilled
from its tuned six: ``python -m experiments.distill_encoder [--layers 3] [--steps 1500] [--write]``.

- **Student**: the teacher's layers :data:`PICK` ``[k]`` (every other one, ending with the tuned top layer), the
  embeddings shared and frozen.
- **Distillation**: the student learns the teacher's final token states (mean squared error over real tokens) on
  the training texts only: ``assets/semantics_train/*.jsonl`` and the blind writers' ``train.jsonl``
  (``assets/semantics_eval_v3``, ``assets/semantics_eval_w3``). AdamW with a cosine schedule, batches of
  :data:`BATCH` texts of similar length, from a fixed key.
- **Judged** on the dev splits (``assets/semantics_eval_v2/dev.jsonl``, ``assets/semantics_eval/dev.jsonl``; never
  the test splits or the frozen benches). The shipped head reads the student's states with its parameters,
  temperature, vote and threshold unchanged. Measured: the intent accuracy on motion texts, the share acted on
  (confidence at or above the threshold), and agreement with the six-layer teacher. Then the warm median of the
  compiled program (encoder and head, one text, its token bucket), six layers against ``k``, alternating text by
  text on the same texts; and the warm median of ``jg.ground(text)`` itself, what a user calls, with each encoder in
  turn (the student through the shipped head's loader for the length of the timing; the rule and the no-motion
  detector as shipped).

Nothing is shipped from here. ``--write`` stores the report in ``results/distill_encoder.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import optax

from jgrounding.io import write_atomic
from jgrounding.semantics import encoder, features, structure
from jgrounding.semantics import head as semantic_head
from jgrounding.semantics.embedded import predict_tuned_many
from jgrounding.vocabulary import INTENTS

ROOT = Path(__file__).resolve().parent.parent
PICK = {2: (2, 5), 3: (1, 3, 5), 4: (0, 2, 4, 5)}
BATCH = 32
LEARNING_RATE = 2e-4
SEED = 0
DEV = {
    "v2 dev": ROOT / "assets" / "semantics_eval_v2" / "dev.jsonl",
    "plain dev": ROOT / "assets" / "semantics_eval" / "dev.jsonl",
}


def read_jsonl(path) -> list[dict]:
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def training_texts() -> list[str]:
    paths = sorted((ROOT / "assets" / "semantics_train").glob("*.jsonl"))
    paths += [ROOT / "assets" / d / "train.jsonl" for d in ("semantics_eval_v3", "semantics_eval_w3")]
    texts = [r["text"] for p in paths for r in read_jsonl(p)]
    return sorted(set(texts))


def student_of(teacher: dict, layers: int) -> dict:
    pick = np.array(PICK[layers])
    return dict(
        teacher, layers=jax.tree.map(lambda x: jnp.asarray(np.asarray(x)[pick], jnp.float32), teacher["layers"])
    )


def distill(teacher: dict, layers: int, steps: int, texts: list[str], progress: bool = True) -> tuple[dict, list]:
    """The student's parameters after ``steps`` AdamW steps, and the loss every 100 steps."""
    teacher = jax.tree.map(lambda x: jnp.asarray(x, jnp.float32), teacher)
    student = student_of(teacher, layers)
    frozen = {k: v for k, v in student.items() if k != "layers"}
    opt = optax.adamw(optax.warmup_cosine_decay_schedule(0.0, LEARNING_RATE, steps // 20, steps), weight_decay=0.01)
    trained = student["layers"]
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
    batches = [order[i : i + BATCH] for i in range(0, len(order) - BATCH + 1, BATCH)]
    rng = np.random.default_rng(SEED)
    losses, t0 = [], time.perf_counter()
    for s in range(steps):
        idx = batches[rng.integers(len(batches))]
        chunk = [enc[i] for i in idx]
        ids, mask = encoder.pad_rows(chunk, encoder.bucket_length(max(len(e.ids) for e in chunk)), len(chunk))
        trained, state, value = step(trained, state, ids, mask)
        if s % 100 == 0 or s == steps - 1:
            losses.append((s, float(value)))
            if progress:
                print(f"step {s:5d}: loss {float(value):.5f} ({time.perf_counter() - t0:.0f} s)", flush=True)
    return dict(frozen, layers=trained), losses


def judge(head, texts_by_split: dict) -> dict:
    """Per dev split: intent accuracy on motion texts, share acted on, and the argmax intents (for agreement)."""
    out = {}
    for name, rows in texts_by_split.items():
        probs = predict_tuned_many(head, [r["text"] for r in rows])[0]
        pred = probs.argmax(1)
        motion = np.array([r["intent"] != "none" for r in rows])
        gold = np.array([INTENTS.index(r["intent"]) if r["intent"] != "none" else -1 for r in rows])
        acted = probs.max(1) >= head.threshold
        out[name] = {
            "intent": float((pred == gold)[motion].mean()),
            "acted": float(acted[motion].mean()),
            "pred": pred,
        }
    return out


def single_text_ms(heads: dict, texts: list[str], passes: int = 3) -> dict:
    """Warm median (ms) of the compiled program for one text, heads alternating text by text."""
    structs = [structure.analyse(t) for t in texts]
    extras = np.stack([features.tuned_extras(t, st) for t, st in zip(texts, structs)])
    inputs = []
    for idx, ids, mask, pools in features.encoder_batches(texts, structs, batch_size=1):
        inputs.append((ids, mask, pools, extras[idx]))
    times = {k: [] for k in heads}
    for h in heads.values():  # compile every bucket first
        for ids, mask, pools, x in inputs:
            jax.block_until_ready(h.run_tuned(ids, mask, pools, x))
    for p in range(passes):
        for i, (ids, mask, pools, x) in enumerate(inputs):
            names = list(heads) if (i + p) % 2 == 0 else list(heads)[::-1]
            for k in names:
                t0 = time.perf_counter()
                jax.block_until_ready(heads[k].run_tuned(ids, mask, pools, x))
                times[k].append(time.perf_counter() - t0)
    return {k: 1e3 * float(np.median(v)) for k, v in times.items()}


def ground_ms(heads: dict, texts: list[str], passes: int = 3) -> dict:
    """Warm median (ms) of ``jg.ground(text)`` with each head's encoder, alternating head by head text by text: the
    shipped head's loader (``semantic_head.load``, which every grounding call reads) returns that head meanwhile."""
    import jgrounding as jg

    loader = semantic_head.load
    times = {k: [] for k in heads}
    try:
        for h in heads.values():  # warm: every bucket compiled for this encoder
            semantic_head.load = lambda path=None, h=h: h
            for t in texts:
                jg.ground(t)
        for p in range(passes):
            for i, t in enumerate(texts):
                for k in list(heads) if (i + p) % 2 == 0 else list(heads)[::-1]:
                    semantic_head.load = lambda path=None, h=heads[k]: h
                    t0 = time.perf_counter()
                    jg.ground(t)
                    times[k].append(time.perf_counter() - t0)
    finally:
        semantic_head.load = loader
    return {k: 1e3 * float(np.median(v)) for k, v in times.items()}


def main(argv=None) -> int:
    from experiments.bench_sample import cpu_isa, cpu_model

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--layers", type=int, default=3, choices=sorted(PICK))
    p.add_argument("--steps", type=int, default=1500)
    p.add_argument("--write", action="store_true", help="write results/distill_encoder.md")
    args = p.parse_args(argv)
    head = semantic_head.load()
    teacher = head.encoder_params()
    texts = training_texts()
    print(f"{len(texts)} training texts; distilling {encoder.NUM_LAYERS} -> {args.layers} layers ({PICK[args.layers]})")
    t0 = time.perf_counter()
    student, losses = distill(teacher, args.layers, args.steps, texts)
    train_s = time.perf_counter() - t0
    small = dataclasses.replace(head, encoder=student)
    dev = {k: read_jsonl(v) for k, v in DEV.items()}
    full, fast = judge(head, dev), judge(small, dev)
    timing_texts = [r["text"] for rows in dev.values() for r in rows][::4]
    both = {"six layers": head, f"{args.layers} layers": small}
    ms = single_text_ms(both, timing_texts)
    user = ground_ms(both, timing_texts)
    rows = []
    for name in dev:
        agree = float((full[name]["pred"] == fast[name]["pred"]).mean())
        rows.append(
            f"| {name} | {len(dev[name])} | {full[name]['intent']:.3f} | {fast[name]['intent']:.3f} | "
            f"{full[name]['acted']:.3f} | {fast[name]['acted']:.3f} | {agree:.3f} |"
        )
    six, few = ms["six layers"], ms[f"{args.layers} layers"]
    six_g, few_g = user["six layers"], user[f"{args.layers} layers"]
    flags = os.environ.get("XLA_FLAGS", "") or "none"
    report = "\n".join(
        [
            f"### The shipped head's encoder distilled to {args.layers} layers (`python -m experiments.distill_encoder "
            f"--layers {args.layers} --steps {args.steps}`)",
            "",
            f"Student: the tuned teacher's layers {list(PICK[args.layers])}, trained {args.steps} steps (batch {BATCH}, "
            f"AdamW {LEARNING_RATE}, cosine) to match the teacher's final token states on {len(texts)} training texts "
            f"in {train_s:.0f} s; token-state MSE {losses[0][1]:.4f} at the start, {losses[-1][1]:.4f} at the end. "
            "The shipped head (parameters, temperature, vote, threshold) reads the student unchanged.",
            "",
            "| dev split | n | intent, six layers | intent, student | acted, six | acted, student | same intent |",
            "|---|---|---|---|---|---|---|",
            *rows,
            "",
            f"Warm median of the compiled program for one text ({len(timing_texts)} dev texts, alternating, 3 passes; "
            f"{os.cpu_count()} cores, {cpu_model()}, {cpu_isa()}, XLA_FLAGS {flags}): six layers {six:.2f} ms, "
            f"{args.layers} layers {few:.2f} ms ({six / few:.2f}x). `jg.ground(text)`, what a user calls, on the same "
            f"texts in the same way: six layers {six_g:.2f} ms, {args.layers} layers {few_g:.2f} ms "
            f"({six_g / few_g:.2f}x).",
            "",
        ]
    )
    print(report)
    if args.write:
        write_atomic(ROOT / "results" / "distill_encoder.md", report)
    return 0 if math.isfinite(losses[-1][1]) else 1


if __name__ == "__main__":
    raise SystemExit(main())
