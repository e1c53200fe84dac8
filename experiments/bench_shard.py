"""Sharded evaluation throughput: ``python -m experiments.bench shard`` (1 vs 4 devices, one run).

The shipped Tuple + Spline + RF checkpoint generates the 64 held-out tuples x 30 samples (1920
trajectories, Euler S = 50, one batch) through ``generate.generate(..., mesh=distributed.make_mesh())``:
the (condition x sample) batch is split over the mesh. On a CPU each device count runs in its own
process with ``XLA_FLAGS=--xla_force_host_platform_device_count=N`` (XLA fixes the count at start-up);
the forced host devices share the same cores, so no gain is expected on a small machine: the figure
shows that the sharded path runs and returns the same trajectories. ``--real`` instead measures this
machine's own devices (e.g. the GPUs of one node) in one process: a mesh of 1 device vs all of them.
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

ROOT = Path(__file__).resolve().parent.parent
NUM_SAMPLES = 30  # K_div of Table I


def measure(mesh_sizes, reps: int, dump: str | None = None) -> list[dict]:
    """Time ``evaluation.generate.generate`` over meshes of the given sizes in this process."""
    import jax
    import numpy as np

    from jgrounding import load_library
    from jgrounding.evaluation import generate
    from jgrounding.policy import sampling
    from jgrounding.training import distributed

    trained, emb = sampling.load()
    lib = load_library()
    cond, intensity = emb[lib.heldout.intent], lib.heldout.intensity
    total = len(cond) * NUM_SAMPLES
    rows = []
    for size in mesh_sizes:
        mesh = distributed.make_mesh(size)

        def run(i):
            return generate.generate(
                trained, cond, intensity, jax.random.key(i), num_samples=NUM_SAMPLES, batch=total, mesh=mesh
            )

        u = run(0)  # compile
        times = []
        for i in range(reps):
            t0 = time.perf_counter()
            run(i)
            times.append(time.perf_counter() - t0)
        dt = float(np.median(times))
        rows.append(
            {
                "devices": size,
                "platform": jax.devices()[0].platform,
                "trajectories": total,
                "seconds": dt,
                "per_s": total / dt,
            }
        )
        if dump:
            np.save(f"{dump}-{size}.npy", u)
    return rows


def _forced(devices: int, reps: int, dump: str) -> dict:
    env = {
        **os.environ,
        "JAX_PLATFORMS": "cpu",
        "PYTHONPATH": str(ROOT),
        "XLA_FLAGS": f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count={devices}".strip(),
    }
    cmd = [
        sys.executable,
        "-m",
        "experiments.bench_shard",
        "--worker",
        str(devices),
        "--reps",
        str(reps),
        "--dump",
        dump,
    ]
    out = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True)
    if out.returncode:
        raise RuntimeError(f"worker with {devices} device(s) failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])[0]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.bench shard", description=__doc__.split("\n")[0])
    p.add_argument("--devices", default="1,4", help="device counts to compare (default 1,4; the first is the base)")
    p.add_argument("--reps", type=int, default=5, help="timed repetitions per device count (median reported)")
    p.add_argument("--real", action="store_true", help="use this machine's own devices in one process")
    p.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    p.add_argument("--dump", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker:
        import jax

        if jax.device_count() != args.worker:
            raise SystemExit(f"expected {args.worker} devices, JAX sees {jax.device_count()}")
        print(json.dumps(measure([args.worker], args.reps, args.dump)))
        return 0
    try:
        counts = [int(c) for c in args.devices.split(",")]
    except ValueError:
        counts = []
    if not counts or min(counts) < 1 or args.reps < 1:
        p.error(f"--devices must be positive integers separated by commas and --reps >= 1, got {args.devices!r}")

    import numpy as np

    with tempfile.TemporaryDirectory() as tmp:
        dump = str(Path(tmp) / "u")
        if args.real:
            import jax

            counts = sorted({1, jax.device_count()}) if args.devices == "1,4" else counts
            rows = measure(counts, args.reps, dump)
        else:
            rows = [_forced(n, args.reps, dump) for n in counts]
        base_u = np.load(f"{dump}-{counts[0]}.npy")
        diffs = {n: float(np.abs(np.load(f"{dump}-{n}.npy") - base_u).max()) for n in counts}
    base = rows[0]["per_s"]
    kind = "own devices" if args.real else "forced host devices, one process each"
    lines = [
        f"Sharded evaluation ({kind}): 64 held-out tuples x {NUM_SAMPLES} samples, RF Euler S = 50, "
        f"shipped checkpoint; median of {args.reps}; load average {os.getloadavg()[0]:.2f} on "
        f"{os.cpu_count()} cores.",
        "",
        "| devices | platform | time per batch | trajectories/s | ratio vs 1st | max abs diff vs 1st |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['devices']} | {r['platform']} | {1e3 * r['seconds']:.1f} ms | {r['per_s']:,.0f} | "
        f"{r['per_s'] / base:.2f}x | {diffs[r['devices']]:.1e} |"
        for r in rows
    ]
    if not args.real:
        lines += [
            "",
            "Forced host devices share the same CPU cores, so no speed-up is expected here; the "
            "table shows the sharded path runs and matches the single-device trajectories.",
        ]
    text = "\n".join(lines)
    print(text)
    from jgrounding.io import write_atomic

    write_atomic(ROOT / "results" / "bench_shard.md", text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
