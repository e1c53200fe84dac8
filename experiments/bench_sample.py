"""Sampling speed as users meet it: ``python -m experiments.bench sample`` (all numbers from one run).

First, through ``jg.sample`` itself for every step count S in ``STEP_COUNTS`` (each served by
its shipped checkpoint, ``jgrounding/assets/checkpoints/shipped.json``): single-trajectory and 1,920-trajectory times
(64 held-out tuples x 30), the public/core ratio, the achieved GFLOP/s against the machine's peak
(cores x clock x fp32 FLOP per cycle from /proc/cpuinfo's vector flags), and the fixed per-call cost
taken apart (dispatch, random numbers, gate, host copy, Python). ``make bench-peer`` adds PyTorch peers
(experiments/bench_peer.py) as a block of results/bench_sample.md that this script keeps.

Then (``--all-samplers``), for the shipped RF checkpoint, every sampler (euler, midpoint, rk4) at S = 50 and few-step S = 4, 2, 1:
the public ``jg.sample`` (one trajectory per call, cycling through the held-out tuples; and 1920
trajectories per call: one tuple x 1920, and 64 held-out tuples x 30) beside the compiled core
(:func:`jgrounding.evaluation.latency.core_ms`: the same computation with its inputs already on the
device and no host work), and their ratio. DDPM the same way from its ablation checkpoint when one
exists. Then the first ``jg.sample`` in a fresh process, cold and with JAX's persistent compilation
cache warm, and (unless ``--skip-train``) training speed. The latency goals are printed beside the
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
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jgrounding import load_library, safety
from jgrounding.evaluation import latency
from jgrounding.io import write_atomic
from jgrounding.policy import sampling
from jgrounding.training import TrainConfig, trainer

ROOT = Path(__file__).resolve().parent.parent
PAPER_MS = {"tuple_spline_rf": 4.87, "tuple_spline_ddpm": 7.86}
DDPM_CHECKPOINT = ROOT / "runs" / "ablation" / "tuple_spline_ddpm"
RF_CONFIGS = tuple((sampler, s) for sampler in ("euler", "midpoint", "rk4") for s in (50, 4, 2, 1))
DDPM_CONFIGS = (("ancestral", 50), ("ddim", 4), ("ddim", 2), ("ddim", 1))
GOALS = {"single": (0.4, 0.08), "batch": (100.0, 12.0)}  # ms at S = 50 / at S <= 4 (a 2-core CPU)
BATCH = 1920  # 64 held-out tuples x K_div = 30
FIRST_CALL = (
    "import time; t = time.perf_counter(); import jax, jgrounding as jg; "
    "jg.sample(jax.random.key(0), 'greeting', 'moderate'); print(time.perf_counter() - t)"
)


STEP_COUNTS = (1, 2, 4, 8, 50)
PEER_START, PEER_END = "<!-- peer:start -->", "<!-- peer:end -->"  # experiments/bench_peer.py writes between


def cpu_model(cpuinfo: str = "/proc/cpuinfo") -> str:
    """The CPU's model name as the kernel reports it (``platform.processor()`` where /proc is absent)."""
    import platform

    try:
        line = next(x for x in Path(cpuinfo).read_text().splitlines() if x.startswith("model name"))
        return line.split(":", 1)[1].strip()
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def _cpu_flags(cpuinfo: str) -> set[str]:
    flags = set()
    for line in Path(cpuinfo).read_text().splitlines():
        if line.startswith("flags"):
            flags |= set(line.split(":", 1)[1].split())
    return flags


def cpu_isa(cpuinfo: str = "/proc/cpuinfo") -> str:
    """The widest vector unit the CPU reports: ``avx512f``, ``avx2+fma`` or ``sse`` (XLA_FLAGS may limit what XLA
    uses; this reads /proc/cpuinfo)."""
    flags = _cpu_flags(cpuinfo)
    return "avx512f" if "avx512f" in flags else "avx2+fma" if {"avx2", "fma"} <= flags else "sse"


