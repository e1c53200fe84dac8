"""Candidate actuation trajectories from elephant-inspired kinematic primitives (Sec. III-C.1).

A trajectory is four tendon pulls (0 toward the user, 1 the robot's left, 2 away, 3 right) at four
key moments (tau = 0, 1/3, 2/3, 1), built from the primitives of SPEC §2: bending toward a side (one
tendon), curling (a strong pull bends the compliant tip most), retraction (co-contraction shortens
the trunk), extension (release) and compliant contact (a forward bend that reaches the user).

**One-to-many** (Sec. IV: grounding is one-to-many). The intents in :data:`SPLIT` have two distinct
valid variants, mirror images across the sagittal plane (:data:`VARIANTS` says why each is valid);
a tuple's four realizations split 2 + 2 between them, so that their mean is neither. The other
intents have one form and a small left/right tilt of the tip (close variants, well inside tau).

**Intensity** is a real axis (SPEC §2: reach, curvature, tempo, proximity), not a scaling toward
rest. Each variant has a *subtle* end (:func:`subtle_anchor`: the motion is kept back near the
robot's body, at a respectful distance, with a late, slow onset) and an *emphatic* end
(:func:`emphatic_anchor`: full reach toward the user, co-contraction that stiffens and curls the
trunk, on time); moderate and pronounced are the points 1/3 and 2/3 of the way. The ends were
refined into a code in which every two intents, every two variants and every two intensity levels
two apart are far in RMS (``python -m tools.design_signatures``; :data:`CODE`).

A candidate is a cosine-eased interpolation of the key poses on a time axis warped per realization,
with per-realization variation in amplitude, timing and key-pose noise. The library reduces it with
Eq. (ci) and keeps it only if it passes screening.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jgrounding.library.signatures import CODE as _CODE
from jgrounding.vocabulary import INTENTS, NUM_INTENSITIES

NUM_STEPS = 150
KEY_TIMES = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0])
MIRROR = np.array([0, 3, 2, 1])  # left <-> right tendons

# Emphatic key poses of variant A per intent, written from SPEC §2: rows (toward, L, away, R), columns
# the four key moments; 0 slack .. 1 largest safe pull.
_ANCHORS = {
    # rises toward the user on its left side and waves (lateral pull pulses over a left-held bend)
    "greeting": ([0.15, 0.8, 0.8, 0.5], [0.6, 0.95, 0.45, 0.95], [0.05, 0.05, 0.05, 0.05], [0.05, 0.05, 0.6, 0.05]),
    # slow lowering wave that ends retracted (all tendons co-contracted)
    "farewell": ([0.05, 0.05, 0.05, 0.3], [0.85, 0.6, 0.9, 0.5], [0.05, 0.2, 0.3, 0.6], [0.05, 0.05, 0.05, 0.05]),
    # slow approach toward the user's left shoulder, then gentle patting (toward pull pulses)
    "comforting": ([0.05, 0.7, 0.4, 0.85], [0.6, 0.85, 0.85, 0.85], [0.05, 0.05, 0.05, 0.05], [0.05, 0.05, 0.05, 0.05]),
    # leans toward the user and holds nearly still, tip slightly tilted
    "attentive_listening": (
        [0.55, 0.6, 0.6, 0.6],
        [0.35, 0.35, 0.35, 0.35],
        [0.05, 0.05, 0.05, 0.05],
        [0.05, 0.05, 0.05, 0.05],
    ),
    # extends and probes on the left side of the object, sniffing side to side
    "curiosity": ([0.3, 0.35, 0.35, 0.3], [0.6, 0.95, 0.45, 0.95], [0.35, 0.05, 0.05, 0.05], [0.05, 0.05, 0.5, 0.05]),
    # wide curl around the user, wrapping from the robot's left
    "embracing": ([0.05, 0.7, 0.95, 0.95], [0.6, 0.9, 0.9, 0.9], [0.05, 0.05, 0.05, 0.05], [0.05, 0.05, 0.05, 0.05]),
    # retracts (co-contraction) and bends away from the user
    "withdrawal": ([0.05, 0.05, 0.05, 0.05], [0.05, 0.35, 0.4, 0.4], [0.15, 0.8, 0.95, 0.95], [0.05, 0.2, 0.3, 0.3]),
    # curls the tip inward into a tight spiral near the body, to the robot's right (strong lateral curl)
    "coiling": ([0.05, 0.2, 0.35, 0.35], [0.05, 0.05, 0.05, 0.05], [0.05, 0.3, 0.45, 0.45], [0.6, 0.85, 0.95, 0.95]),
    # loose bouncy pendulum: lateral swings with a little away-pull
    "playful_swing": (
        [0.05, 0.05, 0.05, 0.05],
        [0.95, 0.05, 0.95, 0.05],
        [0.3, 0.45, 0.3, 0.45],
        [0.05, 0.95, 0.05, 0.95],
    ),
    # bobs up and down: co-contraction pulses (shorten / lengthen) with a forward lean
    "nodding": ([0.35, 0.85, 0.35, 0.85], [0.05, 0.55, 0.05, 0.55], [0.05, 0.5, 0.05, 0.5], [0.05, 0.55, 0.05, 0.55]),
    # shakes side to side: lateral oscillation with a co-contracted away tendon (stiff, upright)
    "refusing": ([0.05, 0.05, 0.05, 0.05], [0.05, 0.85, 0.05, 0.85], [0.6, 0.6, 0.6, 0.6], [0.85, 0.05, 0.85, 0.05]),
    # curls the tip back toward the robot from its left: away-pull pulses over a left-held bend
    "beckoning": ([0.45, 0.25, 0.45, 0.25], [0.6, 0.85, 0.85, 0.85], [0.15, 0.9, 0.25, 0.9], [0.05, 0.05, 0.05, 0.05]),
    # extends toward a target on the user's left and holds
    "pointing": ([0.15, 0.9, 0.9, 0.9], [0.6, 0.85, 0.85, 0.85], [0.05, 0.5, 0.5, 0.5], [0.05, 0.05, 0.05, 0.05]),
    # rises high with energetic flourishes: all tendons strong (shortened, raised), lateral flourish
    "celebrating": ([0.55, 0.95, 0.6, 0.95], [0.5, 0.95, 0.3, 0.95], [0.55, 0.95, 0.6, 0.95], [0.5, 0.3, 0.95, 0.3]),
    # relaxes and droops: almost slack, slow
    "resting": ([0.1, 0.05, 0.05, 0.05], [0.1, 0.05, 0.05, 0.05], [0.1, 0.05, 0.05, 0.05], [0.1, 0.05, 0.05, 0.05]),
    # reaches toward the user with the tip curled upward, handing over from its left
    "offering": ([0.05, 0.5, 0.95, 0.95], [0.6, 0.85, 0.85, 0.85], [0.05, 0.05, 0.05, 0.05], [0.05, 0.3, 0.3, 0.3]),
}
ANCHORS = np.array([np.array(_ANCHORS[m], dtype=np.float64) for m in INTENTS])  # (16, 4, 4)

# One-to-many intents: variant B is variant A mirrored (left <-> right). Why each is valid:
VARIANTS = {
    "greeting": "a wave raised on the robot's left or on its right: people wave with either hand",
    "comforting": "patting the user's left or right shoulder: both console",
    "curiosity": "probing the object from its left or its right side",
    "embracing": "a hug wraps from either side",
    "coiling": "the spiral curls to the left or to the right; the shy self-hug is the same",
    "beckoning": "the tip curls in from the left or from the right: both say 'come here'",
    "pointing": "two targets, to the left and to the right (the door, the shelf): pointing is at a target",
    "offering": "handing over from the left or from the right of the user",
}
SPLIT = np.array([m in VARIANTS for m in INTENTS])
# Why the others have one form: a mirror of a symmetric motion is itself (attentive listening,
# nodding, resting, celebrating, withdrawal); the swing's and the refusal's other phase and the
# farewell's other side are only ~0.4 RMS apart with P = 4 controls (the splines smooth the
# alternation): close enough that a replay of the other phase is sometimes within tau, too far to
# be the same answer; we keep one phase and leave the side to the tilt.

REACH = np.array([2 if m in ("withdrawal", "coiling", "resting", "refusing") else 0 for m in INTENTS])
# Intents that lean toward the user without touching: their toward-user pull stays below contact.
NO_CONTACT = np.array(
    [m in ("attentive_listening", "nodding", "celebrating", "greeting", "pointing", "refusing") for m in INTENTS]
)


def subtle_anchor(poses: np.ndarray, reach: int) -> np.ndarray:
    """The subtle end of a variant: kept back near the body, little reach, a late, slow onset."""
    p = poses.copy()
    p[:, 1:] = 0.5 * poses[:, 1:] + 0.5 * poses[:, :-1]  # half a key moment late: slower tempo
    p[reach] = 0.05 + (p[reach] - 0.05) * 0.15  # small reach in the intent's own direction
    if reach == 0:  # intents that go toward the user are held back by the away tendon: a respectful distance
        p[2] += 0.4 * (1.0 - p[2])
    return p


def emphatic_anchor(poses: np.ndarray) -> np.ndarray:
    """The emphatic end: full reach as written, slack tendons co-contracted (stiffer, more curvature)."""
    p = poses.copy()
    p[:, 1:] = np.where(p[:, 1:] < 0.2, p[:, 1:] + 0.25, p[:, 1:])
    return p


def design_anchors() -> np.ndarray:
    """``(16, 2, 2, 4, 4)``: [intent, variant, end (subtle, emphatic)] key poses before refinement."""
    out = np.zeros((len(INTENTS), 2, 2, 4, 4))
    for m in range(len(INTENTS)):
        out[m, 0] = subtle_anchor(ANCHORS[m], REACH[m]), emphatic_anchor(ANCHORS[m])
        out[m, 1] = out[m, 0][:, MIRROR]
    return out


CODE = np.array(_CODE, dtype=np.float64)  # (16, 2, 2, 4, 4), refined design_anchors()


def key_poses(intent: int, variant: int, intensity: int) -> np.ndarray:
    """``(4, 4)`` key poses of the tuple's variant: ``intensity / 3`` of the way from subtle to emphatic."""
    s = intensity / (NUM_INTENSITIES - 1)
    return (1.0 - s) * CODE[intent, variant, 0] + s * CODE[intent, variant, 1]


