"""The prepared accelerator check: ``bash scripts/device_check.sh [--tiny] [--engines E,...] [--out PATH]``.

On one GPU in at most 8 minutes, writes results/gpu.md with, from one run:

1. Rollout throughput (150 control steps x 4 substeps) of each engine: native MuJoCo on every host core
   (``mujoco.rollout``), MJX's JAX implementation (``"mjx"``) and its Warp implementation (``"mjx-warp"``), for
   batches of 1,920 to 65,536 run as padded chunks of ``CHUNK``: the compile (first call minus a warm call) apart
   from the run, trajectories/s and physics steps/s of the warm call, and the tip agreement with native MuJoCo.
2. The sampler on the device: ``jg.sample`` single-trajectory latency and 1,920-trajectory time per S, and
   the compiled core's throughput for a batch of 65,536.
3. The ablation's physics columns (shape success, shape RMS, shape diversity, feasibility) for one seed of
   the shipped RF, K = 30 samples of each held-out tuple, on each engine through the ablation's own call
   (``jg.sim.rollout`` in chunks of ``MJX_CHUNK``), cold (compile included, as the ablation meets it) and warm.
4. The goals: >= 5 M physics steps/s at the best batch, and the physics columns faster on the accelerator
   than on native MuJoCo with the compile included; each printed as met or not.

``--tiny`` runs every step on the CPU in seconds (CI): small batches, K = 2 on 4 tuples, native MuJoCo
alone unless ``--engines`` names more (MJX's JAX trunk compiles for ~45 s on a CPU, Warp's kernels for ~20 s);
the file says so.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import jax
import mujoco
import numpy as np

from jgrounding import load_library, sim
from jgrounding.evaluation import generate, latency, metrics
from jgrounding.evaluation import physics as trunk_eval
from jgrounding.io import write_atomic
from jgrounding.policy import sampling

ROOT = Path(__file__).resolve().parent.parent


def cpu_model() -> str:
    """The host CPU's model name (/proc/cpuinfo), or the platform's processor string."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or "unknown CPU"


FULL = {
    "batches": (1920, 8192, 32768, 65536),
    "native": 8192,  # native MuJoCo's rate is flat in B: measured up to here, not at 65,536 (minutes on 16 cores)
    "k": 30,
    "tuples": 64,
    "core_batch": 65536,
    "reps": 50,
    "steps": (1, 50),
    "engines": ("native", "mjx", "mjx-warp"),
}
TINY = {
    "batches": (8, 16),
    "native": 16,
    "k": 2,
    "tuples": 4,
    "core_batch": 64,
    "reps": 5,
    "steps": (1,),
    "engines": ("native",),
}
CHUNK = 8192  # MJX chunk for batches >= CHUNK (2,048 below it)
PHYSICS_STEPS = 150 * sim.SUBSTEPS  # physics steps of one trajectory
GOAL_STEPS_PER_S = 5e6


def commands(lib, batch: int) -> np.ndarray:
    """``batch`` library trajectories (train and held out, repeated) ``(B, 150, 4)``."""
    u = np.concatenate([lib.train.u, lib.heldout.u]).astype(np.float32)
    return u[np.arange(batch) % len(u)]


def rollout(u, engine: str):
    """(rollout, compile seconds, run seconds) on ``engine``: the first call's time minus a warm call's is the
    compile (MJX programs, one per chunk size; Warp's kernels; native: none)."""
    if engine == "native":
        t0 = time.perf_counter()
        r = sim.rollout(u, engine="native")
        return r, 0.0, time.perf_counter() - t0
    from jgrounding.sim import mjx as trunk_mjx

    fn = trunk_mjx.rollout_warp if engine == "mjx-warp" else trunk_mjx.rollout_mjx
    chunk = CHUNK if len(u) >= CHUNK else min(2048, 1 << (len(u) - 1).bit_length())
    t0 = time.perf_counter()
    fn(u[:chunk], True, chunk=chunk)  # compile (or load from the persistent cache), then run one chunk
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    fn(u[:chunk], True, chunk=chunk)
    warm_chunk = time.perf_counter() - t0
    t0 = time.perf_counter()
    r = fn(u, True, chunk=chunk)
    return r, max(0.0, first - warm_chunk), time.perf_counter() - t0


def throughput(lib, sizes: dict, engines: tuple[str, ...]) -> tuple[list[str], dict]:
    """The throughput table, and each engine's best physics steps/s."""
    u_native = commands(lib, sizes["native"])
    rollout(u_native[:2], "native")  # load the model and start the worker threads before timing
    native, _, t_native = rollout(u_native, "native")
    native_rate = len(u_native) / t_native
    lines = [
        "| engine | B | compile (s) | run (s) | trajectories/s | physics steps/s | vs native | max tip gap vs native |",
        "|---|---|---|---|---|---|---|---|",
    ]
    best = {}
    for engine in engines:
        for b in sizes["batches"]:
            if engine == "native" and b > sizes["native"]:
                continue
            u = commands(lib, b)
            r, compile_s, t = rollout(u, engine)
            n = min(len(u_native), b)
            gap = 1e3 * float(np.abs(r.backbone[:n, :, -1] - native.backbone[:n, :, -1]).max())
            rate = b / t
            best[engine] = max(best.get(engine, 0.0), rate * PHYSICS_STEPS)
            lines.append(
                f"| {engine} | {b:,} | {compile_s:.1f} | {t:.2f} | {rate:,.0f} | {rate * PHYSICS_STEPS:,.0f} "
                f"| {rate / native_rate:.2f}x | {gap:.2f} mm |"
            )
            print("  " + lines[-1], flush=True)
    return lines, best


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


