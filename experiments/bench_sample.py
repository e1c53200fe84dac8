"""Sampling speed as users meet it: ``python -m experiments.bench sample`` (all numbers from one run).

For the shipped RF checkpoint, every sampler (euler, midpoint, rk4) at S = 50 and few-step S = 4, 2, 1:
the public ``jg.sample`` (one trajectory per call, cycling through the held-out tuples; and 1920
trajectories per call: one tuple x 1920, and 64 held-out tuples x 30) beside the compiled core
(:func:`jgrounding.evaluation.latency.core_ms`: the same computation with its inputs already on the
device and no host work), and their ratio. DDPM the same way from its ablation checkpoint when one
exists. Then the first ``jg.sample`` in a fresh process, cold and with JAX's persistent compilation
cache warm, and (unless ``--skip-train``) training speed. Goals of issue #14 are printed beside the
numbers; nothing here asserts them.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax

from jgrounding import load_library
from jgrounding.evaluation import latency
from jgrounding.generators import methods, sampling
from jgrounding.io import write_atomic
from jgrounding.training import TrainConfig

ROOT = Path(__file__).resolve().parent.parent
PAPER_MS = {"tuple_spline_rf": 4.87, "tuple_spline_ddpm": 7.86}
DDPM_CHECKPOINT = ROOT / "runs" / "ablation" / "tuple_spline_ddpm"
RF_CONFIGS = tuple((sampler, s) for sampler in ("euler", "midpoint", "rk4") for s in (50, 4, 2, 1))
DDPM_CONFIGS = (("ancestral", 50), ("ddim", 4), ("ddim", 2), ("ddim", 1))
GOALS = {"single": (0.4, 0.08), "batch": (100.0, 12.0)}  # ms at S = 50 / at S <= 4 (issue #14, this CPU)
BATCH = 1920  # 64 held-out tuples x K_div = 30
FIRST_CALL = (
    "import time; t = time.perf_counter(); import jax, jgrounding as jg; "
    "jg.sample(jax.random.key(0), 'greeting', 'moderate'); print(time.perf_counter() - t)"
)


def _goal(kind: str, steps: int) -> str:
    return f"<= {GOALS[kind][0 if steps == 50 else 1]:g} ms" if steps in (50, 4, 2, 1) else ""


def _rows(model: sampling.Model, label: str, configs, lib, reps: int, batch_reps: int) -> list[tuple]:
    ho = lib.heldout
    cond = model.intent_emb[ho.intent]
    key = jax.random.key(0)
    rows = []
    for sampler, s in configs:
        pub = latency.public_ms(model, ho.intent, ho.intensity, key, sampler=sampler, steps=s, reps=reps)
        core = latency.core_ms(model.trained, cond, ho.intensity, key, sampler=sampler, steps=s, reps=reps)
        rows.append((f"{label} {sampler} S={s}: single trajectory", pub, core, _goal("single", s)))
        one = latency.batch_ms(
            model,
            [int(ho.intent[0])],
            [int(ho.intensity[0])],
            key,
            num_samples=BATCH,
            sampler=sampler,
            steps=s,
            reps=batch_reps,
        )
        many = latency.batch_ms(
            model, ho.intent, ho.intensity, key, num_samples=BATCH // len(ho), sampler=sampler, steps=s, reps=batch_reps
        )
        core_b = latency.core_ms(
            model.trained, cond, ho.intensity, key, sampler=sampler, steps=s, batch=BATCH, reps=batch_reps
        )
        rows.append((f"{label} {sampler} S={s}: 1 tuple x {BATCH}", one, core_b, _goal("batch", s)))
        rows.append(
            (f"{label} {sampler} S={s}: {len(ho)} tuples x {BATCH // len(ho)}", many, core_b, _goal("batch", s))
        )
        print(
            f"  {label} {sampler} S={s}: single {pub:.3f} ms (core {core:.3f}); {BATCH}: {one:.1f} / "
            f"{many:.1f} ms (core {core_b:.1f})",
            flush=True,
        )
    return rows


def first_call(cache_dir: str | None) -> float:
    """Seconds from ``import jax`` to the first ``jg.sample`` result in a fresh Python process."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_COMPILATION_CACHE")}
    env["PYTHONPATH"] = str(ROOT)
    if cache_dir is not None:
        env.update(
            JAX_COMPILATION_CACHE_DIR=cache_dir,
            JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0",
            JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES="0",
        )
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], env=env, capture_output=True, text=True, cwd=ROOT)
    return float(out.stdout.strip().splitlines()[-1]) if out.returncode == 0 else float("nan")


