"""Trunk physics throughput: MJX (jit(vmap(scan))) against native MuJoCo doing the same rollouts.

``python -m experiments.bench trunk --compile`` instead measures where MJX's compile time goes: the cold
``jit(mjx.step)`` compile of model variants (contact pairs, substep structure), each in a fresh process.

``python -m experiments.bench trunk [--batches 64,256,1920] [--chunk 256]`` prints, in one run: the MJX
compile time cold (empty persistent cache) and again in a fresh process with the cache filled, then
physics steps/s for each batch size on both engines, as ratios, and the tip agreement of the two.
MJX runs every batch as padded chunks of ``--chunk`` so one compiled program serves all sizes.
Then, for the ablation's batch (K_div x 64 = 1,920 trajectories per method and seed), simulated
trajectories per second on each engine through :func:`jgrounding.evaluation.physics.simulate_samples` (what the
ablation calls), which engine ``"auto"`` picks here, and the share of ``make ablation`` that physics
takes: measured, from the last run's results/ablation.json, and predicted from this rate.
Writes results/bench_trunk.md.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax
import mujoco
import numpy as np

from experiments import bench_sample
from jgrounding import load_library, sim
from jgrounding.evaluation import physics
from jgrounding.io import write_atomic
from jgrounding.sim import mjcf as tm
from jgrounding.sim import mjx as trunk_mjx

ROOT = Path(__file__).resolve().parent.parent
_CACHED = (
    "import sys, time, numpy as np; from jgrounding.sim import mjx as trunk_mjx; trunk_mjx.enable_compilation_cache(sys.argv[1]); "
    "u = np.zeros((int(sys.argv[2]), 150, 4)); t = time.perf_counter(); "
    "trunk_mjx.rollout_mjx(u, True, chunk=int(sys.argv[2])); print(time.perf_counter() - t - float(sys.argv[3]))"
)


def _first_and_warm(u, chunk):
    """(seconds of the first call, seconds of a second call) of the MJX rollout of ``u``."""
    times = []
    for _ in range(2):
        t0 = time.perf_counter()
        trunk_mjx.rollout_mjx(u, True, chunk=chunk)
        times.append(time.perf_counter() - t0)
    return times


_PROBE = """
import sys, time, jax, mujoco
from mujoco import mjx
from jgrounding.sim import mjcf as tm
from jgrounding.sim.mjx import compiler_options
contact, pairs, what = sys.argv[1] == "1", int(sys.argv[2]), sys.argv[3]
opts = None if sys.argv[4:] == ["xla-default"] else compiler_options()
m = mujoco.MjModel.from_xml_string(tm.build_xml(contact=contact, contact_segments=pairs))
m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR
mx = mjx.put_model(m)
d = mjx.make_data(mx)
if what.startswith("chunk"):  # the rollout program of jgrounding.sim.mjx, as engine "mjx" compiles it
    from jgrounding.sim import mjx as trunk_mjx
    t = time.perf_counter()
    lowered = trunk_mjx.lower_rollout(int(what[5:]), contact)
    t1 = time.perf_counter()
    lowered.compile()
    print(t1 - t, time.perf_counter() - t1, float("nan"))
    raise SystemExit(0)
if what == "step":
    fn = jax.jit(mjx.step, compiler_options=opts)
elif what in ("nested", "flat"):  # a whole rollout of 2 trunks, 150 control steps x 4 substeps, two program shapes
    def one(u):
        d0 = mjx.make_data(mx)
        if what == "nested":  # a scan of control steps around a scan of substeps
            def control_step(d, c):
                d = jax.lax.scan(lambda d, _: (mjx.step(mx, d), None), d.replace(ctrl=c), None, length=4)[0]
                return d, d.xpos
            return jax.lax.scan(control_step, d0, u)[1]
        def physics_step(d, c):  # one flat scan over every physics step (jgrounding.sim.mjx)
            d = mjx.step(mx, d.replace(ctrl=c))
            return d, d.xpos
        return jax.lax.scan(physics_step, d0, jax.numpy.repeat(u, 4, axis=0))[1][3::4]
    fn = jax.jit(jax.vmap(one), compiler_options=opts)
    d = jax.numpy.zeros((2, 150, 4), jax.numpy.float32)
