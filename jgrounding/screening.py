"""Screening of candidate trajectories (Sec. III-C.1): bounds, smoothness, simulation, semantics.

All checks are vectorised over a batch ``(B, 150, 4)`` and return boolean ``(B,)`` arrays, so the
build script can report an acceptance rate per tuple and per check. The paper screens with an MLLM
judge and manual verification on hardware; ours replaces both with simulation on the trunk
(:mod:`jgrounding.trunk`) and explicit rules on the simulated whole-body shape (:data:`RULES`).
"""

from __future__ import annotations

import numpy as np

from jgrounding import safety, trunk
from jgrounding.vocabulary import INTENTS

MAX_OVERSHOOT = 0.30  # the raw reconstruction may leave [0, 1] by this much (saturated by the gate)
MAX_JERK = 0.03  # max |third difference| of u per step: a saturation kink at a bound is <= one slew step

# Semantic agreement of the simulated shape with the intent (features from trunk.features; metres,
# radians, m/s). Each rule is a readable statement of what the behaviour must show.
RULES = {
    "greeting": lambda f: (f["reach_toward_user"] > 0.12) & (f["lateral_reversals"] >= 1),
    "farewell": lambda f: (f["lateral_reversals"] >= 1) & (f["max_tip_height"] > 0.55),
    "comforting": lambda f: f["min_user_distance"] < 0.12,
    "attentive_listening": lambda f: f["reach_toward_user"] > 0.15,
    "curiosity": lambda f: (f["lateral_reversals"] >= 2) & (f["lateral_excursion"] > 0.25),
    "embracing": lambda f: (f["curvature_max"] > 1.4) & (f["min_user_distance"] < 0.12),
    "withdrawal": lambda f: (f["retreat_from_user"] > 0.12) & (f["reach_toward_user"] < 0.05),
    "coiling": lambda f: (f["curvature_max"] > 1.2) & (f["reach_toward_user"] < 0.08),
    "playful_swing": lambda f: (f["lateral_reversals"] >= 2) & (f["lateral_excursion"] > 0.3),
    "nodding": lambda f: f["vertical_reversals"] >= 2,
    "refusing": lambda f: (f["lateral_reversals"] >= 2) & (f["lateral_excursion"] > 0.25),
    "beckoning": lambda f: (f["vertical_reversals"] >= 2) & (f["retreat_from_user"] > 0.1),
    "pointing": lambda f: (f["reach_toward_user"] > 0.04) & (f["peak_tip_speed"] < 1.0),
    "celebrating": lambda f: (f["vertical_reversals"] >= 3) & (f["peak_tip_speed"] > 1.0),
    "resting": lambda f: (f["curvature_max"] < 0.6) & (f["peak_tip_speed"] < 0.6),
    "offering": lambda f: (f["min_user_distance"] < 0.12) & (f["reach_toward_user"] > 0.15),
}
assert set(RULES) == set(INTENTS)

CHECKS = ("bounds", "smooth", "feasible", "semantic")


def screen(raw: np.ndarray, u: np.ndarray, intent: np.ndarray, *, simulate: bool = True) -> dict[str, np.ndarray]:
    """Checks for reconstructions ``raw`` ``(B, T, N_u)`` and their gated form ``u``; intents ``(B,)``.

    Returns a dict of boolean ``(B,)`` arrays, one per check in :data:`CHECKS`, plus ``"accepted"``.
    ``simulate=False`` runs only the checks that need no trunk model (bounds and slew, smoothness), for
    any number of tendons N_u; the simulated checks need the built-in 4-tendon trunk.
    """
    bounds = (raw.min(axis=(1, 2)) >= -MAX_OVERSHOOT) & (raw.max(axis=(1, 2)) <= 1 + MAX_OVERSHOOT)
    bounds &= np.array([safety.is_safe(x) for x in u])
    smooth = np.abs(np.diff(u, n=3, axis=1)).max(axis=(1, 2)) <= MAX_JERK
    if not simulate:
        return {"bounds": bounds, "smooth": smooth, "accepted": bounds & smooth}
    rollout = trunk.rollout(u, engine="native")
    feats = trunk.features(rollout)
    semantic = np.zeros(len(u), dtype=bool)
    for m, name in enumerate(INTENTS):
        sel = intent == m
        if sel.any():
            semantic[sel] = RULES[name]({k: v[sel] for k, v in feats.items()})
    out = {"bounds": bounds, "smooth": smooth, "feasible": trunk.feasible(rollout), "semantic": semantic}
    out["accepted"] = np.logical_and.reduce([out[c] for c in CHECKS])
    return out