def train_rows(lib, steps: int) -> list[str]:
    lines = []
    for seeds in ((0,), (0, 1, 2, 3, 4)):
        cfg = TrainConfig(steps=steps)
        methods.train("tuple_spline_rf", lib, seeds, TrainConfig(steps=cfg.chunk), progress=False)  # compile
        t0 = time.perf_counter()
        methods.train("tuple_spline_rf", lib, seeds, cfg, progress=False)
        dt = time.perf_counter() - t0
        lines.append(
            f"| train RF {steps} steps, {len(seeds)} seed(s) | {dt:.1f} s | "
            f"{steps * len(seeds) / dt:,.0f} seed-steps/s |"
        )
    return lines


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--reps", type=int, default=200, help="calls per single-trajectory median")
    p.add_argument("--batch-reps", type=int, default=5, help="calls per batch median")
    p.add_argument("--train-steps", type=int, default=10_000)
    p.add_argument("--skip-train", action="store_true")
    args = p.parse_args(argv)
    lib = load_library()
    load = os.getloadavg()[0]
    # The first call in a fresh process, before this process competes for the CPU.
    with tempfile.TemporaryDirectory() as cache:
        cold = first_call(None)
        fill = first_call(cache)
        warm = first_call(cache)
    print(f"first jg.sample in a fresh process: cold {cold:.2f} s, warm persistent cache {warm:.2f} s", flush=True)
    rf = sampling.model()
    rows = _rows(rf, "RF", RF_CONFIGS, lib, args.reps, args.batch_reps)
    if DDPM_CHECKPOINT.exists():
        ddpm_note = f"DDPM from its ablation checkpoint ({DDPM_CHECKPOINT.relative_to(ROOT)}, seed 0)"
        rows += _rows(sampling.model(DDPM_CHECKPOINT), "DDPM", DDPM_CONFIGS, lib, args.reps, args.batch_reps)
    else:
        ddpm_note = (
            f"DDPM not measured: no checkpoint at {DDPM_CHECKPOINT.relative_to(ROOT)} (`make ablation` writes it)"
        )
    lines = [
        f"Sampling benchmark: the public `jg.sample` beside the compiled core, one run (RF: the shipped "
        f"checkpoint; {ddpm_note}). Load average {load:.2f} at the start on {os.cpu_count()} cores; "
        f"jax {jax.__version__} on {jax.default_backend()}. Medians of {args.reps} single calls (cycling "
        f"through the {len(lib.heldout)} held-out tuples) and of {args.batch_reps} batch calls.",
        "",
        "| what | public jg.sample | compiled core | public / core | goal (public) |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| {what} | {pub:.3f} ms | {core:.3f} ms | {pub / core:.2f}x | {goal} |" for what, pub, core, goal in rows
    ]
    single50 = next(pub for what, pub, _, _ in rows if what == "RF euler S=50: single trajectory")
    ho = lib.heldout
    itself = {
        s: latency.jg_sample_ms(ho.intent, ho.intensity, jax.random.key(1), steps=s, reps=args.reps) for s in (50, 1)
    }
    lines += [
        "",
        f"`jg.sample(key, intent, intensity, steps=S)` itself, with its routing to the shipped model for S "
        f"(`assets/checkpoints/shipped.json`) and checkpoint-cache lookup: S = 50 {itself[50]:.3f} ms "
        f"({itself[50] / single50:.2f}x the public-path row above), S = 1 {itself[1]:.3f} ms (the 2-rectified model).",
        "",
        f"RF euler S=50 single trajectory: public {single50:.3f} ms vs the paper's "
        f"{PAPER_MS['tuple_spline_rf']} ms ({PAPER_MS['tuple_spline_rf'] / single50:.1f}x faster here).",
        "",
        "| first jg.sample in a fresh process (import jax + jgrounding, load, compile or cache hit, sample) "
        "| seconds | goal |",
        "|---|---|---|",
        f"| cold (no persistent compilation cache) | {cold:.2f} s | |",
        f"| filling the persistent cache (JAX_COMPILATION_CACHE_DIR, min compile time 0) | {fill:.2f} s | |",
        f"| warm persistent cache | {warm:.2f} s | <= 1.0 s |",
    ]
    if not args.skip_train:
        lines += ["", "| training | measured | rate |", "|---|---|---|"] + train_rows(lib, args.train_steps)
    text = "\n".join(lines)
    print(text)
    write_atomic(ROOT / "results" / "bench_sample.md", text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
