"""Candidate actuation trajectories from elephant-inspired kinematic primitives (Sec. III-C.1).

Each intent is a *tendon signature*: the pull of the four tendons (0 toward the user, 1 left, 2 away,
3 right) at four key moments of the motion (tau = 0, 1/3, 2/3, 1), built from the primitives of
SPEC §2 — bending toward a side (one tendon), curling (a strong pull, which bends the compliant tip
most), retraction (co-contraction of all tendons shortens the trunk), extension (release), and
compliant contact (a forward bend that reaches the user). Every realization also leans to the left
or to the right (an extra pull on one lateral tendon, chosen by coin): bending direction.

The signatures were chosen as a code with large pairwise distance, so that replaying a different
intent is far in RMS even at the subtle intensity (see ``experiments/references.py``).

A candidate u(tau) is a smooth (cosine-eased) interpolation of the signature's key poses on a time
axis that is warped per realization, scaled by the intensity (reach / curvature), with per-realization
variation in amplitude, timing, proximity and lateral direction. The library then reduces it with
Eq. (ci) (``splines.fit``) and keeps the reconstruction only if it passes screening.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jgrounding.vocabulary import INTENTS, NUM_INTENSITIES

NUM_STEPS = 150
KEY_TIMES = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0])

# Semantic anchors: key poses per intent, written from SPEC §2. The stored SIGNATURES below are
# these anchors refined into a code by `python -m experiments.design_signatures`.
# Key poses per intent: rows are (toward, L, away, R) tendons, columns the four key moments.
# Levels: 0 slack .. 1 largest safe pull (before the intensity scale).
_ANCHORS = {
    # rises toward the user, then waves L-R-L
    "greeting": ([.15, .75, .75, .45], [.05, .95, .05, .85], [.05, .05, .05, .05], [.05, .05, .9, .05]),
    # slow lowering wave that ends retracted (all tendons co-contracted)
    "farewell": ([.05, .05, .05, .3], [.85, .05, .75, .5], [.05, .2, .3, .5], [.05, .8, .05, .5]),
    # slow approach toward the user, then gentle patting (toward pull pulses)
    "comforting": ([.05, .7, .4, .85], [.05, .2, .6, .6], [.05, .05, .05, .05], [.05, .05, .05, .05]),
    # leans toward the user and holds nearly still, tip slightly tilted
    "attentive_listening": ([.55, .6, .6, .6], [.35, .35, .35, .35], [.05, .05, .05, .05], [.05, .05, .05, .05]),
    # extends (slack) and probes side to side with the tip, a little forward
    "curiosity": ([.3, .35, .35, .3], [.05, .75, .05, .75], [.35, .05, .05, .05], [.75, .05, .75, .05]),
    # wide curl around the user: strong forward curl with a lateral wrap
    "embracing": ([.05, .7, .95, .95], [.05, .35, .6, .6], [.05, .05, .05, .05], [.05, .05, .05, .05]),
    # retracts (co-contraction) and bends away from the user
    "withdrawal": ([.05, .05, .05, .05], [.05, .35, .4, .4], [.15, .8, .95, .95], [.05, .2, .3, .3]),
    # curls the tip inward into a tight spiral near the body (strong lateral curl + retraction)
    "coiling": ([.05, .2, .35, .35], [.05, .05, .05, .05], [.05, .3, .45, .45], [.15, .8, .95, .95]),
    # loose bouncy pendulum: large lateral swings with a little away-pull
    "playful_swing": ([.05, .05, .05, .05], [.95, .05, .95, .05], [.3, .45, .3, .45], [.05, .95, .05, .95]),
    # bobs up and down: co-contraction pulses (shorten/lengthen) with a forward lean
    "nodding": ([.35, .85, .35, .85], [.05, .55, .05, .55], [.05, .5, .05, .5], [.05, .55, .05, .55]),
    # shakes side to side: lateral oscillation with co-contracted away tendon (stiff, upright)
    "refusing": ([.05, .05, .05, .05], [.05, .85, .05, .85], [.6, .6, .6, .6], [.85, .05, .85, .05]),
    # repeatedly curls the tip back toward the robot: away-pull pulses
    "beckoning": ([.45, .25, .45, .25], [.05, .05, .05, .05], [.15, .9, .25, .9], [.05, .05, .05, .05]),
    # extends straight toward a direction and holds: toward + away co-pull straightens, small lateral aim
    "pointing": ([.15, .9, .9, .9], [.05, .6, .6, .6], [.05, .5, .5, .5], [.05, .05, .05, .05]),
    # rises high with energetic flourishes: all tendons strong (shortened, raised) with lateral flourish
    "celebrating": ([.55, .95, .6, .95], [.5, .95, .3, .95], [.55, .95, .6, .95], [.5, .3, .95, .3]),
    # relaxes and droops: almost slack, slow
    "resting": ([.1, .05, .05, .05], [.1, .05, .05, .05], [.1, .05, .05, .05], [.1, .05, .05, .05]),
    # reaches toward the user, tip curled upward (strong toward pull late), lateral aim
    "offering": ([.05, .5, .95, .95], [.05, .05, .05, .05], [.05, .05, .05, .05], [.05, .3, .3, .3]),
}
ANCHORS = np.array([np.array(_ANCHORS[m], dtype=np.float64) for m in INTENTS])  # (16, 4, 4)

# The intents' signatures: ANCHORS refined into a code (python -m experiments.design_signatures).
_SIGNATURES = {
    "greeting": ([0.02, 0.97, 0.97, 0.07], [0.02, 0.97, 0.02, 0.97], [0.02, 0.02, 0.02, 0.02], [0.02, 0.02, 0.97, 0.35]),
    "farewell": ([0.02, 0.02, 0.02, 0.46], [0.97, 0.35, 0.97, 0.79], [0.02, 0.02, 0.97, 0.89], [0.27, 0.97, 0.02, 0.29]),
    "comforting": ([0.35, 0.97, 0.02, 0.60], [0.02, 0.02, 0.97, 0.97], [0.02, 0.02, 0.02, 0.02], [0.02, 0.02, 0.02, 0.02]),
    "attentive_listening": ([0.97, 0.97, 0.97, 0.90], [0.97, 0.97, 0.02, 0.02], [0.02, 0.02, 0.02, 0.02], [0.02, 0.02, 0.02, 0.02]),
    "curiosity": ([0.35, 0.02, 0.02, 0.02], [0.35, 0.97, 0.02, 0.97], [0.42, 0.02, 0.02, 0.02], [0.97, 0.02, 0.97, 0.09]),
    "embracing": ([0.02, 0.97, 0.97, 0.97], [0.02, 0.02, 0.97, 0.97], [0.02, 0.02, 0.02, 0.02], [0.12, 0.02, 0.02, 0.02]),
    "withdrawal": ([0.02, 0.02, 0.02, 0.02], [0.02, 0.02, 0.97, 0.78], [0.03, 0.97, 0.97, 0.97], [0.02, 0.02, 0.02, 0.36]),
    "coiling": ([0.11, 0.35, 0.02, 0.14], [0.02, 0.02, 0.02, 0.02], [0.02, 0.02, 0.97, 0.78], [0.11, 0.97, 0.97, 0.97]),
    "playful_swing": ([0.02, 0.02, 0.02, 0.02], [0.97, 0.02, 0.97, 0.02], [0.83, 0.97, 0.02, 0.02], [0.11, 0.97, 0.02, 0.97]),
    "nodding": ([0.88, 0.97, 0.02, 0.97], [0.02, 0.97, 0.02, 0.27], [0.07, 0.97, 0.02, 0.42], [0.26, 0.97, 0.02, 0.58]),
    "refusing": ([0.02, 0.02, 0.02, 0.02], [0.07, 0.97, 0.02, 0.89], [0.97, 0.97, 0.97, 0.79], [0.97, 0.02, 0.97, 0.02]),
    "beckoning": ([0.60, 0.02, 0.97, 0.52], [0.02, 0.02, 0.02, 0.02], [0.35, 0.97, 0.69, 0.97], [0.02, 0.02, 0.02, 0.02]),
    "pointing": ([0.02, 0.97, 0.97, 0.97], [0.04, 0.97, 0.97, 0.72], [0.02, 0.97, 0.97, 0.63], [0.02, 0.02, 0.02, 0.02]),
    "celebrating": ([0.68, 0.97, 0.97, 0.97], [0.70, 0.97, 0.28, 0.97], [0.68, 0.97, 0.94, 0.97], [0.66, 0.85, 0.97, 0.43]),
    "resting": ([0.02, 0.02, 0.02, 0.02], [0.02, 0.02, 0.02, 0.02], [0.02, 0.02, 0.02, 0.02], [0.02, 0.02, 0.02, 0.02]),
    "offering": ([0.02, 0.02, 0.97, 0.97], [0.02, 0.02, 0.02, 0.02], [0.02, 0.02, 0.02, 0.02], [0.16, 0.97, 0.86, 0.30]),
}
SIGNATURES = np.array([np.array(_SIGNATURES[m], dtype=np.float64) for m in INTENTS])  # (16, 4, 4)


# Intensity (subtle .. emphatic) scales reach / curvature / contact proximity, and tempo (motion
# key poses come earlier, so the expressive part lasts longer and moves faster).
INTENSITY_SCALE = np.array([0.76, 0.84, 0.92, 1.0])
INTENSITY_TEMPO = np.array([0.05, 0.02, -0.01, -0.04])  # shift of the middle key times


@dataclasses.dataclass(frozen=True)
class Variation:
    """Spread of the within-tuple realizations (SPEC §3)."""

    amplitude: float = 0.12  # relative, uniform +-
    timing: float = 0.10  # shift of the middle key times, uniform +-
    proximity: float = 0.10  # offset of the toward-user tendon where it is pulled, uniform +-
    jitter: float = 0.07  # per key-pose noise (std)
    tilt: float = 0.22  # extra pull of one lateral tendon (left or right, by coin): bending direction


def _ease(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
    w = 0.5 - 0.5 * np.cos(np.pi * s)
    return a + (b - a) * w


def _interpolate(poses: np.ndarray, times: np.ndarray, num_steps: int) -> np.ndarray:
    """Cosine-eased interpolation of key poses ``(4, K)`` at ``times`` -> ``(T, 4)``."""
    tau = np.linspace(0.0, 1.0, num_steps)
    seg = np.clip(np.searchsorted(times, tau, side="right") - 1, 0, len(times) - 2)
    s = (tau - times[seg]) / (times[seg + 1] - times[seg])
    return _ease(poses[:, seg], poses[:, seg + 1], s).T


def candidate(rng: np.random.Generator, intent: int, intensity: int,
              variation: Variation = Variation(), num_steps: int = NUM_STEPS) -> np.ndarray:
    """One candidate trajectory ``(T, 4)`` for the tuple, drawn with ``rng``."""
    poses = SIGNATURES[intent].copy()
    side = 1 if rng.random() < 0.5 else 3  # bend direction: toward the robot's left or right
    poses[side] += variation.tilt * rng.uniform(0.6, 1.0)
    scale = INTENSITY_SCALE[intensity] * (1.0 + rng.uniform(-variation.amplitude, variation.amplitude))
    base = 0.05
    poses = base + (poses - base) * scale
    pulled = poses[0] > 0.2
    poses[0] = np.where(pulled, poses[0] + rng.uniform(-variation.proximity, variation.proximity), poses[0])
    poses = poses + rng.normal(0.0, variation.jitter, poses.shape)
    poses = np.clip(poses, 0.02, 0.97)
    times = KEY_TIMES.copy()
    shift = INTENSITY_TEMPO[intensity] + rng.uniform(-variation.timing, variation.timing)
    times[1:3] = np.clip(times[1:3] + shift, 0.12, 0.88)
    return _interpolate(poses, times, num_steps)


def candidates(seed: int, per_tuple: int, variation: Variation = Variation()) -> np.ndarray:
    """``(16, 4, per_tuple, T, 4)`` candidates, deterministic in ``seed`` (one stream per tuple)."""
    out = np.empty((len(INTENTS), NUM_INTENSITIES, per_tuple, NUM_STEPS, 4))
    for m in range(len(INTENTS)):
        for z in range(NUM_INTENSITIES):
            rng = np.random.default_rng([seed, m, z])
            for k in range(per_tuple):
                out[m, z, k] = candidate(rng, m, z, variation)
    return out