else:  # one control step: SUBSTEPS physics steps in a scan, vmapped over 64 trunks
    def ctrl(d):
        return jax.lax.scan(lambda d, _: (mjx.step(mx, d), None), d, None, length=4)[0]
    fn = jax.jit(jax.vmap(lambda d: ctrl(d)), compiler_options=opts)
    d = jax.tree.map(lambda x: jax.numpy.stack([x] * 64), d)
t = time.perf_counter()
lowered = fn.lower(mx, d) if what == "step" else fn.lower(d)
t1 = time.perf_counter()
compiled = lowered.compile()
t2 = time.perf_counter()
args = (mx, d) if what == "step" else (d,)
jax.block_until_ready(compiled(*args))
t3 = time.perf_counter()
for _ in range(20):
    out = compiled(*args)
jax.block_until_ready(out)
steps = {"step": 1, "nested": 2 * 600, "flat": 2 * 600}.get(what, 4 * 64)
print(t1 - t, t2 - t1, 20 * steps / (time.perf_counter() - t3))
"""
COMPILE_VARIANTS = (  # (label, contact, pairs, what[, "xla-default": without jgrounding.sim.mjx.compiler_options])
    (
        f'the ablation\'s chunk: engine "mjx" (jgrounding.sim.mjx), vmap({sim.MJX_CHUNK}) of one flat scan of 600 '
        "physics steps, shipped model",
        "1",
        str(tm.CONTACT_SEGMENTS),
        f"chunk{sim.MJX_CHUNK}",
    ),
    (
        "the same program for a chunk of 256",
        "1",
        str(tm.CONTACT_SEGMENTS),
        "chunk256",
    ),
    ("no contact pairs, single step", "0", "0", "step"),
    (f"{tm.CONTACT_SEGMENTS} pairs (shipped model), single step", "1", str(tm.CONTACT_SEGMENTS), "step"),
    (
        f"{tm.CONTACT_SEGMENTS} pairs (shipped model), single step, XLA's default CPU fusion emitters",
        "1",
        str(tm.CONTACT_SEGMENTS),
        "step",
        "xla-default",
    ),
    ("no contact pairs, vmap(64) of a scan of 4 substeps", "0", "0", "scan"),
    (
        f"{tm.CONTACT_SEGMENTS} pairs (shipped model), vmap(64) of a scan of 4 substeps",
        "1",
        str(tm.CONTACT_SEGMENTS),
        "scan",
    ),
    (f"{tm.NUM_SEGMENTS} pairs (every segment), vmap(64) of a scan of 4 substeps", "1", str(tm.NUM_SEGMENTS), "scan"),
    ("no contact pairs, rollout of 2: scan of 150 control steps around a scan of 4 substeps", "0", "0", "nested"),
    ("no contact pairs, rollout of 2: one flat scan of 600 physics steps (jgrounding.sim.mjx)", "0", "0", "flat"),
    (
        f"{tm.CONTACT_SEGMENTS} pairs (shipped model), rollout of 2: nested scans",
        "1",
        str(tm.CONTACT_SEGMENTS),
        "nested",
    ),
    (
        f"{tm.CONTACT_SEGMENTS} pairs (shipped model), rollout of 2: one flat scan",
        "1",
        str(tm.CONTACT_SEGMENTS),
        "flat",
    ),
)


COMPILE_TIMEOUT_S = 300  # a variant's process (import, trace, compile, 20 warm calls) is stopped after this


def compile_probe(only: str | None = None) -> list[str]:
    lines = ["| MJX model variant | trace + lower (s) | XLA compile (s) | warm physics steps/s |", "|---|---|---|---|"]
    for label, *argv in COMPILE_VARIANTS:
        if only and only not in label:
            continue
        try:
            out = subprocess.run(
                [sys.executable, "-c", _PROBE, *argv],
                capture_output=True,
                text=True,
                cwd=ROOT,
                env={**os.environ, "PYTHONPATH": str(ROOT)},
                timeout=COMPILE_TIMEOUT_S,
            )
        except subprocess.TimeoutExpired:
            lines.append(f"| {label} | stopped after {COMPILE_TIMEOUT_S} s in all | not finished | — |")
            print(lines[-1], flush=True)
            continue
        trace, comp, rate = (float(x) for x in out.stdout.split()[-3:]) if out.returncode == 0 else (float("nan"),) * 3
        lines.append(f"| {label} | {trace:.1f} | {comp:.1f} | {f'{rate:,.0f}' if np.isfinite(rate) else '—'} |")
        print(lines[-1], flush=True)
    return lines


# The compile regression's bisection (docs/versions.md): jit(mjx.step) of the shipped trunk.xml compiled
# cold in a venv per (jax, MuJoCo/MJX) stack, with XLA's defaults and with jgrounding.sim.mjx.compiler_options().
BISECT_STACKS = (("0.6.2", "3.3.7"), ("0.7.0", "3.3.7"), ("0.7.1", "3.3.7"), ("0.10.2", "3.17.0"))
_STEP_PROBE = """
import json, sys, time, jax, mujoco
from mujoco import mjx
m = mujoco.MjModel.from_xml_path(sys.argv[1])
opts = json.loads(sys.argv[2])
mx = mjx.put_model(m); d = mjx.make_data(mx)
t0 = time.perf_counter(); lowered = jax.jit(mjx.step, compiler_options=opts).lower(mx, d); t1 = time.perf_counter()
lowered.compile(); t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def bisect(stacks=BISECT_STACKS, venvs: Path = ROOT / "runs" / "bisect") -> list[str]:
    """Each stack in its own venv under ``venvs`` (created once, pip's cache), the step probe run twice in it."""
    from jgrounding.io import asset

    xml = str(asset("trunk.xml"))
    mujoco_of = {"3.3.7": "3.3.7", "3.17.0": "4.0.1"}  # the MuJoCo release each MJX pairs with
    lines = [
        "| jax | MuJoCo / MJX | XLA CPU fusion emitters | trace + lower (s) | XLA compile (s) |",
        "|---|---|---|---|---|",
    ]
    for jax_v, mjx_v in stacks:
        env = venvs / f"jax{jax_v}-mjx{mjx_v}"
        py = env / "bin" / "python"
        if not py.exists():
            subprocess.run([sys.executable, "-m", "venv", str(env)], check=True)
            pins = [f"jax=={jax_v}", f"jaxlib=={jax_v}", f"mujoco=={mujoco_of[mjx_v]}", f"mujoco-mjx=={mjx_v}"]
            subprocess.run([str(py), "-m", "pip", "install", "-q", *pins], check=True)
        for emitters in ("default", "off"):
            out = subprocess.run(
                # The stack's venv lacks jgrounding: the options travel from compiler_options() as JSON.
                [
                    str(py),
                    "-c",
                    _STEP_PROBE,
                    xml,
                    json.dumps(trunk_mjx.compiler_options() if emitters == "off" else None),
                ],
                capture_output=True,
                text=True,
                env={**os.environ, "JAX_PLATFORMS": "cpu"},
            )
            lower, comp = (float(x) for x in out.stdout.split()[-2:]) if out.returncode == 0 else (float("nan"),) * 2
            label = "XLA's default" if emitters == "default" else "off (`compiler_options()`)"
            lines.append(f"| {jax_v} | {mujoco_of[mjx_v]} / {mjx_v} | {label} | {lower:.1f} | {comp:.1f} |")
            print(lines[-1], flush=True)
    return lines


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--batches", default="64,256,1920")
    p.add_argument(
        "--chunk",
        type=int,
        default=trunk_mjx.CPU_MAX_CHUNK,
        help="MJX's padded chunk (on the CPU at most jgrounding.sim.mjx.CPU_MAX_CHUNK)",
    )
    p.add_argument("--compile", action="store_true", help="measure where MJX compile time goes, then exit")
    p.add_argument("--only", help="with --compile: only the variants whose label contains this text")
    p.add_argument(
        "--bisect",
        action="store_true",
        help="compile jit(mjx.step) on each stack of BISECT_STACKS (a venv each), then exit",
    )
    args = p.parse_args(argv)
    if args.bisect:
        from experiments.bench_sample import cpu_model, peak_gflops

        lines = bisect()
        lines.append(
            f"\nCold compiles of jit(mjx.step) of jgrounding/assets/trunk.xml, one process each, {cpu_model()}, "
            f"{peak_gflops()[1]}, load average {os.getloadavg()[0]:.2f} (`python -m experiments.bench trunk --bisect`)."
        )
        write_atomic(ROOT / "results" / "mjx_compile_bisect.md", "\n".join(lines) + "\n")
        return 0
    if args.compile:
        from experiments.bench_sample import cpu_model, peak_gflops

        lines = compile_probe(args.only)
        lines.append(
            f"\nCold compiles, no persistent cache, jax {jax.__version__}, MuJoCo/MJX {mujoco.__version__}, "
            f"{cpu_model()}, {peak_gflops()[1]}, XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r}, load average "
            f"{os.getloadavg()[0]:.2f}; sensors disabled as in jgrounding.sim.mjx; every row but the one that says "
            "otherwise compiled with jgrounding.sim.mjx.compiler_options()."
        )
        suffix = "" if not args.only else "_" + "".join(c if c.isalnum() else "-" for c in args.only)[:40]
        out = ROOT / "results" / f"bench_trunk_compile_jax{jax.__version__}{suffix}.md"
        write_atomic(out, "\n".join(lines) + "\n")
        print(f"wrote {out}")
        return 0
    lib = load_library()
    pool = np.concatenate([lib.train.u, lib.heldout.u])
    physics_steps = sim.NUM_STEPS * sim.SUBSTEPS
    lines = []

    def say(line=""):
        print(line, flush=True)
        lines.append(line)

    with tempfile.TemporaryDirectory() as cache:
        trunk_mjx.enable_compilation_cache(cache)
        first, run = _first_and_warm(pool[: args.chunk], args.chunk)
        out = subprocess.run(
            [sys.executable, "-c", _CACHED, cache, str(args.chunk), str(run)],
            capture_output=True,
            text=True,
            cwd=ROOT,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
        )
        cached = float(out.stdout.split()[-1]) if out.returncode == 0 else float("nan")
    say(
        f"MJX batched rollout (chunk {args.chunk}, 150 control steps x {sim.SUBSTEPS} substeps): compile "
        f"{first - run:.1f} s cold (first call {first:.1f} s minus a warm call {run:.1f} s); "
        f"{cached:.1f} s in a fresh process with the persistent compilation cache filled (trace + cache load)."
    )
    say("")
    say("| B | native steps/s | MJX steps/s | MJX / native | max tip gap MJX vs native |")
    say("|---|---|---|---|---|")
    for b in (int(x) for x in args.batches.split(",")):
        u = pool[np.arange(b) % len(pool)]
        t0 = time.perf_counter()
        ref = sim.rollout(u, engine="native")
        native = b * physics_steps / (time.perf_counter() - t0)
        t0 = time.perf_counter()
        got = trunk_mjx.rollout_mjx(u, True, chunk=args.chunk)
        mjx = b * physics_steps / (time.perf_counter() - t0)
        gap = float(np.linalg.norm(got.tip - ref.tip, axis=-1).max())
        say(f"| {b} | {native:,.0f} | {mjx:,.0f} | {mjx / native:.3f}x | {1e3 * gap:.2f} mm |")
    say("")
    say(
        f"{bench_sample.cpu_model()} ({bench_sample.cpu_isa()}), {os.cpu_count()} CPU cores, XLA_FLAGS="
        f"{os.environ.get('XLA_FLAGS', '')!r}, jax {jax.__version__}, MuJoCo {mujoco.__version__}, load average "
        f"{os.getloadavg()[0]:.2f}; native = mujoco.rollout, one thread per "
        f"core; MJX = jax on CPU, float32, every batch run as padded chunks of {args.chunk} (so B = 64 does a chunk's "
        "work: one compiled program serves every B). Commands: library trajectories, repeated to fill B."
    )
    ablation_throughput(pool, say)
    screening_latency(say)
    write_atomic(ROOT / "results" / "bench_trunk.md", "\n".join(lines) + "\n")
    return 0


