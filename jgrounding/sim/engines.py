"""Which MJX implementation ``engine="auto"`` runs on an accelerator: the one of higher measured throughput.

:func:`fastest` rolls the same batch (``MJX_CHUNK`` trunks, 150 control steps) through every MJX implementation
that can run on the device (``"mjx"``; ``"mjx-warp"`` where Warp can, :func:`jgrounding.sim.mjx.warp_unavailable`),
timing a second call after a first that compiles, and keeps the faster. The programs are the ones the ablation and
screening then run, so the measurement costs their compile once. The choice is stored per device kind and stack
in ``engine_choice.json`` in the machine's cache (:func:`jgrounding.io.cache_dir`; ``JGROUNDING_CACHE=off``
measures every process), and said once on stderr with both rates. On the CPU ``"auto"`` is native MuJoCo,
measured faster than both MJX implementations by ``python -m experiments.bench trunk``.
"""

from __future__ import annotations

import functools
import json
import sys
import time

import numpy as np

from jgrounding import io

CHOICE_FILE = "engine_choice.json"


def probe_commands(batch: int, steps: int = 150) -> np.ndarray:
    """A deterministic batch of smooth commands in [0, 1] ``(batch, steps, 4)``: each trunk bends toward its own
    side and back (a half sine per tendon, phases spread over the batch), so contacts and tendons are exercised."""
    t = np.linspace(0.0, 1.0, steps)[None, :, None]
    phase = np.linspace(0.0, 2 * np.pi, batch, endpoint=False)[:, None, None] + np.arange(4)[None, None] * np.pi / 2
    return 0.5 + 0.45 * np.sin(np.pi * t) * np.cos(phase)


def measure(engines_: tuple[str, ...], batch: int, steps: int = 150) -> dict[str, float]:
    """Trajectories per second of each engine on :func:`probe_commands`, the second of two calls (the first
    compiles, or loads from the persistent compilation cache)."""
    from jgrounding import sim

    u = probe_commands(batch, steps)
    rates = {}
    for engine in engines_:
        sim.rollout(u, engine=engine)
        t0 = time.perf_counter()
        sim.rollout(u, engine=engine)
        rates[engine] = batch / (time.perf_counter() - t0)
    return rates


def _key() -> str:
    import jax
    import mujoco

    kinds = ",".join(sorted({d.device_kind for d in jax.devices()}))
    return f"{jax.default_backend()}:{kinds}|jax {jax.__version__}|mujoco {mujoco.__version__}"


@functools.lru_cache(maxsize=1)
def fastest() -> str:
    """``"mjx"`` or ``"mjx-warp"``, whichever rolls out the ablation's chunk faster on this device (cached)."""
    from jgrounding.sim import MJX_CHUNK
    from jgrounding.sim import mjx as trunk_mjx

    key, folder = _key(), io.cache_dir()
    path = folder / CHOICE_FILE if folder else None
    stored = json.loads(path.read_text()) if path and path.exists() else {}
    if key in stored:
        return stored[key]["engine"]
    why_not = trunk_mjx.warp_unavailable()
    candidates = ("mjx",) if why_not else ("mjx", "mjx-warp")
    rates = measure(candidates, MJX_CHUNK) if len(candidates) > 1 else {"mjx": float("nan")}
    choice = max(candidates, key=lambda e: rates[e])
    said = ", ".join(f"{e} {r:,.0f} trajectories/s" for e, r in rates.items() if np.isfinite(r))
    print(
        f'engine "auto" on {key}: {choice}' + (f" ({said}; measured once)" if said else f" (mjx-warp: {why_not})"),
        file=sys.stderr,
    )
    if path:
        io.write_atomic(path, json.dumps({**stored, key: {"engine": choice, "rates": rates}}, indent=1))
    return choice
