"""Physics metrics of generated samples: every sample simulated, compared in shape space.

Table II's physics columns (``experiments.ablation``) and the physics-aware training read these:

- **shape RMS** between two simulated motions: ``sqrt(mean over T and backbone points of |a - b|^2)``
  in metres (:func:`shape_rms`), the whole-body analogue of the actuation RMS of Sec. IV-A.3;
- **shape success**: fraction of samples whose shape RMS to the held-out reference's simulated motion
  is within ``tau_shape``, a tolerance calibrated from the library's own spread (:func:`calibrate`);
- **shape diversity**: mean pairwise shape RMS of a tuple's K samples (the analogue of Div.);
- **feasibility**: :func:`jgrounding.sim.feasible` (stable, contact force, tip speed near the user).

:func:`simulate_samples` rolls out a whole ``(N, K, 150, 4)`` batch through
:func:`jgrounding.sim.rollout` (``engine="auto"``), in chunks so memory stays bounded, and simulates
each distinct trajectory once: a deterministic generator's K samples are identical, so its 30
copies cost one rollout (exact, not an approximation).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from jgrounding import sim

CHUNK = sim.MJX_CHUNK  # trajectories per rollout call: ~40 MB of backbone in float64; one MJX chunk


def shape_rms(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Shape RMS (m) of backbones ``(..., T, P, 3)`` against ``(..., T, P, 3)`` -> ``(...)``."""
    return np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1), axis=(-2, -1)))


def pairwise_shape_rms(backbone: np.ndarray) -> np.ndarray:
    """``(..., K, T, P, 3)`` -> ``(..., K, K)`` shape RMS of every pair (Gram form: one matmul)."""
    x = backbone.reshape(backbone.shape[:-3] + (-1,)).astype(np.float64)
    n_points = backbone.shape[-3] * backbone.shape[-2]
    sq = np.sum(x * x, axis=-1)
    d2 = sq[..., :, None] + sq[..., None, :] - 2.0 * x @ np.swapaxes(x, -1, -2)
    return np.sqrt(np.maximum(d2, 0.0) / n_points)


def shape_diversity(backbone: np.ndarray) -> np.ndarray:
    """Mean pairwise shape RMS of ``(..., K, T, P, 3)`` samples -> ``(...)`` (0 for K = 1)."""
    k = backbone.shape[-4]
    if k < 2:
        return np.zeros(backbone.shape[:-4])
    d = pairwise_shape_rms(backbone)
    iu = np.triu_indices(k, 1)
    return d[..., iu[0], iu[1]].mean(axis=-1)


@dataclasses.dataclass(frozen=True)
class ShapeTolerance:
    """``tau_m``: the shape RMS at the same percentile of the library's pairwise shape distances as
    ``tau_rms`` is of its pairwise actuation distances; the rest documents the spread it came from."""

    tau_m: float
    tau_rms: float
    percentile: float  # % of library pairs with actuation RMS <= tau_rms
    within_tuple_median_m: float
    wrong_intent_median_m: float
    oracle_success: float  # within-tuple pairs inside tau_m
    wrong_intent_success: float  # different-intent pairs inside tau_m


def calibrate(
    u: np.ndarray, backbone: np.ndarray, intent: np.ndarray, intensity: np.ndarray, tau_rms: float
) -> ShapeTolerance:
    """Shape tolerance from the library's own spread (quantile matching of the two distances).

    Args:
      u: ``(N, T, 4)`` library actuation; backbone: ``(N, T, P, 3)`` its simulated motion;
      intent, intensity: ``(N,)`` labels; tau_rms: the actuation tolerance (0.35).
    Returns:
      :class:`ShapeTolerance`. Over all library pairs, the fraction q within ``tau_rms`` in actuation
      space fixes the percentile; ``tau_m`` is that percentile of the pairs' shape RMS. So a pair of
      library motions is "close" in shape exactly as often as it is close in actuation, and the shape
      column asks the same question as Table II's success, one stage later in the pipeline.
    """
    n = len(u)
    flat = u.reshape(n, -1).astype(np.float64)
    sq = np.sum(flat * flat, axis=1)
    act = np.sqrt(np.maximum(sq[:, None] + sq[None] - 2 * flat @ flat.T, 0.0) / flat.shape[1])
    shape = pairwise_shape_rms(backbone)
    iu = np.triu_indices(n, 1)
    act, shape = act[iu], shape[iu]
    q = float(np.mean(act <= tau_rms))
    tau_m = float(np.quantile(shape, q, method="inverted_cdf"))  # the smallest distance with a share q within
    same = (intent[iu[0]] == intent[iu[1]]) & (intensity[iu[0]] == intensity[iu[1]])
    wrong = intent[iu[0]] != intent[iu[1]]
    return ShapeTolerance(
        tau_m=tau_m,
        tau_rms=float(tau_rms),
        percentile=100 * q,
        within_tuple_median_m=float(np.median(shape[same])),
        wrong_intent_median_m=float(np.median(shape[wrong])),
        oracle_success=float(np.mean(shape[same] <= tau_m)),
        wrong_intent_success=float(np.mean(shape[wrong] <= tau_m)),
    )


