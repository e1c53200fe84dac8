"""Calibration of the semantic head on the dev split (Sec. III-A; ``python -m tools.train_semantics`` fits them):
the softmax temperature of the intents, the ordinal intensity cut points, and the expected calibration error
they are judged by.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np


def with_cut_points(params: dict, theta) -> dict:
    """``params`` with the ordinal intensity cut points set to ``theta`` ``(3,)``, strictly increasing (a single
    head; stored as theta0 and the softplus-inverse of the gaps, as :func:`jgrounding.semantics.head.thresholds` reads them)."""
    theta = np.asarray(theta, np.float64)
    gaps = np.diff(theta)
    if theta.shape != (3,) or np.any(gaps <= 0):
        raise ValueError(f"cut points must be 3 strictly increasing values, got {theta.tolist()}")
    return dict(params, z_theta0=jnp.float32(theta[0]), z_gaps=jnp.asarray(np.log(np.expm1(gaps)), jnp.float32))


def expected_calibration_error(confidence, correct, bins: int = 10) -> float:
    """ECE: sum over equal-width confidence bins of |accuracy - mean confidence| weighted by the bin's share."""
    confidence, correct = np.asarray(confidence, float), np.asarray(correct, float)
    idx = np.minimum((confidence * bins).astype(int), bins - 1)
    return float(
        sum(
            abs(correct[idx == b].mean() - confidence[idx == b].mean()) * np.mean(idx == b)
            for b in range(bins)
            if np.any(idx == b)
        )
    )


def fit_temperature(logits_fn, intent, grid=np.exp(np.linspace(np.log(0.3), np.log(5.0), 60))) -> float:
    """The temperature (grid search) that minimises the NLL of the true intents; ``logits_fn(T)`` gives probs."""
    nll = [-np.mean(np.log(np.clip(logits_fn(t)[np.arange(len(intent)), intent], 1e-9, 1))) for t in grid]
    return float(grid[int(np.argmin(nll))])
