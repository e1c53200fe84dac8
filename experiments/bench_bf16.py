"""A trial for one trajectory: the shipped S = 50 model with its weights stored as bfloat16 and
widened to float32 inside the compiled program, against the float32 model it ships: ``python -m
experiments.bench_bf16 [--rounds 10] [--write]``.

The float32 weights of the velocity MLP (0.8 MB) do not fit a 512 KB L2 cache; stored as bfloat16 they take half.
Both models are :class:`jgrounding.policy.program.Model` objects, sampled exactly as ``jg.sample`` samples a
single trajectory (the weights are constants of the compiled program; with bfloat16 weights every matmul takes a
bfloat16 operand, which XLA widens to float32 where it is used). Printed, and with ``--write`` written to
results/bench_bf16.md:

- speed: single ``Model.sample`` calls of both in alternation (:func:`jgrounding.evaluation.latency.interleaved_ms`:
  ``--rounds`` rounds, a fresh random order each, 40 calls per model and round cycling through the held-out
  tuples), each the median of per-round medians with its 95 % interval, and the paired sign test;
- quality: the benchmark v3 metrics (:func:`jgrounding.evaluation.distribution.score`) of K = 30 samples of every
  held-out tuple from each, with the same keys, and the largest difference between the two models' trajectories.
The CPU model, vector ISA and XLA_FLAGS head the output.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from experiments.bench_sample import cpu_isa, cpu_model
from jgrounding import load_library
from jgrounding.evaluation import distribution, latency
from jgrounding.io import write_atomic
from jgrounding.policy import program, sampling

RESULTS = Path(__file__).resolve().parent.parent / "results" / "bench_bf16.md"
REPS = 40
METRICS = ("prec_tau", "prec_r", "between", "mode_cov", "mode_bal", "intent_ret", "intensity_ret", "mm_ratio")


def models(steps: int = 50) -> dict[str, program.Model]:
    """The shipped model for ``steps`` as ``jg.sample`` loads it, and the same with its weights stored as bfloat16."""
    path = sampling.shipped_checkpoint(steps)
    f32 = sampling.model(None if path == sampling.DEFAULT_CHECKPOINT else path)
    tr = f32.trained
    bf16 = jax.tree.map(lambda x: x.astype(jnp.bfloat16) if jnp.issubdtype(x.dtype, jnp.floating) else x, tr.params)
    half = program.Model(dataclasses.replace(tr, params=bf16), f32.intent_emb, name=f"{f32.name} (bfloat16 weights)")
    return {"float32": f32, "bfloat16 storage": half}


def weight_bytes(model: program.Model) -> int:
    return int(sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(model.trained.params)))


def weights_as_arguments(model: program.Model, dtype, lib=None) -> tuple:
    """``(call, args_list)`` of one trajectory's network + spline (no gate) with the weights an argument of the
    compiled program in ``dtype``: as program constants (``jg.sample``'s programs) XLA folds a bfloat16 -> float32
    conversion at compile time and keeps float32 weights, so bfloat16 storage exists only as an argument. Compiled
    on the runtime ``jg.sample`` uses for one trajectory."""
    tr = model.trained
    params = jax.tree.map(lambda x: x.astype(dtype) if jnp.issubdtype(x.dtype, jnp.floating) else x, tr.seed_params(0))
    params = jax.device_put(params)
    config, emb = model.config(None, 50), jax.device_put(model.intent_emb)

    def run(params, intent, intensity, key):
        return tr.actuation(key, emb[intent], intensity, config, params=params)

    example = (params, np.zeros(1, np.int32), np.zeros(1, np.int32), jax.random.key(0))
    compiled = program.compile_for(jax.jit(run).lower(*example), 1)
    ho = (lib or load_library()).heldout
    rows = [jax.device_put((np.array([m], np.int32), np.array([z], np.int32))) for m, z in zip(ho.intent, ho.intensity)]
    return compiled, [(params, *rows[i % len(rows)], jax.random.key(i)) for i in range(REPS)]


def timing(ms: dict[str, program.Model], lib, rounds: int) -> dict[str, np.ndarray]:
    ho = lib.heldout
    entries = {}
    for name, m in ms.items():
        config = m.config(None, 50)
        args = [(jax.random.key(i), int(ho.intent[i % 64]), int(ho.intensity[i % 64])) for i in range(REPS)]
        entries[f"jg.sample path, {name} (weights: program constants)"] = (
            lambda k, a, b, m=m, c=config: m.sample(k, a, b, 1, c),
            args,
        )
    f32 = ms["float32"]
    entries["network + spline, float32 weights as an argument"] = weights_as_arguments(f32, jnp.float32, lib)
    entries["network + spline, bfloat16 weights as an argument"] = weights_as_arguments(f32, jnp.bfloat16, lib)
    return latency.interleaved_ms(entries, rounds=rounds)


def quality(ms: dict[str, program.Model], lib, k: int = 30) -> tuple[dict, float]:
    ho, ev = lib.heldout, lib.evaluation
    r = distribution.radius(ev)
    out, samples = {}, {}
    for name, m in ms.items():
        u = m.sample(jax.random.key(100), list(ho.intent), list(ho.intensity), k, m.config(None, 50))
        samples[name] = u
        out[name] = distribution.score(u, ho.intent, ho.intensity, ev, r=r).summary()
    a, b = samples.values()
    return out, float(np.abs(a - b).max())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--rounds", type=int, default=10, help="interleaved timing rounds")
    p.add_argument("--write", action="store_true", help=f"write {RESULTS.name} under results/")
    args = p.parse_args(argv)
    lib = load_library()
    ms = models()
    head = (
        f"bfloat16 weight storage for one trajectory, S = 50 ({ms['float32'].trained.method}), on 2 cores of "
        f"{cpu_model()} ({cpu_isa()}, XLA_FLAGS={os.environ.get('XLA_FLAGS') or '(none)'}), jax {jax.__version__}; "
        f"load average {os.getloadavg()[0]:.2f} at the start. Weights: "
        + ", ".join(f"{n} {weight_bytes(m) / 1e6:.2f} MB" for n, m in ms.items())
        + "."
    )
    print(head, flush=True)
    rounds = timing(ms, lib, args.rounds)
    lines = [head, "", "| one trajectory, S = 50 | ms (median of round medians) | 95% interval |", "|---|---|---|"]
    for name, x in rounds.items():
        med, lo, hi = latency.median_interval(x)
        lines.append(f"| {name} | {med:.3f} | [{lo:.3f}, {hi:.3f}] |")
    names = list(rounds)
    lines.append("")
    for a, b in ((names[1], names[0]), (names[3], names[2])):
        cmp = latency.compare_ms(rounds[a], rounds[b])
        lines.append(
            f"- {a} / {b}: {cmp['ratio']:.3f} (median over rounds); faster in {cmp['faster_rounds']} of "
            f"{cmp['rounds']} rounds, sign test p = {cmp['p']:.3f}: {cmp['verdict']}."
        )
    lines.append(
        "- As program constants the bfloat16 -> float32 conversion is folded at compile time (the compiled program "
        "holds float32 weights): the first pair runs the same program. As an argument the conversion runs inside "
        "the program, at every step."
    )
    scores, max_diff = quality(ms, lib)
    names = list(scores)
    lines += [
        "",
        "Quality, benchmark v3 metrics of K = 30 samples of each of the 64 held-out tuples (the same keys for both):",
        "",
        "| metric | " + " | ".join(names) + " | difference |",
        "|---|" + "---|" * (len(names) + 1),
    ]
    for key in METRICS:
        a, b = (scores[n][key] for n in names)
        lines.append(f"| {distribution.LABELS[key]} | {a:.3f} | {b:.3f} | {b - a:+.3f} |")
    lines += ["", f"Largest difference between the two models' trajectories from the same keys: {max_diff:.4f}."]
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_atomic(RESULTS, text + "\n")
        print(f"wrote {RESULTS}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
