"""Fuzzing the public sampler at scale: ``python -m experiments.bench fuzz [--trajectories 1000000]``.

Random calls of ``jg.sample`` — random (intent, intensity) sequences in every accepted form (names in
any case and separator, indices, numpy integers, a single value repeated), random keys (typed, raw,
extreme key words), random ``num_samples`` and sampler settings — until at least ``--trajectories``
trajectories came back. Every one must have the right shape and be finite, inside [0, 1] and
slew-limited; the counts are printed (and written to results/bench_fuzz.md).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np

import jgrounding as jg
from jgrounding import safety
from jgrounding.io import write_atomic

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = (
    ("euler", 50),
    ("euler", 1),
    ("euler", 2),
    ("euler", 4),
    ("midpoint", 2),
    ("midpoint", 4),
    ("rk4", 1),
    ("rk4", 2),
    ("euler", 8),
)
WORDS = (0, 1, 2**31, 2**32 - 1)


def _value(rng: np.random.Generator, names: tuple[str, ...]):
    i = int(rng.integers(len(names)))
    form = rng.integers(4)
    if form == 0:
        return names[i]
    if form == 1:
        return f"  {names[i].upper().replace('_', '-')} "
    return i if form == 2 else np.int64(i)


def _key(rng: np.random.Generator):
    kind = rng.integers(3)
    seed = int(rng.integers(2**32))
    if kind == 0:
        return jax.random.key(seed)
    if kind == 1:
        return jax.random.PRNGKey(seed)
    words = [WORDS[rng.integers(4)] if rng.random() < 0.5 else int(rng.integers(2**32)) for _ in range(2)]
    return np.array(words, np.uint32)


def _bad(u: np.ndarray) -> int:
    """Trajectories ``(..., 150, N_u)`` that are non-finite, out of [0, 1] or exceed the slew bound."""
    flat = u.reshape(-1, *u.shape[-2:])
    ok = np.isfinite(flat).all(axis=(1, 2))
    ok &= (flat.min(axis=(1, 2)) >= safety.ACTUATION_MIN) & (flat.max(axis=(1, 2)) <= safety.ACTUATION_MAX)
    ok &= np.abs(np.diff(flat, axis=1)).max(axis=(1, 2)) <= safety.MAX_SLEW + 1e-6
    return int((~ok).sum())


def fuzz(seed: int, trajectories: int, max_per_call: int = 4096, progress: bool = False) -> dict:
    """Random public calls until ``trajectories`` came back; returns the counts (``bad`` must be 0)."""
    rng = np.random.default_rng(seed)
    counts = {"calls": 0, "trajectories": 0, "bad": 0, "configs": set()}
    while counts["trajectories"] < trajectories:
        sampler, steps = CONFIGS[rng.integers(len(CONFIGS))]
        k = int(rng.integers(1, 65)) if rng.random() < 0.8 else int(rng.integers(1, max_per_call + 1))
        if rng.random() < 0.3:  # one tuple
            intent, intensity, n = _value(rng, jg.INTENTS), _value(rng, jg.INTENSITIES), 1
            shape = (150, 4) if k == 1 else (k, 150, 4)
        else:
            n = int(rng.integers(1, max(2, max_per_call // k) + 1))
            intent = [_value(rng, jg.INTENTS) for _ in range(n)] if rng.random() < 0.9 else _value(rng, jg.INTENTS)
            intensity = (
                [_value(rng, jg.INTENSITIES) for _ in range(n)]
                if rng.random() < 0.9 or not isinstance(intent, list)
                else _value(rng, jg.INTENSITIES)
            )
            shape = (n, k, 150, 4)
        u = jg.sample(_key(rng), intent, intensity, num_samples=k, sampler=sampler, steps=steps)
        if u.shape != shape or u.dtype != np.float32:
            raise AssertionError(f"shape {u.shape} / dtype {u.dtype}, expected {shape} float32")
        counts["bad"] += _bad(u)
        counts["calls"] += 1
        counts["trajectories"] += n * k
        counts["configs"].add((sampler, steps))
        if progress and counts["trajectories"] // 100_000 > (counts["trajectories"] - n * k) // 100_000:
            print(f"  {counts['trajectories']:,} trajectories, {counts['bad']} bad", flush=True)
    return counts


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--trajectories", type=int, default=1_000_000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    c = fuzz(args.seed, args.trajectories, progress=True)
    dt = time.perf_counter() - t0
    text = (
        f"Fuzzed jg.sample: {c['calls']:,} random calls, {c['trajectories']:,} trajectories "
        f"({len(c['configs'])} sampler settings, seed {args.seed}) in {dt:.0f} s: {c['bad']} out of bounds, "
        f"non-finite or over the slew bound."
    )
    print(text)
    write_atomic(ROOT / "results" / "bench_fuzz.md", text + "\n")
    return 1 if c["bad"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
