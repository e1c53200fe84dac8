"""PyTorch peers timed beside ``jg.sample`` in the same run: ``make bench-peer``.

``python -m experiments.bench_peer [--python .venv-peer/bin/python]``: exports the shipped S = 50 model
(seed 0's parameters, its recorded guidance w, the intent embeddings and the Catmull-Rom basis), times
``jg.sample`` at S = 50 (one trajectory per call, and 64 held-out tuples x 30 = 1,920 per call), then runs
experiments/peer_torch.py in the separate PyTorch environment (eager, then ``torch.compile``: the same
network, precomputation and Euler sampler), then times ``jg.sample`` again, all one after the other on
this machine. A parity check runs the JAX and the PyTorch sampler from the same noise. The ratios go into
the peer block of results/bench_sample.md (between ``<!-- peer:start -->`` and ``<!-- peer:end -->``;
``python -m experiments.bench sample`` keeps the block). torch is never a dependency of the package.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from experiments.bench_sample import (
    BATCH,
    PEER_END,
    PEER_START,
    cpu_isa,
    cpu_model,
    flops_per_sample,
    matmul_gflops,
    median_s,
    network_ms,
)
from jgrounding import load_library
from jgrounding.actuation import splines
from jgrounding.evaluation import latency
from jgrounding.generators import flows
from jgrounding.io import write_atomic
from jgrounding.policy import sampling

ROOT = Path(__file__).resolve().parent.parent
STEPS = 50
GOALS = {"single": 7.0, "batch": 1.5}  # torch.compile / jg.sample at S = 50: the speed goals
SHARE_GOAL = 0.70  # jg.sample's achieved GFLOP/s at 1,920 over the machine's matmul rate on the same shapes


def export(model: sampling.Model, intent, intensity, path: Path, eps: np.ndarray) -> np.ndarray:
    """Write the arrays peer_torch.py rebuilds the model from; return JAX's u for ``eps`` (the parity check)."""
    tr = model.trained
    net = nnx.merge(tr.graphdef, jax.tree.map(lambda x: x[0], tr.params))
    k1 = np.asarray(net.l1.kernel.value)
    d, td = net.dim, net.time_dim
    arrays = {
        "intent_emb": model.intent_emb,
        "intensity_emb": np.asarray(net.cond.intensity.embedding.value),
        "w_x": k1[:d],
        "w_t": k1[d : d + td],
        "w_c": k1[d + td :],
        "b1": np.asarray(net.l1.bias.value),
        "basis": np.asarray(splines.basis(splines.NUM_STEPS, tr.num_controls), np.float32),
        "depth": np.int32(net.depth),
        "steps": np.int32(STEPS),
        "guidance": np.float32(model.guidance),
        "num_tendons": np.int32(tr.num_tendons),
        "intent": np.asarray(intent, np.int32),
        "intensity": np.asarray(intensity, np.int32),
        "per_tuple": np.int32(BATCH // len(intent)),
        "parity_eps": eps,
    }
    for i in range(2, net.depth + 1):
        layer = getattr(net, f"l{i}")
        arrays[f"w{i}"], arrays[f"b{i}"] = np.asarray(layer.kernel.value), np.asarray(layer.bias.value)
    np.savez(path, **{k: np.asarray(v) for k, v in arrays.items()})
    # The same computation in JAX from the same noise (what jg.sample runs, without the slew limit).
    b = eps.shape[0]
    cond = jnp.asarray(model.intent_emb[np.asarray(intent[:b])])
    ctx = net.context(cond, jnp.asarray(intensity[:b], jnp.int32))
    w = model.guidance
    both = jnp.concatenate([ctx, net.null_context(b)])

    def velocity(x, time_ctx):
        if not w:
            return net.velocity(x, time_ctx, ctx)
        v = net.velocity(jnp.concatenate([x, x]), time_ctx, both)
        return v[:b] + w * (v[:b] - v[b:])

    y = flows.rf_sample(velocity, jnp.asarray(eps), steps=STEPS, embed_time=net.time_context)
    c = (0.5 * (y + 1.0)).reshape(b, tr.num_tendons, tr.num_controls)
    return np.clip(np.asarray(splines.reconstruct(c)), 0.0, 1.0)


def jg_times(lib, reps: int, batch_reps: int) -> tuple[float, float]:
    ho = lib.heldout
    single = latency.jg_sample_ms(ho.intent, ho.intensity, jax.random.key(1), steps=STEPS, reps=reps)
    keys = iter(jax.random.split(jax.random.key(2), batch_reps + 1))
    batch = 1e3 * median_s(
        lambda: sampling.sample(next(keys), list(ho.intent), list(ho.intensity), BATCH // len(ho), steps=STEPS),
        batch_reps,
    )
    return single, batch


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--python", default=str(ROOT / ".venv-peer" / "bin" / "python"), help="the PyTorch environment")
    p.add_argument("--reps", type=int, default=200)
    p.add_argument("--batch-reps", type=int, default=5)
    p.add_argument(
        "--out",
        default=str(ROOT / "results" / "bench_sample.md"),
        help="the file whose peer block is written (e.g. another machine's or ISA's record beside the default)",
    )
    args = p.parse_args(argv)
    if not Path(args.python).exists():
        raise SystemExit(f"{args.python} not found: `make bench-peer` creates .venv-peer with CPU PyTorch")
    lib = load_library()
    ho = lib.heldout
    path = sampling.shipped_checkpoint(STEPS)
    model = sampling.model(None if path == sampling.DEFAULT_CHECKPOINT else path)
    load = os.getloadavg()[0]
    before = jg_times(lib, args.reps, args.batch_reps)
    print(f"jg.sample S={STEPS}: single {before[0]:.3f} ms, {BATCH}: {before[1]:.1f} ms", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        eps = np.asarray(jax.random.normal(jax.random.key(5), (4, model.trained.num_tendons * 4)), np.float32)
        u_jax = export(model, ho.intent, ho.intensity, Path(tmp) / "w.npz", eps)
        cmd = [args.python, str(ROOT / "experiments" / "peer_torch.py"), str(Path(tmp) / "w.npz")]
        cmd += [str(Path(tmp) / "out.json"), str(args.reps), str(args.batch_reps)]
        subprocess.run(cmd, check=True, env={**os.environ, "PYTHONPATH": ""})
        peer = json.loads((Path(tmp) / "out.json").read_text())
    after = jg_times(lib, args.reps, args.batch_reps)
    print(f"jg.sample S={STEPS} again: single {after[0]:.3f} ms, {BATCH}: {after[1]:.1f} ms", flush=True)
    floor = network_ms(model, STEPS, args.reps, lib)  # the network + spline alone: what no overhead cut goes below
    print(f"network + spline alone, S={STEPS}: {floor:.3f} ms", flush=True)
    parity = float(np.abs(np.asarray(peer["parity_u"]) - u_jax).max())
    single, batch = (before[0] + after[0]) / 2, (before[1] + after[1]) / 2
    rate = matmul_gflops(model, STEPS)  # the machine's JAX matmul rate on the network's shapes, measured now
    gflop = BATCH * flops_per_sample(model, STEPS) / 1e9
    achieved = gflop / (batch / 1e3)
    share = achieved / rate
    print(
        f"jg.sample {BATCH}: {gflop:.2f} GFLOP in {batch:.1f} ms = {achieved:.1f} GFLOP/s, {100 * share:.0f} % of the "
        f"matmul rate on the same shapes ({rate:.1f} GFLOP/s; goal >= {100 * SHARE_GOAL:.0f} %)",
        flush=True,
    )
    machine = (
        f"{os.cpu_count()} cores of {cpu_model()} ({cpu_isa()}; XLA_FLAGS={os.environ.get('XLA_FLAGS') or '(none)'}, "
        f"ATEN_CPU_CAPABILITY={os.environ.get('ATEN_CPU_CAPABILITY') or '(default)'})"
    )
    w = f", guidance w = {model.guidance:g} (2 rows per sample)" if model.guidance else ""
    rows = [
        ("`jg.sample` (before the peers)", before[0], before[1]),
        ("`jg.sample` (after the peers)", after[0], after[1]),
        (f"PyTorch {peer['torch']} eager", peer["eager_single_ms"], peer["eager_batch_ms"]),
        (f"PyTorch {peer['torch']} `torch.compile`", peer["compiled_single_ms"], peer["compiled_batch_ms"]),
    ]
    lines = [
        PEER_START,
        "",
        "### PyTorch peers, same run (`make bench-peer`, experiments/bench_peer.py)",
        "",
        f"S = {STEPS} Euler, {Path(model.name).name}{w}; one run, one after the other on {machine} (load "
        f"average {load:.2f} at the start, torch threads {peer['threads']}). PyTorch runs "
        f"the same network and precomputation from the exported weights (peer_torch.py; clamp only, no slew "
        f"limit); medians of {args.reps} single calls and {args.batch_reps} calls of {BATCH}. Parity: from the "
        f"same noise, JAX and PyTorch trajectories differ by at most {parity:.1e}. torch.compile took "
        f"{peer['compile_s']:.1f} s to compile both sizes.",
        "",
        f"| sampler | single | {BATCH} samples |",
        "|---|---|---|",
        *[f"| {name} | {s:.3f} ms | {b:.1f} ms |" for name, s, b in rows],
        "",
        f"| ratio (peer / jg.sample, jg.sample = mean of before and after) | single | {BATCH} | goal |",
        "|---|---|---|---|",
        f"| eager | {peer['eager_single_ms'] / single:.1f}x | {peer['eager_batch_ms'] / batch:.2f}x | |",
        f"| `torch.compile` | {peer['compiled_single_ms'] / single:.1f}x | {peer['compiled_batch_ms'] / batch:.2f}x "
        f"| >= {GOALS['single']:g}x single, >= {GOALS['batch']:g}x {BATCH} |",
        "",
        f"The matmul rate on the network's own shapes, measured in this run (`bench_sample.matmul_gflops`): "
        f"{rate:.1f} GFLOP/s. `jg.sample` at {BATCH}: {gflop:.2f} GFLOP in {batch:.1f} ms = {achieved:.1f} GFLOP/s, "
        f"**{100 * share:.0f} %** of it (goal >= {100 * SHARE_GOAL:.0f} %: "
        f"{'met' if share >= SHARE_GOAL else 'not met'}).",
        "",
        f"The single-sample goal needs `jg.sample` within {peer['compiled_single_ms'] / GOALS['single']:.3f} ms "
        f"(torch.compile / {GOALS['single']:g}). The network and spline of one trajectory alone (no gate, no host "
        f"work, inputs on the device, the runtime jg.sample uses; `bench_sample.network_ms`) took {floor:.3f} ms in "
        f"this run: torch.compile / network = {peer['compiled_single_ms'] / floor:.1f}x is the most any cut in the "
        "sampler's overhead could reach on this machine.",
        "",
        PEER_END,
    ]
    block = "\n".join(lines)
    print(block)
    out = Path(args.out)
    text = out.read_text() if out.exists() else ""
    if PEER_START in text and PEER_END in text:
        text = text[: text.index(PEER_START)] + block + text[text.index(PEER_END) + len(PEER_END) :]
    else:
        text = text.rstrip("\n") + "\n\n" + block + "\n"
    write_atomic(out, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
