"""Does a re-run give the same numbers? ``python -m experiments.reproducibility [--steps N] [--seeds 0,1]``.

Trains the methods whose Table II numbers moved between two clones (the dense CNNs) and the RF, each in a fresh
process under four settings: the default twice (the same machine and threads: run-to-run), XLA's CPU backend
on one thread (``--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1``: another thread count),
and XLA told to emit AVX2 code only (``--xla_cpu_max_isa=AVX2``: what a CPU without AVX-512 runs, as the
machine that re-ran ``make ablation``). Every run prints a digest of its trained parameters and the paper-protocol
success of its samples; the script reports which runs agree bit for bit and the spread of the success between
settings. Writes results/reproducibility.{md,json}.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from jgrounding.io import write_atomic

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("raw_dense_cnn", "tuple_dense_cnn", "tuple_spline_rf")
SINGLE_THREAD = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
AVX2 = "--xla_cpu_max_isa=AVX2"  # the code XLA emits for a CPU without AVX-512 (e.g. a 2-core EPYC without AVX-512)
SETTINGS = (
    ("default", ""),
    ("default, again", ""),
    ("one XLA CPU thread", SINGLE_THREAD),
    ("AVX2 code (no AVX-512)", AVX2),
)

WORKER = r"""
import hashlib, json, sys
import jax, numpy as np
from jgrounding import config as configs, load_library, semantics
from jgrounding.evaluation import generate, metrics
from jgrounding.generators import methods
from jgrounding.training import trainer

method, steps, seeds = sys.argv[1], int(sys.argv[2]), tuple(int(s) for s in sys.argv[3].split(","))
lib = load_library()
emb = semantics.intent_embeddings()
entry = methods.spec(method)
text = None
if entry.condition.needs_text:
    text = semantics.embed([t for row in lib.train.texts for t in row]).reshape(len(lib.train), -1, 384)
    held = semantics.embed([row[0] for row in lib.heldout.texts])
cfg = configs.get("paper", [f"train.steps={steps}", "train.chunk=500"])
tr = trainer.fit(method, lib, seeds, cfg.train, intent_emb=emb, text_emb=text, progress=False)
h = hashlib.sha256()
for leaf in jax.tree.leaves(tr.params):
    h.update(np.ascontiguousarray(np.asarray(leaf)).tobytes())
cond = entry.condition.conditions(lib.heldout, emb, held if text is not None else None)
u = generate.generate(tr, cond, lib.heldout.intensity, jax.random.key(1), num_samples=1)
r = np.asarray(metrics.rms(u, lib.heldout.u[None, :, None]))[:, :, 0]
print("RESULT " + json.dumps({"digest": h.hexdigest(), "success": (r <= metrics.TAU_RMS).mean(1).tolist()}))
"""


def run_one(method: str, steps: int, seeds: str, xla_flags: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "JAX_PLATFORMS": "cpu"}
    env["XLA_FLAGS"] = " ".join(x for x in (os.environ.get("XLA_FLAGS", ""), xla_flags) if x)
    t0 = time.perf_counter()
    p = subprocess.run(
        [sys.executable, "-c", WORKER, method, str(steps), seeds], cwd=ROOT, env=env, capture_output=True, text=True
    )
    if p.returncode:
        raise SystemExit(f"{method} ({xla_flags or 'default'}) failed:\n{p.stderr[-3000:]}")
    out = json.loads(next(line for line in p.stdout.splitlines() if line.startswith("RESULT "))[7:])
    return {**out, "seconds": time.perf_counter() - t0}


def stack() -> str:
    """The versions a run trained on: jax, flax, optax and MuJoCo."""
    import flax
    import jax
    import mujoco
    import optax

    return f"jax {jax.__version__}, flax {flax.__version__}, optax {optax.__version__}, MuJoCo {mujoco.__version__}"


def render(res: dict) -> str:
    """results/reproducibility.md of a run: every run's digest and success, then per method what differs from
    its default run, and the summary across methods."""
    lines = [
        f"Reproducibility: each method trained {res['steps']} steps (seeds {res['seeds']}) in a fresh process per "
        f"setting on {res['cpu_count']} cores ({res.get('cpu_isa', '?')}; {res.get('stack', 'stack not recorded')}); "
        "success = one sample per held-out tuple "
        "within tau of its reference (the paper's protocol).",
        "",
        "| Method | setting | parameter digest | success per seed | seconds |",
        "|---|---|---|---|---|",
    ]
    verdicts, spreads = [], []
    for method, runs in res["runs"].items():
        for label, r in runs.items():
            lines.append(
                f"| {method} | {label} | {r['digest'][:12]} | {', '.join(f'{x:.3f}' for x in r['success'])} | "
                f"{r['seconds']:.0f} |"
            )
        base, parts = runs["default"], []
        for label, r in runs.items():
            if label == "default":
                continue
            diff = np.subtract(r["success"], base["success"])
            spreads += [abs(float(d)) for d in diff]
            same = r["digest"] == base["digest"]
            parts.append(
                f"{label}: {'bit-identical' if same else 'different parameters'}"
                + ("" if same else f" (success per seed {', '.join(f'{d:+.3f}' for d in diff)})")
            )
        verdicts.append(f"{method} against its default run: " + "; ".join(parts) + ".")
    lines += ["", *[f"- {v}" for v in verdicts]]
    lines.append(
        f"- Largest success difference between any setting and the default run: {max(spreads):.3f} (one sample of "
        "each of 64 tuples: one tuple is 0.016)."
    )
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--steps", type=int, default=10_000, help="training steps per run (Table I)")
    p.add_argument("--seeds", default="0,1", help="comma-separated seeds trained together (vmap)")
    p.add_argument("--out", default="results")
    p.add_argument("--render", action="store_true", help="only rewrite <out>/reproducibility.md from its .json")
    args = p.parse_args(argv)
    out = Path(args.out)
    if args.render:
        res = json.loads((out / "reproducibility.json").read_text())
    else:
        from experiments.ablation import environment

        res = {"steps": args.steps, "seeds": args.seeds, "cpu_count": os.cpu_count(), "runs": {}}
        res["cpu_isa"] = environment().cpu_isa
        res["stack"] = stack()
        for method in METHODS:
            res["runs"][method] = {}
            for label, flags in SETTINGS:
                r = res["runs"][method][label] = run_one(method, args.steps, args.seeds, flags)
                print(f"{method} | {label} | {r['digest'][:12]} | {r['success']} | {r['seconds']:.0f} s", flush=True)
        write_atomic(out / "reproducibility.json", json.dumps(res, indent=1))
    text = render(res)
    write_atomic(out / "reproducibility.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
