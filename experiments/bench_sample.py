"""Sampling and training speed: ``python -m experiments.bench sample`` (all numbers from one run).

Warm single-trajectory latency (tuple -> u, reconstruction and safety gate included) for RF and DDPM
at S = 50 and RF few-step; batched throughput for 1920 trajectories; training time for 10k steps
(one seed, and 5 seeds vmapped); the first ``jg.sample`` call in a fresh process. Ratios are against
the paper's Table II (RF 4.87 ms, DDPM 7.86 ms) and against RF S = 50 in this run.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import jax
import numpy as np

from jgrounding import load_library, semantics

from jgrounding.generators import methods
from jgrounding.io import write_atomic
from jgrounding.training import TrainConfig

PAPER_MS = {"tuple_spline_rf": 4.87, "tuple_spline_ddpm": 7.86}
ROOT = Path(__file__).resolve().parent.parent


def _trained(method, lib):
    path = ROOT / "runs" / "ablation" / method
    if path.exists():
        from experiments.sweep import load_trained

        return load_trained(method, ROOT / "runs" / "ablation"), "ablation checkpoint"
    return methods.train(method, lib, (0,), TrainConfig(steps=2000), progress=False), "trained 2k steps here"


def latency(trained, cond, intensity, steps, sampler="euler"):
    return methods.latency_ms(trained, cond, intensity, jax.random.key(0), sampler=sampler, steps=steps)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--train-steps", type=int, default=10_000)
    p.add_argument("--skip-train", action="store_true")
    args = p.parse_args(argv)
    lib = load_library()
    cond = semantics.intent_embeddings()[lib.heldout.intent]
    inten = lib.heldout.intensity
    rows = []
    rf, rf_src = _trained("tuple_spline_rf", lib)
    ddpm, ddpm_src = _trained("tuple_spline_ddpm", lib)
    base = latency(rf, cond, inten, 50)
    for name, tr, s, sampler in (("RF, Euler S=50", rf, 50, "euler"), ("RF, Euler S=4", rf, 4, "euler"),
                                 ("RF, RK4 S=4", rf, 4, "rk4"), ("DDPM, ancestral S=50", ddpm, 50, "ancestral"),
                                 ("DDPM, DDIM S=4", ddpm, 4, "ddim")):
        ms = base if (tr is rf and s == 50 and sampler == "euler") else latency(tr, cond, inten, s, sampler)
        paper = PAPER_MS[tr.method]
        rows.append((f"single trajectory, {name}", f"{ms:.3f} ms", f"{ms / base:.2f}x RF S=50; paper {paper} ms "
                     f"({paper / ms:.1f}x faster here)"))
    for tr, label in ((rf, "RF S=50"), (ddpm, "DDPM S=50")):
        one = jax.tree.map(lambda x: x[:1], tr.params)
        single = methods.Trained(tr.method, tr.graphdef, one, (0,), tr.num_controls)
        c = np.repeat(cond, 30, axis=0)
        z = np.repeat(inten, 30)
        methods.generate(single, c, z, jax.random.key(0), num_samples=1, batch=1920)
        t0 = time.perf_counter()
        methods.generate(single, c, z, jax.random.key(1), num_samples=1, batch=1920)
        dt = time.perf_counter() - t0
        rows.append((f"batch of 1920 trajectories, {label}", f"{1e3 * dt:.1f} ms", f"{1920 / dt:,.0f} trajectories/s"))
    if not args.skip_train:
        for seeds in ((0,), (0, 1, 2, 3, 4)):
            cfg = TrainConfig(steps=args.train_steps)
            methods.train("tuple_spline_rf", lib, seeds, TrainConfig(steps=cfg.chunk), progress=False)  # compile
            t0 = time.perf_counter()
            methods.train("tuple_spline_rf", lib, seeds, cfg, progress=False)
            dt = time.perf_counter() - t0
            rows.append((f"train RF {args.train_steps} steps, {len(seeds)} seed(s)", f"{dt:.1f} s",
                         f"{args.train_steps * len(seeds) / dt:,.0f} seed-steps/s"))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    code = ("import time; t=time.perf_counter(); import jax, jgrounding as jg; "
            "jg.sample(jax.random.key(0), 'greeting', 'moderate'); print(time.perf_counter()-t)")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, cwd=ROOT)
    first = float(out.stdout.strip().splitlines()[-1]) if out.returncode == 0 else float("nan")
    rows.append(("first jg.sample in a fresh process (import + load + compile)", f"{first:.2f} s", ""))
    load = os.getloadavg()[0]
    lines = [f"Sampling benchmark ({rf_src} for RF, {ddpm_src} for DDPM; load average {load:.2f} on "
             f"{os.cpu_count()} cores, jax {jax.__version__} on {jax.default_backend()}).", "",
             "| what | measured | ratio / note |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    text = "\n".join(lines)
    print(text)
    write_atomic(ROOT / "results" / "bench_sample.md", text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