def library_references(
    lib, tau_rms: float, *, engine: str = "auto", trunk: str | None = None
) -> tuple[np.ndarray, ShapeTolerance]:
    """Simulate the whole library once: the held-out references' backbones and the shape tolerance.

    Args:
      lib: a :class:`jgrounding.library.Library`; tau_rms: the actuation tolerance (0.35); trunk: the MJCF to
      simulate on (None: the shipped trunk; ``PhysicsConfig.trunk``).
    Returns:
      ``(reference backbones (N_heldout, T, P, 3), ShapeTolerance)`` from :func:`calibrate` over train + held-out.
    """
    u = np.concatenate([lib.train.u, lib.heldout.u])
    backbone = sim.rollout(u, engine=engine, trunk=trunk).backbone
    intent = np.concatenate([lib.train.intent, lib.heldout.intent])
    intensity = np.concatenate([lib.train.intensity, lib.heldout.intensity])
    return backbone[len(lib.train) :], calibrate(u, backbone, intent, intensity, tau_rms)


def simulate_samples(
    u: np.ndarray, reference: np.ndarray, tau_m: float, *, engine: str = "auto", trunk: str | None = None
) -> dict:
    """Simulate every sample ``u (N, K, T, 4)`` and score it against ``reference (N, T, P, 3)``.

    Returns a dict: ``shape_rms (N, K)`` metres, ``shape_success (N, K)`` bool (``<= tau_m``),
    ``feasible (N, K)`` bool, ``margin (N, K)`` (:func:`jgrounding.sim.feasibility_margin`),
    ``diversity (N,)`` mean pairwise shape RMS of each tuple's K samples, ``simulated`` (distinct
    trajectories rolled out), ``seconds`` (wall time of the rollouts) and ``engine`` (the one used), on ``trunk``
    (None: the shipped trunk).
    """
    n, k = u.shape[:2]
    flat = np.ascontiguousarray(u.reshape(n * k, *u.shape[2:]), dtype=np.float32)
    # Identical samples (a deterministic generator's K copies) are simulated once.
    uniq, inverse = np.unique(flat.reshape(n * k, -1), axis=0, return_inverse=True)
    uniq = uniq.reshape(-1, *u.shape[2:])
    trunk = sim.resolve_trunk(trunk)
    engine = sim.resolve_engine(engine, trunk)
    backbone = np.empty((len(uniq),) + reference.shape[1:], np.float32)
    margin = np.empty(len(uniq))
    feasible = np.empty(len(uniq), bool)
    t0 = time.perf_counter()
    for i in range(0, len(uniq), CHUNK):
        r = sim.rollout(uniq[i : i + CHUNK], engine=engine, trunk=trunk)
        backbone[i : i + CHUNK] = r.backbone
        margin[i : i + CHUNK] = sim.feasibility_margin(r)
        feasible[i : i + CHUNK] = sim.feasible(r)
    seconds = time.perf_counter() - t0
    inverse = inverse.reshape(-1)
    bb = backbone[inverse].reshape(n, k, *reference.shape[1:])
    dist = shape_rms(bb, reference[:, None].astype(np.float32))
    return {
        "shape_rms": dist,
        "shape_success": dist <= tau_m,
        "feasible": feasible[inverse].reshape(n, k),
        "margin": margin[inverse].reshape(n, k),
        "diversity": shape_diversity(bb),
        "simulated": int(len(uniq)),
        "seconds": seconds,
        "engine": engine,
    }
