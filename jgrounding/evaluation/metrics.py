"""Metrics of Sec. IV-A.3 (SPEC §6) and the reference baselines that bracket them.

- ``rms``: RMS_j = sqrt(mean over T and N_u of (u_hat - u_tar)^2), over the last two axes.
- ``success_rate``: fraction with RMS <= tau (tau_rms = 0.35).
- ``pairwise_diversity``: mean pairwise RMS of K samples (D_j); Div is its mean over held-out tuples.
- ``coverage``: mode coverage, the mean over a tuple's library realizations of the RMS to the nearest
  of K samples (beyond the paper: low when the samples reach every demonstrated variant, not one).
- ``reference_baselines``: the oracle (replay a random training realization of the same tuple: the
  success ceiling) and wrong-intent replays (the floor), plus adjacent-intensity confusion.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding.actuation import rms  # noqa: F401  (the one RMS distance, public here as Table II's metric)
from jgrounding.config import TAU_RMS

TAUS = (0.25, 0.30, 0.35, 0.40, 0.45)


def success_rate(rms_values, tau: float = TAU_RMS) -> jax.Array:
    """Fraction of RMS values <= tau, over the last axis."""
    return jnp.mean(jnp.asarray(rms_values) <= tau, axis=-1)


@jax.jit
def pairwise_diversity(samples) -> jax.Array:
    """Mean pairwise RMS of samples ``(..., K, T, N_u)`` -> ``(...)`` (D_j of the paper)."""
    k = samples.shape[-3]
    d = rms(samples[..., :, None, :, :], samples[..., None, :, :, :])  # (..., K, K)
    iu = np.triu_indices(k, 1)
    return jnp.mean(d[..., iu[0], iu[1]], axis=-1)


@jax.jit
def coverage(samples, realizations) -> jax.Array:
    """Mean over ``realizations (..., R, T, N_u)`` of the RMS to the nearest of ``samples (..., K, T, N_u)``."""
    d = rms(samples[..., :, None, :, :], realizations[..., None, :, :, :])  # (..., K, R)
    return jnp.mean(jnp.min(d, axis=-2), axis=-1)


def tuple_realizations(library) -> np.ndarray:
    """``(64, R, T, N_u)``: every library realization (train and held-out) of each held-out record's tuple."""
    u = np.concatenate([library.train.u, library.heldout.u])
    key = np.concatenate(
        [library.train.intent * 4 + library.train.intensity, library.heldout.intent * 4 + library.heldout.intensity]
    )
    ho = library.heldout.intent * 4 + library.heldout.intensity
    return np.stack([u[key == k] for k in ho])


def tuple_mean(library) -> np.ndarray:
    """``(64, T, N_u)``: per held-out record, the mean of its tuple's training realizations.

    The best a deterministic regressor can do under a squared loss, as a reference: with a tight
    library it is closer to the held-out target in RMS than any single replayed realization.
    """
    oracle = _pools(library)["oracle"]
    return np.stack([library.train.u[oracle(j)].mean(0) for j in range(len(library.heldout))])


def _pools(library) -> dict:
    """Reference name -> ``pool(j)``: the training records a replay for held-out record j draws from."""
    tr, ho = library.train, library.heldout
    return {
        "oracle": lambda j: np.flatnonzero((tr.intent == ho.intent[j]) & (tr.intensity == ho.intensity[j])),
        "wrong_intent_same_intensity": lambda j: np.flatnonzero(
            (tr.intent != ho.intent[j]) & (tr.intensity == ho.intensity[j])
        ),
        "wrong_intent_any_intensity": lambda j: np.flatnonzero(tr.intent != ho.intent[j]),
        "adjacent_intensity": lambda j: np.flatnonzero(
            (tr.intent == ho.intent[j]) & (np.abs(tr.intensity - ho.intensity[j]) == 1)
        ),
    }


def replay(library, name: str, rng: np.random.Generator) -> np.ndarray:
    """``(64, T, N_u)``: for each held-out record, the u of one training record of reference ``name``
    (a key of :func:`reference_baselines`' result), drawn with ``rng``."""
    pool = _pools(library)[name]
    out = np.empty_like(library.heldout.u)
    for j in range(len(library.heldout)):
        out[j] = library.train.u[rng.choice(pool(j))]
    return out


def reference_baselines(library, seed: int = 0, draws: int = 20, taus=TAUS) -> dict:
    """Success of replayed library trajectories against the held-out targets, mean and std over draws.

    ``oracle``: a training realization of the same tuple. ``wrong_intent_same_intensity`` /
    ``wrong_intent_any_intensity``: one of a different intent. ``adjacent_intensity``: the same intent
    one intensity level away. Returns ``{name: {"success": {tau: (mean, std)}, "rms": (mean, std)}}``;
    a reference is left out when some held-out record has nothing to replay for it.
    """
    ho = library.heldout
    rng = np.random.default_rng(seed)
    out = {}
    for name, pool in _pools(library).items():
        if any(len(pool(j)) == 0 for j in range(len(ho))):
            continue  # a partial (imported) library may lack the records this reference replays

        r = np.stack([np.asarray(rms(replay(library, name, rng), ho.u)) for _ in range(draws)])  # (draws, 64)
        out[name] = {
            "success": {float(t): (float((r <= t).mean(1).mean()), float((r <= t).mean(1).std())) for t in taus},
            "rms": (float(r.mean()), float(r.mean(1).std())),
        }
    return out


def within_between(library) -> dict[str, np.ndarray]:
    """All pairwise RMS distances among library records, grouped: within tuple, between intents at the
    same intensity, adjacent intensity of the same intent (for the library card's histogram)."""
    u = np.concatenate([library.train.u, library.heldout.u])
    m = np.concatenate([library.train.intent, library.heldout.intent])
    z = np.concatenate([library.train.intensity, library.heldout.intensity])
    d = np.asarray(jax.jit(lambda x: rms(x[:, None], x[None]))(u))
    iu = np.triu_indices(len(u), 1)
    d, mi, mj, zi, zj = d[iu], m[iu[0]], m[iu[1]], z[iu[0]], z[iu[1]]
    return {
        "within tuple": d[(mi == mj) & (zi == zj)],
        "different intent, same intensity": d[(mi != mj) & (zi == zj)],
        "same intent, adjacent intensity": d[(mi == mj) & (np.abs(zi - zj) == 1)],
    }


def ordering(success: dict[str, float], order) -> tuple[str, str]:
    """Compare success along a claimed ``order`` (worst to best): "holds" (strictly increasing),
    "ties" (non-decreasing with equal neighbours) or "does not hold"; plus the chain, e.g. ``a < b = c``."""
    vals = [success[m] for m in order]
    rel = ["<" if b > a + 1e-9 else "=" if abs(b - a) <= 1e-9 else ">" for a, b in zip(vals, vals[1:])]
    verdict = "holds" if all(r == "<" for r in rel) else "ties" if ">" not in rel else "does not hold"
    return verdict, " ".join(f"{v:.3f} {r}" for v, r in zip(vals, rel + [""])).strip()