def screening_latency(say, reps: int = 20) -> None:
    """Latency of screened sampling (``jg.sample(..., screen=True)``) beside plain ``jg.sample``, warm, median."""

    from jgrounding.policy import sampling

    say("")
    say(
        "| public call (warm, median of %d) | plain ms | screened ms | screened / plain | candidates simulated per "
        "call | rejected |" % reps
    )
    say("|---|---|---|---|---|---|")
    for k in (1, 8):
        args = ("nodding", "emphatic")
        for fn in (sampling.sample, lambda *a, **kw: sampling.screened(*a, **kw).u):
            fn(jax.random.key(0), *args, num_samples=k)  # compile / thread pool
        plain, screened, cands, rejected = [], [], 0, 0
        for i in range(reps):
            key = jax.random.key(i)
            t0 = time.perf_counter()
            sampling.sample(key, *args, num_samples=k)
            plain.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            res = sampling.screened(key, *args, num_samples=k)
            screened.append(time.perf_counter() - t0)
            cands, rejected = cands + res.candidates, rejected + res.rejected
        p, s = 1e3 * np.median(plain), 1e3 * np.median(screened)
        say(
            f"| jg.sample(key, {args[0]!r}, {args[1]!r}, num_samples={k}) | {p:.2f} | {s:.2f} | {s / p:.0f}x | "
            f"{cands / reps:.1f} | {rejected / reps:.2f} |"
        )
    say(
        "Screened: candidates drawn, rolled out in one batch (engine auto), infeasible ones dropped and redrawn; "
        "the cost is the simulation of 5 s of motion per candidate."
    )