def peak_gflops(cpuinfo: str = "/proc/cpuinfo") -> tuple[float, str]:
    """(peak fp32 GFLOP/s, how it was computed): cores x clock x FLOP per cycle, where an FMA unit on
    512-bit vectors (avx512f) counts 64 fp32 FLOP per cycle, on 256-bit (avx2 + fma) 32, else 8 (SSE)."""
    mhz = [float(x.split(":", 1)[1]) for x in Path(cpuinfo).read_text().splitlines() if x.startswith("cpu MHz")]
    cores = len(os.sched_getaffinity(0))
    isa = cpu_isa(cpuinfo)
    per_cycle = {"avx512f": 64, "avx2+fma": 32}.get(isa, 8)
    ghz = max(mhz) / 1e3 if mhz else float("nan")
    peak = cores * ghz * per_cycle
    return peak, f"{cores} cores x {ghz:.2f} GHz x {per_cycle} fp32 FLOP/cycle ({isa}) = {peak:.0f} GFLOP/s"


def flops_per_sample(model: sampling.Model, steps: int) -> float:
    """Multiply-add FLOPs of the network calls of one sample: per call 2 x (D x W + hidden W x W + W x D)
    (the condition's and time's shares of the first layer are computed once per call, not per step);
    guidance doubles the rows. The spline reconstruction and the gate (~5 kFLOP) are left out."""
    net = nnx.merge(model.trained.graphdef, jax.tree.map(lambda x: x[0], model.trained.params))
    dim = net.dim
    shapes = [getattr(net, f"l{i + 1}").kernel.value.shape for i in range(net.depth)]
    per_call = 2.0 * (dim * shapes[0][1] + sum(a * b for a, b in shapes[1:]))
    return per_call * steps * (2 if model.guidance else 1)


def matmul_gflops(model: sampling.Model, steps: int, batch: int = BATCH, reps: int = 15) -> float:
    """The machine's JAX matmul rate on the network's own shapes, measured now: ``steps`` passes of the
    layers' matmuls alone (rows = ``batch``, doubled with guidance; the first layer's x share, the hidden
    layers, the output layer) in one compiled loop, nothing else; GFLOP/s, median of ``reps``. The sampler's
    achieved rate is reported as a share of this, beside the theoretical peak."""
    net = nnx.merge(model.trained.graphdef, jax.tree.map(lambda x: x[0], model.trained.params))
    dim = net.dim
    shapes = [(dim, net.l1.kernel.value.shape[1])] + [
        getattr(net, f"l{i + 1}").kernel.value.shape for i in range(1, net.depth)
    ]
    rows = batch * (2 if model.guidance else 1)
    keys = jax.random.split(jax.random.key(0), len(shapes) + 1)
    ws = [jax.random.normal(k, s, jnp.float32) / np.sqrt(s[0]) for k, s in zip(keys[1:], shapes)]
    x0 = jax.random.normal(keys[0], (rows, dim), jnp.float32)

    @jax.jit
    def chain(x, ws):
        def body(_, x):
            h = x
            for w in ws:
                h = h @ w
            return x + 1e-3 * h  # the next pass depends on this one, as the sampler's steps do

        return jax.lax.fori_loop(0, steps, body, x)

    flop = 2.0 * rows * sum(a * b for a, b in shapes) * steps
    s = median_s(lambda: jax.block_until_ready(chain(x0, ws)), reps)
    return flop / s / 1e9