@dataclasses.dataclass(frozen=True)
class Variation:
    """Spread of the realizations within one variant (SPEC §3)."""

    amplitude: float = 0.08  # relative, uniform +-
    timing: float = 0.06  # shift of the middle key times, uniform +-
    jitter: float = 0.04  # per key-pose noise (std)
    tilt: float = 0.15  # intents with one form: extra pull of one lateral tendon (coin): tip tilt


def _ease(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
    w = 0.5 - 0.5 * np.cos(np.pi * s)
    return a + (b - a) * w


def _interpolate(poses: np.ndarray, times: np.ndarray, num_steps: int) -> np.ndarray:
    """Cosine-eased interpolation of key poses ``(4, K)`` at ``times`` -> ``(T, 4)``."""
    tau = np.linspace(0.0, 1.0, num_steps)
    seg = np.clip(np.searchsorted(times, tau, side="right") - 1, 0, len(times) - 2)
    s = (tau - times[seg]) / (times[seg + 1] - times[seg])
    return _ease(poses[:, seg], poses[:, seg + 1], s).T


def candidate(
    rng: np.random.Generator,
    intent: int,
    intensity: int,
    variant: int = 0,
    variation: Variation = Variation(),
    num_steps: int = NUM_STEPS,
) -> np.ndarray:
    """One candidate trajectory ``(T, 4)`` of the tuple's ``variant``, drawn with ``rng``."""
    poses = key_poses(intent, variant, intensity)
    if not SPLIT[intent]:
        poses[1 if rng.random() < 0.5 else 3] += variation.tilt * rng.uniform(0.6, 1.0)
    base = 0.05
    poses = base + (poses - base) * (1.0 + rng.uniform(-variation.amplitude, variation.amplitude))
    poses = np.clip(poses + rng.normal(0.0, variation.jitter, poses.shape), 0.02, 0.97)
    times = KEY_TIMES.copy()
    times[1:3] = times[1:3] + rng.uniform(-variation.timing, variation.timing)
    return _interpolate(poses, times, num_steps)


def variants_of(intent: int, realizations: int = 4) -> np.ndarray:
    """Variant of each realization of a tuple: split evenly (A, B, A, B) or all A."""
    return np.arange(realizations) % 2 if SPLIT[intent] else np.zeros(realizations, int)
