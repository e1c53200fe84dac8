"""Trunk physics throughput: MJX (jit(vmap(scan))) against native MuJoCo doing the same rollouts.

``python -m experiments.bench trunk [--batches 64,256,1920] [--chunk 256]`` prints the MJX compile
time separately, then env-steps/s (physics steps) for each batch size on both engines, as ratios.
MJX runs every batch as padded chunks of ``--chunk`` so one compiled program serves all sizes.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from jgrounding import load_library, trunk, trunk_mjx


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--batches", default="64,256,1920")
    p.add_argument("--chunk", type=int, default=256)
    args = p.parse_args(argv)
    trunk_mjx.enable_compilation_cache()
    lib = load_library()
    pool = np.concatenate([lib.train.u, lib.heldout.u])
    physics_steps = trunk.NUM_STEPS * trunk.SUBSTEPS
    t0 = time.perf_counter()
    trunk_mjx.rollout_mjx(pool[: args.chunk], True, chunk=args.chunk)
    compile_s = time.perf_counter() - t0
    print(f"MJX compile (+ first run) for chunk {args.chunk}: {compile_s:.1f} s "
          f"(persistent cache: {trunk_mjx.CACHE_DIR})")
    print(f"{'B':>6} {'native steps/s':>16} {'MJX steps/s':>14} {'MJX / native':>13}")
    for b in (int(x) for x in args.batches.split(",")):
        u = pool[np.arange(b) % len(pool)]
        t0 = time.perf_counter()
        trunk.rollout(u, engine="native")
        native = b * physics_steps / (time.perf_counter() - t0)
        t0 = time.perf_counter()
        trunk_mjx.rollout_mjx(u, True, chunk=args.chunk)
        mjx = b * physics_steps / (time.perf_counter() - t0)
        print(f"{b:>6} {native:>16,.0f} {mjx:>14,.0f} {mjx / native:>12.2f}x", flush=True)
    print(f"({os.cpu_count()} CPU cores; native = mujoco.rollout with one thread per core; "
          f"{trunk.SUBSTEPS} substeps x {trunk.NUM_STEPS} control steps per rollout)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