def median_s(call, reps: int) -> float:
    call()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def step_rows(lib, reps: int, batch_reps: int, peak: float) -> tuple[list[str], dict]:
    """Per S: jg.sample itself (single, 64 x 30) beside the compiled core of the checkpoint it routes to."""
    ho = lib.heldout
    key = jax.random.key(0)
    lines = [
        "| S | served by | single: jg.sample | core | public / core | 1,920: jg.sample | core | public / core "
        "| GFLOP per 1,920 | achieved GFLOP/s | % of peak | matmul rate, same shapes | % of matmul rate |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    out = {}
    for s in STEP_COUNTS:
        path = sampling.shipped_checkpoint(s)
        model = sampling.model(None if path == sampling.DEFAULT_CHECKPOINT else path)
        cond = model.intent_emb[ho.intent]
        single = latency.jg_sample_ms(ho.intent, ho.intensity, key, steps=s, reps=reps)
        config = model.config(None, s)  # the config jg.sample(steps=s) samples with
        core = latency.core_ms(model.trained, cond, ho.intensity, key, config, reps=reps, like_public=True)
        keys = iter(jax.random.split(key, batch_reps + 1))
        many = 1e3 * median_s(
            lambda: sampling.sample(next(keys), list(ho.intent), list(ho.intensity), BATCH // len(ho), steps=s),
            batch_reps,
        )
        core_b = latency.core_ms(
            model.trained, cond, ho.intensity, key, config, batch=BATCH, reps=batch_reps, like_public=True
        )
        gflop = flops_per_sample(model, s) * BATCH / 1e9
        rate = gflop / (many / 1e3)
        mm = matmul_gflops(model, s, reps=batch_reps)
        name = Path(model.name).name
        w = f", w = {model.guidance:g}" if model.guidance else ""
        w += f", T = {model.temperature(s):g}" if model.temperature(s) != 1.0 else ""  # initial-noise scale
        lines.append(
            f"| {s} | {name}{w} | {single:.3f} ms | {core:.3f} ms | {single / core:.2f}x | {many:.1f} ms | "
            f"{core_b:.1f} ms | {many / core_b:.2f}x | {gflop:.2f} | {rate:.1f} | {100 * rate / peak:.1f} % | "
            f"{mm:.1f} GFLOP/s | {100 * rate / mm:.0f} % |"
        )
        out[s] = {
            "single_ms": single,
            "core_ms": core,
            "batch_ms": many,
            "core_batch_ms": core_b,
            "gflop": gflop,
            "matmul_gflops": mm,
        }
        print("  " + lines[-1], flush=True)
    return lines, out


def _compiled_single(fn, *example):
    """``fn`` compiled ahead of time on the runtime ``jg.sample`` uses for one trajectory."""
    return sampling.compile_for(jax.jit(fn).lower(*example), 1)


def _single_parts(model, steps: int, m: int, z: int, key):
    """``(args, ungated)``: the arguments of ``model``'s single-trajectory program at ``steps`` and its network +
    spline without the gate, compiled like it (seed 0's parameters, the tuple's conditioning gathered inside)."""
    args = (
        jax.device_put(np.zeros(model.trained.num_tendons, np.float32)),
        *jax.device_put((np.array([m], np.int32), np.array([z], np.int32))),
        jax.device_put(np.int32(0)),
        key,
    )
    tr = model.trained
    params = tr.seed_params(0)
    config = model.config(None, steps)  # what jg.sample(steps=steps) samples with
    emb = jax.device_put(model.intent_emb)

    def ungated(current, intent, intensity, first, k):
        del current
        return tr.actuation(jax.random.fold_in(k, first), emb[intent], intensity, config, params=params)

    return args, ungated


def network_ms(model, steps: int, reps: int, lib=None) -> float:
    """Median ms of one trajectory's network + spline at ``steps`` alone (no gate, no host work, inputs on the
    device, the runtime jg.sample uses): the floor that no cut in the sampler's overhead can go below."""
    ho = (lib or load_library()).heldout
    args, ungated = _single_parts(model, steps, int(ho.intent[0]), int(ho.intensity[0]), jax.random.key(0))
    raw = _compiled_single(ungated, *args)
    return 1e3 * median_s(lambda: jax.block_until_ready(raw(*args)), reps)


def fixed_cost(lib, steps: int, reps: int) -> list[str]:
    """The fixed cost of one single-trajectory call at ``steps``, taken apart (medians of ``reps``)."""
    ho = lib.heldout
    path = sampling.shipped_checkpoint(steps)
    model = sampling.model(None if path == sampling.DEFAULT_CHECKPOINT else path)
    m, z = int(ho.intent[0]), int(ho.intensity[0])
    key = jax.random.key(0)
    program = model.program(model.config(None, steps), 1, "blend")
    args, ungated = _single_parts(model, steps, m, z, key)
    tr = model.trained
    raw = _compiled_single(ungated, *args)
    gated = _compiled_single(
        lambda current, *a: safety.make_safe(ungated(current, *a), safety.MAX_SLEW, current), *args
    )
    trivial = _compiled_single(lambda current, intent, intensity, first, k: current + first, *args)
    rng = _compiled_single(lambda k, first: jax.random.normal(jax.random.fold_in(k, first), (1, tr.dim)), key, args[3])
    out = program.executable(*args)
    fresh = [jnp.array(out) + 0 for _ in range(reps + 1)]
    it = iter(fresh)
    t = {
        "public": median_s(lambda: model.sample(key, m, z, 1, model.config(None, steps)), reps),
        "compiled": median_s(lambda: jax.block_until_ready(program.executable(*args)), reps),
        "ungated": median_s(lambda: jax.block_until_ready(raw(*args)), reps),
        "gated": median_s(lambda: jax.block_until_ready(gated(*args)), reps),
        "dispatch": median_s(lambda: jax.block_until_ready(trivial(*args)), reps),
        "rng": median_s(lambda: jax.block_until_ready(rng(key, args[3])), reps),
        "copy": median_s(lambda: safety.release(next(it)), reps),
    }
    t = {k: 1e3 * v for k, v in t.items()}
    rows = [
        ("dispatch: a compiled program of the same arguments that returns one of them", t["dispatch"]),
        ("random numbers: fold_in + normal (1, D), less dispatch", max(t["rng"] - t["dispatch"], 0.0)),
        ("network + spline, ungated, less dispatch", max(t["ungated"] - t["dispatch"], 0.0)),
        ("gate (bounds, blend from current, slew limit): the same program gated - ungated", t["gated"] - t["ungated"]),
        ("host copy and release check (device -> numpy, finite, bounds)", t["copy"]),
        ("Python: validation, key, cached inputs (public - compiled - copy)", t["public"] - t["compiled"] - t["copy"]),
    ]
    lines = [
        f"Fixed cost of one single-trajectory `jg.sample` at S = {steps} ({Path(model.name).name}): public "
        f"{t['public']:.3f} ms, the compiled program with its inputs on the device {t['compiled']:.3f} ms "
        f"(medians of {reps}; each part timed on its own, so the parts need not add up exactly).",
        "",
        "| part | ms |",
        "|---|---|",
    ] + [f"| {what} | {ms:.3f} |" for what, ms in rows]
    return lines


def _peer_block(path: Path) -> str:
    """The PyTorch peer block a ``make bench-peer`` run left in ``path`` (kept across re-runs)."""
    text = path.read_text() if path.exists() else ""
    if PEER_START in text and PEER_END in text:
        return text[text.index(PEER_START) : text.index(PEER_END) + len(PEER_END)]
    return f"{PEER_START}\nPyTorch peers: not measured in this file yet (`make bench-peer`).\n{PEER_END}"


def _goal(kind: str, steps: int) -> str:
    return f"<= {GOALS[kind][0 if steps == 50 else 1]:g} ms" if steps in (50, 4, 2, 1) else ""


def _rows(model: sampling.Model, label: str, configs, lib, reps: int, batch_reps: int) -> list[tuple]:
    ho = lib.heldout
    cond = model.intent_emb[ho.intent]
    key = jax.random.key(0)
    rows = []
    for sampler, s in configs:
        config = model.config(sampler, s)
        pub = latency.public_ms(model, ho.intent, ho.intensity, key, config, reps=reps)
        core = latency.core_ms(model.trained, cond, ho.intensity, key, config, reps=reps)
        rows.append((f"{label} {sampler} S={s}: single trajectory", pub, core, _goal("single", s)))
        one = latency.batch_ms(
            model, [int(ho.intent[0])], [int(ho.intensity[0])], key, config, num_samples=BATCH, reps=batch_reps
        )
        many = latency.batch_ms(
            model, ho.intent, ho.intensity, key, config, num_samples=BATCH // len(ho), reps=batch_reps
        )
        core_b = latency.core_ms(model.trained, cond, ho.intensity, key, config, batch=BATCH, reps=batch_reps)
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
        trainer.fit("tuple_spline_rf", lib, seeds, TrainConfig(steps=cfg.chunk), progress=False)  # compile
        t0 = time.perf_counter()
        trainer.fit("tuple_spline_rf", lib, seeds, cfg, progress=False)
        dt = time.perf_counter() - t0
        lines.append(
            f"| train RF {steps} steps, {len(seeds)} seed(s) | {dt:.1f} s | "
            f"{steps * len(seeds) / dt:,.0f} seed-steps/s |"
        )
    return lines


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--reps", type=int, default=200, help="calls per single-trajectory median")
    p.add_argument("--batch-reps", type=int, default=15, help="calls per batch median")
    p.add_argument("--train-steps", type=int, default=10_000)
    p.add_argument("--skip-train", action="store_true")
    p.add_argument(
        "--all-samplers", action="store_true", help="also every RF sampler and DDPM (the latency goals' table)"
    )
    args = p.parse_args(argv)
    lib = load_library()
    load = os.getloadavg()[0]
    # The first call in a fresh process, before this process competes for the CPU.
    with tempfile.TemporaryDirectory() as cache:
        cold = first_call(None)
        fill = first_call(cache)
        warm = first_call(cache)
    print(f"first jg.sample in a fresh process: cold {cold:.2f} s, warm persistent cache {warm:.2f} s", flush=True)
    peak, peak_text = peak_gflops()
    print(f"peak: {peak_text}", flush=True)
    steps_lines, _ = step_rows(lib, args.reps, args.batch_reps, peak)
    lines = [
        f"Sampling benchmark, one run: `jg.sample` itself for each step count S (routed to the checkpoint "
        f"`jgrounding/assets/checkpoints/shipped.json` names for S) beside the compiled core of that checkpoint (the same "
        f"computation with its inputs on the device and no host work). Load average {load:.2f} at the start on "
        f"{os.cpu_count()} cores of {cpu_model()} ({cpu_isa()}, XLA_FLAGS={os.environ.get('XLA_FLAGS') or '(none)'}); "
        f"jax {jax.__version__} on {jax.default_backend()}. Medians of {args.reps} "
        f"single calls (cycling through the {len(lib.heldout)} held-out tuples) and of {args.batch_reps} "
        f"calls of 1,920 trajectories ({len(lib.heldout)} held-out tuples x {BATCH // len(lib.heldout)}).",
        "",
        f"Peak: {peak_text}. Achieved: the network's multiply-add FLOPs of a 1,920 call "
        "(`flops_per_sample`) over the public time. Matmul rate: the same layers' matmuls alone, at the same "
        "rows and steps, in one compiled loop measured in this run (`matmul_gflops`): what JAX reaches on these "
        "shapes on this machine, the sampler's ceiling.",
        "",
        *steps_lines,
        "",
        *fixed_cost(lib, 1, args.reps),
        "",
        *fixed_cost(lib, 50, args.reps),
    ]
    if args.all_samplers:
        rf = sampling.model()
        rows = _rows(rf, "RF", RF_CONFIGS, lib, args.reps, args.batch_reps)
        if DDPM_CHECKPOINT.exists():
            rows += _rows(sampling.model(DDPM_CHECKPOINT), "DDPM", DDPM_CONFIGS, lib, args.reps, args.batch_reps)
        lines += [
            "",
            "Every sampler of the shipped RF (and DDPM from its ablation checkpoint when present), through the "
            "public path of the checkpoint (no routing):",
            "",
            "| what | public | compiled core | public / core | goal |",
            "|---|---|---|---|---|",
        ]
        lines += [
            f"| {what} | {pub:.3f} ms | {core:.3f} ms | {pub / core:.2f}x | {goal} |" for what, pub, core, goal in rows
        ]
    lines += [
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
    out = ROOT / "results" / "bench_sample.md"
    text = "\n".join(lines + ["", _peer_block(out)])
    print(text)
    write_atomic(out, text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
