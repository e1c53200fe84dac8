"""How ``python -m experiments.ablation`` scores a method: its samples on the held-out tuples with the paper's
metrics and latency (:func:`evaluate`), the distribution rows and the shipped model's public rows, the coverage of
the realizations, the physics columns on the trunk (:func:`physics`) and the references (oracle, wrong intent,
tuple mean)."""

from __future__ import annotations

import dataclasses
import time

import jax
import numpy as np

from experiments.ablation_report import (
    BRACKETS,
)
from experiments.ablation_result import NO_PHYSICS, Physics, Reference, Scores
from jgrounding import library
from jgrounding.config import Config
from jgrounding.evaluation import distribution, generate, latency, metrics
from jgrounding.evaluation import physics as trunk_eval

TIME_ROUNDS = 10  # Table II's Time: interleaved rounds (latency.interleaved_ms), each ...
TIME_REPS = 40  # ... TIME_REPS single-trajectory calls per method, cycling through the held-out tuples


def mean_std(x) -> tuple[float, float]:
    """Mean and sample std over seeds (ddof = 1)."""
    return distribution.mean_std(x)


def distribution_row(u, intent, intensity, ev, r) -> Scores:
    """Benchmark v3 metrics of ``u (S, N, K, T, C)`` (S seeds or draws) against the evaluation set: per metric
    ``(mean, std)`` over S and the per-seed values (for tests between methods)."""
    per = [distribution.score(x, intent, intensity, ev, r=r).summary() for x in u]
    names = (*distribution.HEADLINE, "frechet", "prec_r_split")
    return Scores(
        mean_std={k: mean_std([p[k] for p in per]) for k in names},
        per_seed={k: tuple(float(p[k]) for p in per) for k in names},
        std_error={k: float(distribution.std_error([p[k] for p in per])) for k in names},
    )


def public_row(lib, cfg: Config, r, current, draws: int = 5) -> Scores:
    """The shipped model exactly as a user calls it: ``jg.sample(key, intents, intensities, num_samples=K,
    steps=S, current=...)`` over the 64 held-out tuples, ``draws`` keys; distribution metrics per draw."""
    from jgrounding.policy import sampling

    ho, ev = lib.heldout, lib.evaluation
    kwargs = {} if current == "default" else {"current": current}
    u = np.stack(
        [
            sampling.sample(
                jax.random.key(100 + d),
                list(ho.intent),
                list(ho.intensity),
                num_samples=cfg.eval.num_samples,
                steps=cfg.sample.steps,
                **kwargs,
            )
            for d in range(draws)
        ]
    )
    return distribution_row(u, ho.intent, ho.intensity, ev, r)


def samples(trained, lib, cfg, cond_eval, key, mesh=None) -> np.ndarray:
    """The K_div = ``cfg.eval.num_samples`` samples of every held-out tuple that :func:`evaluate` scores, ``u (S, 64,
    K, T, N_u)``: drawn with the first half of the method's ``key`` at ``cfg.sample.steps`` steps, so a checkpoint
    the ablation saved gives them again (``experiments.trunk_physics``)."""
    config = dataclasses.replace(trained.resolve(None), steps=cfg.sample.steps)
    k_gen = jax.random.split(key)[0]
    return generate.generate(
        trained, cond_eval, lib.heldout.intensity, k_gen, num_samples=cfg.eval.num_samples, config=config, mesh=mesh
    )


def evaluate(method, trained, lib, cfg, cond_eval, key, mesh=None):
    ho = lib.heldout
    k_lat = jax.random.split(key)[1]
    config = dataclasses.replace(trained.resolve(None), steps=cfg.sample.steps)
    samples(trained, lib, cfg, cond_eval, key, mesh)  # compile
    t0 = time.perf_counter()
    u = samples(trained, lib, cfg, cond_eval, key, mesh)
    batch_s = time.perf_counter() - t0
    r = np.asarray(metrics.rms(u, ho.u[None, :, None]))  # (S, 64, K)
    div = np.asarray(metrics.pairwise_diversity(u)).mean(axis=1)  # (S,)
    cov = coverage(u, lib)  # (S,)
    calls = latency.latency_calls(trained, ho.intent, ho.intensity, k_lat, config, cond=cond_eval, reps=TIME_REPS)
    return u, r, div, cov, calls, u.shape[0] * u.shape[1] * u.shape[2] / batch_s


