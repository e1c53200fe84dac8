"""The one latency measurement (SPEC §6, Time): what users call, warm, median over calls.

- :func:`latency_ms` is Table II's Time and what the sweeps and ``bench sample`` report: a
  tuple-conditioned method is timed through the public path, :meth:`jgrounding.policy.sampling.Model.sample`
  (the function ``jg.sample`` runs after its cached checkpoint lookup), one trajectory per call, keys
  made before the clock. A raw-text-conditioned method (``jg.sample`` takes tuples, not text) is timed
  through the compiled core and :func:`measures` says so.
- :func:`core_ms` is the compiled core alone (inputs on the device before the clock, no host work):
  the internal figure reported only beside the public one.
- :func:`batch_ms` times one public call for many trajectories.
"""

from __future__ import annotations

import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding.config import SampleConfig
from jgrounding.generators.trained import Trained
from jgrounding.policy import sampling

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


def model_of(trained: Trained) -> sampling.Model:
    """The public sampler of a trained method (seed 0, its own sampling defaults), as
    ``jg.sample(checkpoint=...)`` builds it."""
    from jgrounding import semantics

    return sampling.Model(trained, semantics.intent_embeddings(), name=f"{trained.method} (in memory)")


def measures(trained: Trained) -> str:
    """What :func:`latency_ms` times for ``trained``."""
    return CORE if trained.spec.condition.needs_text else PUBLIC


def _calls(intent, intensity, key, reps: int) -> list:
    """``reps`` (key, intent, intensity) calls cycling through the tuples, keys made before the clock."""
    n = len(intent)
    keys = list(jax.random.split(key, reps))
    return [(keys[i], int(intent[i % n]), int(intensity[i % n])) for i in range(reps)]


def public_ms(
    model: sampling.Model, intent, intensity, key, config: SampleConfig = SampleConfig(), *, num_samples=1, reps=200
) -> float:
    """Median warm wall time (ms) of ``model.sample(key_i, intent[i % N], intensity[i % N], num_samples)``
    with ``config``'s sampler and steps over ``reps`` calls; ``intent``, ``intensity``: index arrays ``(N,)``."""
    config = model.config(config.sampler, config.steps)
    calls = _calls(intent, intensity, key, reps)
    return _median_ms(lambda k, m, z: model.sample(k, m, z, num_samples, config), calls)


def jg_sample_ms(intent, intensity, key, *, steps: int = SampleConfig.steps, reps: int = 200) -> float:
    """Median warm wall time (ms) of ``jg.sample(key_i, intent[i % N], intensity[i % N], steps=steps)`` itself,
    the shipped-model routing and checkpoint-cache lookup included; ``intent``, ``intensity``: ``(N,)`` indices."""
    calls = _calls(intent, intensity, key, reps)
    return _median_ms(lambda k, m, z: sampling.sample(k, m, z, steps=steps), calls)


def batch_ms(
    model: sampling.Model, intent, intensity, key, config: SampleConfig = SampleConfig(), *, num_samples=30, reps=5
) -> float:
    """Median warm wall time (ms) of one public call for ``N x num_samples`` trajectories."""
    config, keys = model.config(config.sampler, config.steps), [(k,) for k in jax.random.split(key, reps)]
    return _median_ms(lambda k: model.sample(k, list(intent), list(intensity), num_samples, config), keys)


def core_fn(trained: Trained, config: SampleConfig | None = None, *, example: tuple | None = None):
    """Compiled ``(cond (B, 384), intensity (B,), key) -> u (B, 150, N_u)``, gated (:meth:`Trained.sample`),
    seed 0's parameters as constants, no seed axis; ``config`` default: the model's own. With ``example``
    (arguments of the shape it will get), compiled ahead of time with the XLA options ``jg.sample`` uses for
    that many trajectories (:func:`sampling.compile_for`), so the two run on the same runtime."""
    params = trained.seed_params(0)
    fn = jax.jit(lambda cond, intensity, key: trained.sample(key, cond, intensity, config, params=params))
    if example is None:
        return fn
    return sampling.compile_for(fn.lower(*example), len(example[0]))


def core_ms(
    trained: Trained,
    cond,
    intensity,
    key,
    config: SampleConfig | None = None,
    *,
    batch: int = 1,
    reps: int = 200,
    like_public: bool = False,
) -> float:
    """Median warm wall time (ms) of the compiled core for ``batch`` trajectories per call, cycling through
    ``cond (N, 384)``, ``intensity (N,)``; inputs and keys on the device before the clock. ``like_public``:
    compiled with the XLA options ``jg.sample`` uses for ``batch`` (the benchmark's public/core ratio)."""
    n = len(cond)
    keys = jax.random.split(key, reps)
    rows = [np.arange(i * batch, (i + 1) * batch) % n for i in range(reps)]
    calls = [
        (jnp.asarray(cond[r], jnp.float32), jnp.asarray(intensity[r], jnp.int32), keys[i]) for i, r in enumerate(rows)
    ]
    fn = core_fn(trained, config, example=calls[0] if like_public else None)
    return _median_ms(fn, calls)


def latency_ms(
    trained: Trained, intent, intensity, key, config: SampleConfig | None = None, *, cond=None, reps: int = 200
) -> float:
    """Table II's Time: median warm single-trajectory grounding (tuple -> u, spline reconstruction and
    safety gate included), cycling through the tuples ``intent``, ``intensity`` ``(N,)``; ``config`` default:
    the model's own sampling defaults.

    Tuple conditioning: the public path (:func:`public_ms` on :func:`model_of`). Raw conditioning: the
    compiled core on the text embeddings ``cond (N, 384)`` (:func:`measures` says which).
    """
    config = trained.resolve(config)
    if trained.spec.condition.needs_text:
        if cond is None:
            raise ValueError(f"{trained.method} is conditioned on text: pass its embeddings as cond (N, 384)")
        return core_ms(trained, cond, intensity, key, config, reps=reps)
    return public_ms(
        model_of(dataclasses.replace(trained, sample_config=config)), intent, intensity, key, config, reps=reps
    )