def physics_rows(lib, sizes: dict, engines: tuple[str, ...]) -> tuple[list[str], dict]:
    """The ablation's physics columns on each engine, cold (compile included) and warm; and each engine's cold
    seconds."""
    from experiments import ablation

    trained, _ = sampling.load()
    n = sizes["tuples"]
    cond = sampling.model().intent_emb[lib.heldout.intent[:n]]
    steps = sizes["steps"][-1]
    config = dataclasses.replace(trained.sample_config, steps=steps)
    u = generate.generate(trained, cond, lib.heldout.intensity[:n], jax.random.key(3), sizes["k"], config)
    lines = [
        "| engine | shape success | shape RMS (m) | shape diversity (m) | feasible | trajectories | seconds, cold "
        "(compile included) | seconds, warm |",
        "|---|---|---|---|---|---|---|---|",
    ]
    cold = {}
    for engine in engines:
        t0 = time.perf_counter()
        ref, tol = trunk_eval.library_references(lib, metrics.TAU_RMS, engine=engine)
        p = ablation.physics(u, ref[:n], tol, engine=engine)
        cold[engine] = time.perf_counter() - t0
        warm = ablation.physics(u, ref[:n], tol, engine=engine)
        lines.append(
            f"| {engine} | {p.shape_success[0]:.3f} | {p.shape_rms_m[0]:.4f} | {p.shape_diversity_m[0]:.4f} "
            f"| {p.feasible[0]:.3f} | {p.samples:,} | {cold[engine]:.1f} | {warm.seconds:.1f} |"
        )
        print("  " + lines[-1], flush=True)
    return lines, cold


def goal_lines(best: dict, cold: dict) -> list[str]:
    """The accelerator goals, each met or not, from the measured figures."""
    lines = []
    accel = {e: v for e, v in best.items() if e != "native"}
    if accel:
        e = max(accel, key=accel.get)
        met = "met" if accel[e] >= GOAL_STEPS_PER_S else "not met"
        lines.append(f"- >= 5 M physics steps/s at the best batch: {met} ({e}: {accel[e] / 1e6:.2f} M/s).")
    fast = {e: v for e, v in cold.items() if e != "native"}
    if fast and "native" in cold:
        e = min(fast, key=fast.get)
        met = "met" if fast[e] < cold["native"] else "not met"
        lines.append(
            f"- Ablation physics columns faster than native MuJoCo, compile included: {met} ({e}: {fast[e]:.1f} s "
            f"against native's {cold['native']:.1f} s)."
        )
    return lines or ["- No accelerator engine ran: no goal is measured."]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tiny", action="store_true", help="CPU, small sizes, native MuJoCo alone unless --engines (CI)")
    p.add_argument(
        "--engines",
        help=f"comma-separated engines to measure, of {', '.join(e for e in sim.ENGINES if e != 'auto')} "
        "(default: all three; --tiny: native)",
    )
    p.add_argument("--out", default=str(ROOT / "results" / "gpu.md"))
    args = p.parse_args(argv)
    t_start = time.perf_counter()
    sizes = TINY if args.tiny else FULL
    engines = tuple(args.engines.split(",")) if args.engines else sizes["engines"]
    for e in engines:
        if e not in sim.ENGINES or e == "auto":
            p.error(f"unknown engine {e!r}; valid: {', '.join(x for x in sim.ENGINES if x != 'auto')}")
    engines = ("native", *[e for e in engines if e != "native"])  # native is every comparison's reference
    from jgrounding.sim import mjx as trunk_mjx

    if "mjx-warp" in engines and trunk_mjx.warp_unavailable():
        print(f"skipping mjx-warp: {trunk_mjx.warp_unavailable()}", flush=True)
        engines = tuple(e for e in engines if e != "mjx-warp")
    backend = jax.default_backend()
    if not args.tiny:
        trunk_mjx.enable_compilation_cache()
    lib = load_library()
    devices = ", ".join(str(d.device_kind) for d in jax.devices())
    print(f"device check on {backend} ({devices}); tiny={args.tiny}", flush=True)
    throughput_lines, best = throughput(lib, sizes, engines)
    physics_lines, cold = physics_rows(lib, sizes, engines)
    parts = {"throughput": throughput_lines, "sampler": sampler_rows(lib, sizes), "physics": physics_lines}
    seconds = time.perf_counter() - t_start
    note = (
        "**Tiny run (CI): every step on the CPU at small sizes; these are not accelerator figures.** No accelerator run has been recorded yet: `bash scripts/device_check.sh` on "
        "a GPU machine replaces this file with its figures."
        if args.tiny
        else f"Accelerator run on {devices}."
    )
    lines = [
        "### Accelerator check (`bash scripts/device_check.sh`, experiments/device_check.py)",
        "",
        note,
        f"jax {jax.__version__}, MuJoCo {mujoco.__version__}, backend {backend}, engines {', '.join(engines)}, "
        f'engine "auto" here: {sim.resolve_engine("auto")}; host {os.cpu_count()} CPU cores ({cpu_model()}); '
        f"run time {seconds:.0f} s.",
        "",
        "#### Goals",
        "",
        *goal_lines(best, cold),
        "",
        "#### Rollout throughput (150 control steps x 4 substeps; native MuJoCo on every host core)",
        "",
        *parts["throughput"],
        "",
        "#### Sampler on this device",
        "",
        *parts["sampler"],
        "",
        f"#### Ablation physics columns, one seed (shipped RF, S = {sizes['steps'][-1]}, K = {sizes['k']} x "
        f"{sizes['tuples']} held-out tuples; cold = the first call in this process, compile included)",
        "",
        *parts["physics"],
    ]
    text = "\n".join(lines) + "\n"
    write_atomic(args.out, text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
