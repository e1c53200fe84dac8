"""The one latency measurement (SPEC §6, Time): what users call, warm, median over calls.

- :func:`latency_ms` is Table II's Time and what the sweeps and ``bench sample`` report: a
  tuple-conditioned method is timed through the public path, :meth:`jgrounding.generators.sampling.Model.sample`
  (the function ``jg.sample`` runs after its cached checkpoint lookup), one trajectory per call, keys
  made before the clock. A raw-text-conditioned method (``jg.sample`` takes tuples, not text) is timed
  through the compiled core and :func:`measures` says so.
- :func:`core_ms` is the compiled core alone (inputs on the device before the clock, no host work):
  the internal figure reported only beside the public one.
- :func:`batch_ms` times one public call for many trajectories.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding.generators import methods, sampling

PUBLIC = "jg.sample (public path: validation, compiled sampler, safety gate, numpy result)"
CORE = "compiled core (raw text condition: jg.sample takes tuples; inputs on the device, no host work)"


def _median_ms(call, args_list) -> float:
    jax.block_until_ready(call(*args_list[0]))  # compile / warm
    times = []
    for args in args_list:
        t0 = time.perf_counter()
        jax.block_until_ready(call(*args))
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def model_of(trained: methods.Trained, guidance: float = 0.0) -> sampling.Model:
    """The public sampler of a trained method (seed 0), as ``jg.sample(checkpoint=...)`` builds it."""
    from jgrounding import semantics

    return sampling.Model(
        trained, semantics.intent_embeddings(), name=f"{trained.method} (in memory)", guidance=guidance
    )


def measures(trained: methods.Trained) -> str:
    """What :func:`latency_ms` times for ``trained``."""
    return CORE if methods.spec(trained.method).condition == "raw" else PUBLIC


def public_ms(
    model: sampling.Model,
    intent,
    intensity,
    key,
    *,
    sampler: str | None = None,
    steps: int = 50,
    num_samples: int = 1,
    reps: int = 200,
) -> float:
    """Median warm wall time (ms) of ``model.sample(key_i, intent[i % N], intensity[i % N], num_samples)``
    over ``reps`` calls; ``intent``, ``intensity``: index arrays ``(N,)``."""
    n = len(intent)
    keys = list(jax.random.split(key, reps))
    calls = [(keys[i], int(intent[i % n]), int(intensity[i % n])) for i in range(reps)]
    return _median_ms(lambda k, m, z: model.sample(k, m, z, num_samples, sampler=sampler, steps=steps), calls)


def jg_sample_ms(intent, intensity, key, *, steps: int = 50, reps: int = 200) -> float:
    """Median warm wall time (ms) of ``jg.sample(key_i, intent[i % N], intensity[i % N], steps=steps)`` itself,
    the shipped-model routing and checkpoint-cache lookup included; ``intent``, ``intensity``: ``(N,)`` indices."""
    n = len(intent)
    keys = list(jax.random.split(key, reps))
    calls = [(keys[i], int(intent[i % n]), int(intensity[i % n])) for i in range(reps)]
    return _median_ms(lambda k, m, z: sampling.sample(k, m, z, steps=steps), calls)


def batch_ms(
    model: sampling.Model,
    intent,
    intensity,
    key,
    *,
    num_samples: int = 30,
    sampler: str | None = None,
    steps: int = 50,
    reps: int = 5,
) -> float:
    """Median warm wall time (ms) of one public call for ``N x num_samples`` trajectories."""
    keys = [(k,) for k in jax.random.split(key, reps)]
    return _median_ms(
        lambda k: model.sample(k, list(intent), list(intensity), num_samples, sampler=sampler, steps=steps), keys
    )


def core_fn(trained: methods.Trained, *, sampler: str = "euler", steps: int = 50, guidance: float = 0.0):
    """Compiled ``(cond (B, 384), intensity (B,), key) -> u (B, 150, N_u)``, gated, seed 0's parameters
    as constants, no seed axis."""
    params = jax.tree.map(lambda x: x[0], trained.params)

    @jax.jit
    def fn(cond, intensity, key):
        return methods.sample_one(
            trained.method,
            trained.graphdef,
            params,
            cond,
            intensity,
            key,
            sampler=sampler,
            steps=steps,
            num_controls=trained.num_controls,
            num_tendons=trained.num_tendons,
            guidance=guidance,
        )

    return fn


def core_ms(
    trained: methods.Trained,
    cond,
    intensity,
    key,
    *,
    sampler: str = "euler",
    steps: int = 50,
    batch: int = 1,
    reps: int = 200,
    guidance: float = 0.0,
) -> float:
    """Median warm wall time (ms) of the compiled core for ``batch`` trajectories per call, cycling through
    ``cond (N, 384)``, ``intensity (N,)``; inputs and keys on the device before the clock."""
    fn = core_fn(trained, sampler=sampler, steps=steps, guidance=guidance)
    n = len(cond)
    keys = jax.random.split(key, reps)
    rows = [np.arange(i * batch, (i + 1) * batch) % n for i in range(reps)]
    calls = [
        (jnp.asarray(cond[r], jnp.float32), jnp.asarray(intensity[r], jnp.int32), keys[i]) for i, r in enumerate(rows)
    ]
    return _median_ms(fn, calls)


def latency_ms(
    trained: methods.Trained,
    intent,
    intensity,
    key,
    *,
    cond=None,
    sampler: str | None = None,
    steps: int = 50,
    reps: int = 200,
    guidance: float = 0.0,
) -> float:
    """Table II's Time: median warm single-trajectory grounding (tuple -> u, spline reconstruction and
    safety gate included), cycling through the tuples ``intent``, ``intensity`` ``(N,)``.

    Tuple conditioning: the public path (:func:`public_ms` on :func:`model_of`). Raw conditioning: the
    compiled core on the text embeddings ``cond (N, 384)`` (:func:`measures` says which).
    """
    if methods.spec(trained.method).condition == "raw":
        if cond is None:
            raise ValueError(f"{trained.method} is conditioned on text: pass its embeddings as cond (N, 384)")
        return core_ms(
            trained, cond, intensity, key, sampler=sampler or "euler", steps=steps, reps=reps, guidance=guidance
        )
    return public_ms(model_of(trained, guidance), intent, intensity, key, sampler=sampler, steps=steps, reps=reps)
