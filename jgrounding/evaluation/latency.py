"""The one latency measurement (SPEC §6, Time): what users call, warm, median over calls.

- :func:`latency_ms` is what the sweeps and ``bench sample`` report, and Table II's Time is the same
  measurement taken for every method in alternation (:func:`interleaved_ms`, with an interval of the
  median, :func:`median_interval`, and a paired test, :func:`compare_ms`): a
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
    return _median_ms(*_public_calls(model, intent, intensity, key, config, num_samples, reps))


def _public_calls(model: sampling.Model, intent, intensity, key, config: SampleConfig, num_samples: int, reps: int):
    """``(call, args_list)`` that :func:`public_ms` times."""
    config = model.config(config.sampler, config.steps)
    return (lambda k, m, z: model.sample(k, m, z, num_samples, config)), _calls(intent, intensity, key, reps)


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
    return _median_ms(*_core_calls(trained, cond, intensity, key, config, batch, reps, like_public))


def _core_calls(trained: Trained, cond, intensity, key, config, batch: int, reps: int, like_public: bool = False):
    """``(compiled core, args_list)`` that :func:`core_ms` times."""
    n = len(cond)
    keys = jax.random.split(key, reps)
    rows = [np.arange(i * batch, (i + 1) * batch) % n for i in range(reps)]
    calls = [
        (jnp.asarray(cond[r], jnp.float32), jnp.asarray(intensity[r], jnp.int32), keys[i]) for i, r in enumerate(rows)
    ]
    return core_fn(trained, config, example=calls[0] if like_public else None), calls


def latency_calls(
    trained: Trained, intent, intensity, key, config: SampleConfig | None = None, *, cond=None, reps: int = 200
) -> tuple:
    """``(call, args_list)``: what :func:`latency_ms` times for ``trained``, one argument tuple per call
    (keys made before the clock); :func:`interleaved_ms` times several of these in alternation."""
    config = trained.resolve(config)
    if trained.spec.condition.needs_text:
        if cond is None:
            raise ValueError(f"{trained.method} is conditioned on text: pass its embeddings as cond (N, 384)")
        return _core_calls(trained, cond, intensity, key, config, batch=1, reps=reps)
    model = model_of(dataclasses.replace(trained, sample_config=config))
    return _public_calls(model, intent, intensity, key, config, num_samples=1, reps=reps)


def latency_ms(
    trained: Trained, intent, intensity, key, config: SampleConfig | None = None, *, cond=None, reps: int = 200
) -> float:
    """Table II's Time of one method on its own: median warm single-trajectory grounding (tuple -> u, spline
    reconstruction and safety gate included), cycling through the tuples ``intent``, ``intensity`` ``(N,)``;
    ``config`` default: the model's own sampling defaults. (The ablation times its methods together,
    interleaved: :func:`interleaved_ms`.)

    Tuple conditioning: the public path (:func:`public_ms` on :func:`model_of`). Raw conditioning: the
    compiled core on the text embeddings ``cond (N, 384)`` (:func:`measures` says which).
    """
    return _median_ms(*latency_calls(trained, intent, intensity, key, config, cond=cond, reps=reps))


def interleaved_ms(entries: dict, rounds: int = 10, seed: int = 0) -> dict[str, np.ndarray]:
    """Per-round medians (ms) of several timed calls measured in alternation, so that a slow spell of the
    machine falls on every entry alike: ``entries`` maps a name to ``(call, args_list)``
    (:func:`latency_calls`); every call is warmed first; then in each of ``rounds`` rounds every entry, in a
    fresh random order, runs all its calls and records their median. Returns ``name -> (rounds,)``."""
    rng = np.random.default_rng(seed)
    names = list(entries)
    for call, args_list in entries.values():
        jax.block_until_ready(call(*args_list[0]))  # compile / warm
    out = {name: [] for name in names}
    for _ in range(rounds):
        for i in rng.permutation(len(names)):
            call, args_list = entries[names[i]]
            times = []
            for args in args_list:
                t0 = time.perf_counter()
                jax.block_until_ready(call(*args))
                times.append(time.perf_counter() - t0)
            out[names[i]].append(1e3 * float(np.median(times)))
    return {name: np.asarray(v) for name, v in out.items()}


def _binom_cdf(k: int, n: int) -> float:
    """P(Bin(n, 1/2) <= k)."""
    from math import comb

    return sum(comb(n, i) for i in range(k + 1)) / 2.0**n


def median_interval(rounds_ms, level: float = 0.95) -> tuple[float, float, float]:
    """(median, low, high) of per-round times: the distribution-free interval of the median from order
    statistics (the widest rank pair whose binomial coverage is at least ``level``; with 10 rounds, the 2nd
    and 9th of the sorted values, 97.9 %); fewer than 6 rounds give the min and max."""
    x = np.sort(np.asarray(rounds_ms, float))
    n = len(x)
    if n == 0:
        raise ValueError("median_interval needs at least one round")
    k = 0  # [x[k], x[n-1-k]] covers the median with probability 1 - 2 P(Bin(n, 1/2) <= k): the largest such k
    while k + 1 < n / 2 and _binom_cdf(k + 1, n) <= (1 - level) / 2:
        k += 1
    return float(np.median(x)), float(x[k]), float(x[n - 1 - k])


def compare_ms(a_rounds, b_rounds, alpha: float = 0.05) -> dict:
    """Paired comparison of two entries of one :func:`interleaved_ms` run, round by round: the median ratio
    a / b, how many rounds a was faster, the exact two-sided sign test's p, and the verdict (``"faster"``,
    ``"slower"`` or ``"not distinguishable"`` at ``alpha``). Rounds of equal time are left out."""
    a, b = np.asarray(a_rounds, float), np.asarray(b_rounds, float)
    if a.shape != b.shape or a.ndim != 1 or len(a) == 0:
        raise ValueError(f"compare_ms needs two equal-length runs of rounds, got {a.shape} and {b.shape}")
    d = a - b
    faster, slower = int((d < 0).sum()), int((d > 0).sum())
    n = faster + slower
    p = 1.0 if n == 0 else min(1.0, 2.0 * _binom_cdf(min(faster, slower), n))
    verdict = "not distinguishable" if p >= alpha else ("faster" if faster > slower else "slower")
    return {"ratio": float(np.median(a / b)), "faster_rounds": faster, "rounds": len(a), "p": p, "verdict": verdict}
