"""The prepared accelerator check: ``bash scripts/device_check.sh [--tiny] [--out PATH]``.

On one GPU in at most 8 minutes, writes results/gpu.md with, from one run:

1. MJX rollout throughput (trajectories/s of 150 control steps x 4 substeps) for batches of 1,920 to
   65,536, run as padded chunks of ``CHUNK`` (one compiled program per chunk size), against native MuJoCo on
   the host CPU (``mujoco.rollout``, one thread per core) for the same commands, and their tip agreement.
2. The sampler on the device: ``jg.sample`` single-trajectory latency and 1,920-trajectory time per S, and
   the compiled core's throughput for a batch of 65,536.
3. The ablation's physics columns (shape success, shape RMS, shape diversity, feasibility) for one seed of
   the shipped RF, K = 30 samples of each held-out tuple, through MJX, beside native MuJoCo on the same
   samples.

``--tiny`` runs every step on the CPU in seconds (CI): small batches, K = 2 on 4 tuples, and native MuJoCo
standing in for MJX (MJX's trunk compiles for ~70 s on a CPU); the file says so.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import jax
import numpy as np

from jgrounding import load_library, sim
from jgrounding.evaluation import generate, latency, metrics
from jgrounding.evaluation import physics as trunk_eval
from jgrounding.io import write_atomic
from jgrounding.policy import sampling

ROOT = Path(__file__).resolve().parent.parent
FULL = {
    "batches": (1920, 8192, 32768, 65536),
    "native": 1920,
    "k": 30,
    "tuples": 64,
    "core_batch": 65536,
    "reps": 50,
    "steps": (1, 50),
}
TINY = {"batches": (8, 16), "native": 8, "k": 2, "tuples": 4, "core_batch": 64, "reps": 5, "steps": (1,)}
CHUNK = 8192  # MJX chunk for batches >= CHUNK (2,048 below it)


def commands(lib, batch: int) -> np.ndarray:
    """``batch`` library trajectories (train and held out, repeated) ``(B, 150, 4)``."""
    u = np.concatenate([lib.train.u, lib.heldout.u]).astype(np.float32)
    return u[np.arange(batch) % len(u)]


def rollout(u, engine: str):
    """(rollout, seconds) on ``engine``; MJX in padded chunks (compiled once per chunk size before timing)."""
    if engine == "native":
        t0 = time.perf_counter()
        r = sim.rollout(u, engine="native")
        return r, time.perf_counter() - t0
    from jgrounding.sim import mjx as trunk_mjx

    chunk = CHUNK if len(u) >= CHUNK else min(2048, 1 << (len(u) - 1).bit_length())
    trunk_mjx.rollout_mjx(u[:1], True, chunk=chunk)  # compile (or load from the persistent cache)
    t0 = time.perf_counter()
    r = trunk_mjx.rollout_mjx(u, True, chunk=chunk)
    return r, time.perf_counter() - t0


def throughput(lib, sizes: dict, mjx_engine: str) -> list[str]:
    u_native = commands(lib, sizes["native"])
    native, t_native = rollout(u_native, "native")
    native_rate = len(u_native) / t_native
    lines = [
        f"| B | {mjx_engine} trajectories/s | native CPU trajectories/s (B = {len(u_native)}) | {mjx_engine} / native "
        "| max tip gap vs native |",
        "|---|---|---|---|---|",
    ]
    for b in sizes["batches"]:
        u = commands(lib, b)
        r, t = rollout(u, mjx_engine)
        n = min(len(u_native), b)
        gap = 1e3 * float(np.abs(r.backbone[:n, :, -1] - native.backbone[:n, :, -1]).max())
        lines.append(f"| {b:,} | {b / t:,.0f} | {native_rate:,.0f} | {b / t / native_rate:.2f}x | {gap:.2f} mm |")
        print("  " + lines[-1], flush=True)
    return lines


def sampler_rows(lib, sizes: dict) -> list[str]:
    ho = lib.heldout
    per_tuple = sizes["k"]
    lines = [
        f"| S | served by | single jg.sample | {len(ho) * per_tuple:,} jg.sample | core, batch "
        f"{sizes['core_batch']:,} | core samples/s |",
        "|---|---|---|---|---|---|",
    ]
    for s in sizes["steps"]:
        path = sampling.shipped_checkpoint(s)
        model = sampling.model(None if path == sampling.DEFAULT_CHECKPOINT else path)
        single = latency.jg_sample_ms(ho.intent, ho.intensity, jax.random.key(0), steps=s, reps=sizes["reps"])
        keys = iter(jax.random.split(jax.random.key(1), 4))
        call = lambda: sampling.sample(next(keys), list(ho.intent), list(ho.intensity), per_tuple, steps=s)  # noqa: E731
        call()
        t0 = time.perf_counter()
        call()
        batch = 1e3 * (time.perf_counter() - t0)
        cond = model.intent_emb[ho.intent]
        config = dataclasses.replace(model.trained.sample_config, sampler=None, steps=s)
        core = latency.core_ms(
            model.trained, cond, ho.intensity, jax.random.key(2), config, batch=sizes["core_batch"], reps=3
        )
        lines.append(
            f"| {s} | {Path(model.name).name} | {single:.3f} ms | {batch:.1f} ms | {core:.1f} ms | "
            f"{sizes['core_batch'] / core * 1e3:,.0f} |"
        )
        print("  " + lines[-1], flush=True)
    return lines


def physics_rows(lib, sizes: dict, mjx_engine: str) -> list[str]:
    from experiments import ablation

    trained, _ = sampling.load()
    n = sizes["tuples"]
    cond = sampling.model().intent_emb[lib.heldout.intent[:n]]
    steps = sizes["steps"][-1]
    config = dataclasses.replace(trained.sample_config, steps=steps)
    u = generate.generate(trained, cond, lib.heldout.intensity[:n], jax.random.key(3), sizes["k"], config)
    lines = [
        "| engine | shape success | shape RMS (m) | shape diversity (m) | feasible | trajectories | seconds |",
        "|---|---|---|---|---|---|---|",
    ]
    for engine in dict.fromkeys((mjx_engine, "native")):
        ref, tol = trunk_eval.library_references(lib, metrics.TAU_RMS, engine=engine)
        p = ablation.physics(u, ref[:n], tol, engine=engine)
        lines.append(
            f"| {engine} | {p.shape_success[0]:.3f} | {p.shape_rms_m[0]:.4f} | {p.shape_diversity_m[0]:.4f} "
            f"| {p.feasible[0]:.3f} | {p.samples:,} | {p.seconds:.1f} |"
        )
        print("  " + lines[-1], flush=True)
    return lines


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tiny", action="store_true", help="CPU, small sizes, native standing in for MJX (CI)")
    p.add_argument("--out", default=str(ROOT / "results" / "gpu.md"))
    args = p.parse_args(argv)
    t_start = time.perf_counter()
    sizes = TINY if args.tiny else FULL
    backend = jax.default_backend()
    mjx_engine = "native" if args.tiny else "mjx"
    if not args.tiny:
        from jgrounding.sim import mjx as trunk_mjx

        trunk_mjx.enable_compilation_cache()
    lib = load_library()
    devices = ", ".join(str(d.device_kind) for d in jax.devices())
    print(f"device check on {backend} ({devices}); tiny={args.tiny}", flush=True)
    parts = {
        "throughput": throughput(lib, sizes, mjx_engine),
        "sampler": sampler_rows(lib, sizes),
        "physics": physics_rows(lib, sizes, mjx_engine),
    }
    seconds = time.perf_counter() - t_start
    note = (
        "**Tiny run (CI): every step on the CPU at small sizes, native MuJoCo standing in for MJX; these are "
        "not accelerator figures.** No accelerator run has been recorded yet: `bash scripts/device_check.sh` on "
        "a GPU machine replaces this file with its figures."
        if args.tiny
        else f"Accelerator run on {devices}."
    )
    lines = [
        "### Accelerator check (`bash scripts/device_check.sh`, experiments/device_check.py)",
        "",
        note,
        f'jax {jax.__version__}, backend {backend}, engine "auto" here: {sim.resolve_engine("auto")}; host '
        f"{os.cpu_count()} CPU cores; run time {seconds:.0f} s.",
        "",
        f"#### Rollout throughput: {mjx_engine} vs native MuJoCo on the CPU (150 control steps x 4 substeps)",
        "",
        *parts["throughput"],
        "",
        "#### Sampler on this device",
        "",
        *parts["sampler"],
        "",
        f"#### Ablation physics columns, one seed (shipped RF, S = {sizes['steps'][-1]}, K = {sizes['k']} x "
        f"{sizes['tuples']} "
        "held-out tuples)",
        "",
        *parts["physics"],
    ]
    text = "\n".join(lines) + "\n"
    write_atomic(args.out, text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