def coverage(u, lib) -> np.ndarray:
    """Mean coverage RMS per seed of ``u (S, N, K, T, N_u)``; tuples may hold different numbers of
    realizations (an imported library), then one tuple at a time."""
    key = lambda s: s.intent * 4 + s.intensity  # noqa: E731
    every_key = np.concatenate([key(lib.train), key(lib.heldout)])
    if len({int((every_key == k).sum()) for k in key(lib.heldout)}) == 1:
        return np.asarray(metrics.coverage(u, metrics.tuple_realizations(lib)[None])).mean(axis=1)
    every = np.concatenate([lib.train.u, lib.heldout.u])
    return np.stack(
        [np.asarray(metrics.coverage(u[:, j], every[every_key == k][None])) for j, k in enumerate(key(lib.heldout))],
        axis=1,
    ).mean(axis=1)


def physics(u, ref, tol, engine="auto", per_tuple: int | None = None, trunk: str | None = None) -> Physics:
    """Samples ``u (S, 64, K, T, 4)`` (S seeds) simulated against the held-out references' simulated
    backbones ``ref (64, T, 11, 3)``: shape RMS, shape success (``<= tol.tau_m``), shape diversity and
    feasibility over the simulated samples, each mean ± std over seeds; plus the rollouts' count and seconds.
    ``per_tuple``: simulate the first that many of each tuple's K samples (i.i.d. draws: a random subset;
    ``EvalConfig.physics_samples``); None: all. ``trunk``: the MJCF simulated (``PhysicsConfig.trunk``)."""
    u = np.asarray(u)[:, :, :per_tuple] if per_tuple else u
    res = [trunk_eval.simulate_samples(x, ref, tol.tau_m, engine=engine, trunk=trunk) for x in u]
    return Physics(
        shape_rms_m=mean_std([r["shape_rms"].mean() for r in res]),
        shape_success=mean_std([r["shape_success"].mean() for r in res]),
        shape_diversity_m=mean_std([r["diversity"].mean() for r in res]),
        feasible=mean_std([r["feasible"].mean() for r in res]),
        simulated=int(sum(r["simulated"] for r in res)),
        samples=int(np.prod(u.shape[:3])),
        seconds=float(sum(r["seconds"] for r in res)),
        engine=res[0]["engine"],
    )


def references(
    lib, ev_cfg, ref_backbone, tol, simulate: bool, trunk: str | None = None
) -> tuple[dict[str, Reference], dict[str, Physics]]:
    """The paper-protocol references (replays over draws, the tuple mean, the library's brackets as expected
    values) and the physics of the replayed ones; a partial (imported) library lacks some."""
    refs = {
        name: Reference(success=ref["success"], rms=ref["rms"])
        for name, ref in metrics.reference_baselines(lib, seed=0, draws=max(len(ev_cfg.seeds), 5)).items()
    }
    rng = np.random.default_rng(0)
    ref_phys = {
        name: physics(metrics.replay(lib, name, rng)[None, :, None], ref_backbone, tol, ev_cfg.engine, trunk=trunk)
        if simulate
        else NO_PHYSICS
        for name in ("oracle", "wrong_intent_any_intensity")
        if name in refs
    }
    mean_u = metrics.tuple_mean(lib)
    r_mean = np.asarray(metrics.rms(mean_u, lib.heldout.u))
    refs["tuple_mean"] = Reference(
        success={float(t): (float((r_mean <= t).mean()), 0.0) for t in metrics.TAUS}, rms=(float(r_mean.mean()), 0.0)
    )
    ref_phys["tuple_mean"] = (
        physics(mean_u[None, :, None], ref_backbone, tol, ev_cfg.engine, trunk=trunk) if simulate else NO_PHYSICS
    )
    # Brackets of the benchmark (library.brackets): expected values over the library, no sampling.
    complete = len(lib.heldout) == 64 and len(lib.train) == 192  # an imported library may lack tuples
    brackets, dist = (library.brackets(lib, metrics.TAUS), library.bracket_distances(lib)) if complete else ({}, {})
    for name in BRACKETS if complete else ():
        refs[name] = Reference(
            success={t: (v, 0.0) for t, v in brackets[name].items()},
            rms=(float(np.mean([x.mean() for x in dist[name]])), 0.0),
        )
    return refs, ref_phys