def ablation_rollouts(
    per_tuple: int | None = None,
    seeds: int = 5,
    deterministic: int = 3,
    generative: int = 3,
    candidates: int | None = None,
    library: int = 256,
    references: int = 3 * 64,
) -> int:
    """Distinct trajectories ``make ablation`` simulates with its defaults: the first ``per_tuple`` samples of each
    tuple of the generative rows (DDPM, RF, physics-aware RF; default ``EvalConfig.physics_samples`` of K_div), one
    per tuple for the deterministic CNNs (their copies are identical and simulated once), the physics-aware
    fine-tuning's screened candidates, the library once (held-out references and the shape tolerance) and the
    reference rows."""
    from jgrounding.config import EvalConfig, PhysicsConfig

    if per_tuple is None:
        ev = EvalConfig()
        per_tuple = min(ev.physics_samples, ev.num_samples)
    if candidates is None:
        cfg = PhysicsConfig()
        candidates = cfg.rounds * 64 * cfg.candidates
    return seeds * (64 * (deterministic + generative * per_tuple) + candidates) + library + references


def ablation_throughput(pool, say, k_div: int = 30) -> None:
    """Simulated trajectories/s for the ablation's batch on each engine, and physics' share of the ablation."""
    from experiments import ablation_result

    batch = 64 * k_div
    u = pool[np.arange(batch) % len(pool)].reshape(64, k_div, 150, 4).copy()
    u += np.random.default_rng(0).uniform(0, 1e-4, u.shape) * (u < 1 - 1e-4)  # distinct: no rollout is deduplicated
    ref = sim.rollout(pool[:64]).backbone
    say("")
    say(
        f"Physics columns of the ablation: one batch = K_div x 64 = {batch:,} trajectories per method and seed "
        f'(engine "auto" picks {sim.resolve_engine("auto")} on this machine).'
    )
    say("")
    say(f"| engine | trajectories/s | s per batch of {batch:,} |")
    say("|---|---|---|")
    rate = {}
    for engine in ("native", "mjx"):
        physics.simulate_samples(u[:, :16], ref, 0.1, engine=engine)  # warm: one full chunk (MJX compiles it)
        res = physics.simulate_samples(u, ref, 0.1, engine=engine)
        rate[engine] = res["simulated"] / res["seconds"]
        say(f"| {engine} | {rate[engine]:,.0f} | {res['seconds']:.1f} |")
    auto = rate[sim.resolve_engine("auto")]
    n = ablation_rollouts()
    say("")
    say(f"make ablation (defaults) simulates {n:,} distinct trajectories: {n / auto:.0f} s at the auto engine's rate.")
    try:
        last = ablation_result.load(ROOT / "results")
    except (FileNotFoundError, ValueError) as e:
        say(f"No last ablation run to compare with: {e}")
        return
    t = last.timing
    say(
        f"Last ablation run (results/ablation.json, {last.date}): physics {t.physics_s:.0f} s of "
        f"{t.run_s:.0f} s ({100 * t.physics_s / t.run_s:.0f}%), engine {last.physics_engine}."
    )


if __name__ == "__main__":
    raise SystemExit(main())
