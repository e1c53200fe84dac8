"""Screening of candidate trajectories (Sec. III-C.1): bounds, smoothness, simulation, semantics.

All checks are vectorised over a batch ``(B, 150, 4)`` and return boolean ``(B,)`` arrays, so the
build script can report an acceptance rate per tuple and per check. The paper screens with an MLLM
judge and manual verification on hardware; ours replaces both with simulation on the trunk
(:mod:`jgrounding.sim`) and explicit rules on the simulated whole-body shape (:data:`RULES`).
"""

from __future__ import annotations

import numpy as np

from jgrounding import safety, sim
from jgrounding.vocabulary import INTENTS

MAX_OVERSHOOT = 0.30  # the raw reconstruction may leave [0, 1] by this much (saturated by the gate)
MAX_JERK = 0.03  # max |third difference| of u per step: a saturation kink at a bound is <= one slew step

# Semantic agreement of the simulated shape with the intent (features from trunk.features; metres,
# radians, m/s). Each rule is a readable statement of what the behaviour must show. ``z`` is the
# intensity index (0 subtle .. 3 emphatic): reach and proximity grow with it (SPEC §2), so a rule asks
# for contact or a long reach only where the intensity calls for it (``near(z)``, ``reach(z)``), and
# a subtle motion must keep its respectful distance (no contact: ``far(z)``).
NEAR = (0.30, 0.28, 0.24, 0.15)  # m: the tip comes at least this close to the user, per intensity
REACH = (-0.05, -0.03, 0.02, 0.12)  # m: toward-user reach of intents that go toward the user, per intensity
SWING = (0.08, 0.12, 0.18, 0.25)  # m: lateral excursion of a swing or a shake, per intensity
RISE = (0.05, 0.1, 0.15, 0.25)  # m: how high a celebration lifts the tip above rest, per intensity


def _near(f, z):
    return f["min_user_distance"] < np.take(NEAR, z)


def _reach(f, z):
    return f["reach_toward_user"] > np.take(REACH, z)


def _respectful(f, z):
    return (z >= 2) | (f["min_user_distance"] > 0.05)


# Libraries v3 and v4 (every realization starts from rest and has three key poses after it) check each intent's
# kinematic signature (SPEC §2) on the simulated tip path: the plane an oscillation lies in, where a
# motion ends, how high it rises.
RULES = {
    "greeting": lambda f, z: (
        _reach(f, z) & (f["lateral_reversals"] >= 1) & (f["rise"] > np.take(RISE, z) / 2) & _respectful(f, z)
    ),
    "farewell": lambda f, z: (f["lateral_reversals"] >= 1) & (f["max_tip_height"] > 0.55),
    "comforting": lambda f, z: _near(f, z) & _reach(f, z),
    "attentive_listening": lambda f, z: _reach(f, z) & _respectful(f, z),
    "curiosity": lambda f, z: (f["lateral_reversals"] >= 1) & (f["lateral_excursion"] > 0.5 * np.take(SWING, z)),
    "embracing": lambda f, z: (f["curvature_max"] > 1.4) & _near(f, z) & _reach(f, z),
    "withdrawal": lambda f, z: (
        (f["retreat_from_user"] > np.take((-0.01, 0.02, 0.05, 0.08), z))
        & (f["reach_toward_user"] < 0.05)
        & (f["final_retreat"] > 0.0)  # ends farther from the user than it started
    ),
    "coiling": lambda f, z: (f["curvature_max"] > 1.2) & (f["reach_toward_user"] < 0.08),
    "playful_swing": lambda f, z: (f["lateral_reversals"] >= 1) & (f["lateral_excursion"] > np.take(SWING, z)),
    "nodding": lambda f, z: (
        (f["vertical_reversals"] >= np.take((1, 1, 2, 2), z))  # a subtle nod is one bob
        & (f["sagittal_excursion"] > f["lateral_excursion"])
        & _respectful(f, z)
    ),
    "refusing": lambda f, z: (
        (f["lateral_reversals"] >= 1)
        & (f["lateral_excursion"] > np.take(SWING, z))
        & (f["lateral_excursion"] > 0.8 * f["sagittal_excursion"])
        & _respectful(f, z)
    ),
    "beckoning": lambda f, z: (f["vertical_reversals"] >= np.take((0, 0, 1, 1), z)) & (f["retreat_from_user"] > 0.0),
    "pointing": lambda f, z: _reach(f, z) & (f["peak_tip_speed"] < 3.5) & _respectful(f, z),
    "celebrating": lambda f, z: (f["lateral_reversals"] >= 1) & (f["rise"] > np.take(RISE, z)),
    "resting": lambda f, z: (f["peak_tip_speed"] < 2.0) & (f["min_user_distance"] > 0.10),
    "offering": lambda f, z: _near(f, z) & _reach(f, z),
}
assert set(RULES) == set(INTENTS)

CHECKS = ("bounds", "smooth", "feasible", "semantic")


def screen(
    raw: np.ndarray,
    u: np.ndarray,
    intent: np.ndarray,
    *,
    simulate: bool = True,
    intensity: np.ndarray | None = None,
    trunk: str | None = None,
) -> dict[str, np.ndarray]:
    """Checks for reconstructions ``raw`` ``(B, T, N_u)`` and their gated form ``u``; intents ``(B,)``.

    Returns a dict of boolean ``(B,)`` arrays, one per check in :data:`CHECKS`, plus ``"accepted"``.
    ``simulate=False`` runs only the checks that need no trunk model (bounds and slew, smoothness), for
    any number of tendons N_u; the simulated checks need the built-in 4-tendon trunk. ``intensity``
    ``(B,)`` grades the reach and proximity a rule asks for; without it the emphatic grade applies. ``trunk``: the
    MJCF simulated (a fitted trunk; None, the shipped one).
    """
    bounds = (raw.min(axis=(1, 2)) >= -MAX_OVERSHOOT) & (raw.max(axis=(1, 2)) <= 1 + MAX_OVERSHOOT)
    bounds &= np.array([safety.is_safe(x) for x in u])
    smooth = np.abs(np.diff(u, n=3, axis=1)).max(axis=(1, 2)) <= MAX_JERK
    if not simulate:
        return {"bounds": bounds, "smooth": smooth, "accepted": bounds & smooth}
    rollout = sim.rollout(u, engine="native", trunk=trunk)
    feats = sim.features(rollout)
    semantic = np.zeros(len(u), dtype=bool)
    for m, name in enumerate(INTENTS):
        sel = intent == m
        if sel.any():
            z = np.full(int(sel.sum()), 3) if intensity is None else np.asarray(intensity)[sel]
            semantic[sel] = RULES[name]({k: v[sel] for k, v in feats.items()}, z)
    out = {"bounds": bounds, "smooth": smooth, "feasible": sim.feasible(rollout), "semantic": semantic}
    out["accepted"] = np.logical_and.reduce([out[c] for c in CHECKS])
    return out
