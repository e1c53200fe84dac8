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

**Library v3: recordings of a real trunk.** Every realization starts from the trunk's rest command (all
tendons slack: the first key pose is 0) and either returns to rest (the oscillating gestures in
:data:`RETURNS`) or holds its last pose (pointing holds, withdrawal stays away, farewell ends retracted).
Within a variant, realizations vary as a person's repetitions do (:class:`Variation`): onset and tempo
+-15 %, amplitude +-10 % and a little key-pose noise.

A candidate is the Catmull-Rom curve through the key poses, played on a time axis that is delayed
(onset) and stretched (tempo) per realization, scaled (amplitude) and jittered. The library reduces it
with Eq. (ci) and keeps it only if it passes screening.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jgrounding.actuation import splines
from jgrounding.config import NUM_STEPS  # noqa: E402  (T of Table I)
from jgrounding.library import code_words
from jgrounding.vocabulary import INTENTS, NUM_INTENSITIES

REST = 0.0  # the rest command: every tendon slack (jgrounding.safety.REST)
KEY_TIMES = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0])
MIRROR = np.array([0, 3, 2, 1])  # left <-> right tendons

# Emphatic key poses of variant A per intent, written from SPEC §2: rows (toward, L, away, R), columns
# the four key moments; 0 slack .. 1 largest safe pull.
_ANCHORS = {
    # v3: the first key pose is rest (every realization starts there); the gestures in RETURNS end at rest.
    # rises toward the user and waves (left, then right), ends raised toward the user
    "greeting": ([0, 0.7, 0.7, 0.6], [0, 0.9, 0.1, 0.5], [0, 0.0, 0.0, 0.0], [0, 0.05, 0.8, 0.05]),
    # a slow wave (right, then left) that lowers and ends retracted (all tendons co-contracted)
    "farewell": ([0, 0.3, 0.1, 0.1], [0, 0.1, 0.7, 0.45], [0, 0.5, 0.3, 0.45], [0, 0.7, 0.1, 0.45]),
    # slow approach toward the user's left shoulder, contact, then a stroke
    "comforting": ([0, 0.6, 0.95, 0.9], [0, 0.6, 0.8, 0.4], [0, 0.0, 0.0, 0.0], [0, 0.0, 0.0, 0.0]),
    # leans toward the user and holds nearly still, tip slightly tilted
    "attentive_listening": ([0, 0.6, 0.6, 0.6], [0, 0.2, 0.2, 0.2], [0, 0.0, 0.0, 0.0], [0, 0.0, 0.0, 0.0]),
    # extends and probes, sniffing to the right, then the left, then the right again
    "curiosity": ([0, 0.45, 0.45, 0.3], [0, 0.05, 0.8, 0.05], [0, 0.4, 0.1, 0.4], [0, 0.8, 0.05, 0.5]),
    # wide curl around the user, wrapping from the robot's left, held
    "embracing": ([0, 0.8, 0.95, 0.95], [0, 0.9, 0.95, 0.95], [0, 0.0, 0.0, 0.0], [0, 0.0, 0.3, 0.3]),
    # retracts (co-contraction) and bends away from the user, held there
    "withdrawal": ([0, 0.0, 0.0, 0.0], [0, 0.1, 0.3, 0.3], [0, 0.7, 0.95, 0.95], [0, 0.1, 0.3, 0.3]),
    # curls the tip inward into a tight spiral near the body, to the robot's right, held
    "coiling": ([0, 0.0, 0.0, 0.0], [0, 0.0, 0.0, 0.0], [0, 0.3, 0.5, 0.5], [0, 0.8, 0.95, 0.95]),
    # loose, bouncy pendulum: right, then left, then back to rest
    "playful_swing": ([0, 0.2, 0.2, 0], [0, 0.05, 0.95, 0], [0, 0.2, 0.2, 0], [0, 0.95, 0.05, 0]),
    # bobs in the sagittal plane: toward the user (up), away (up on the other side), back to rest
    "nodding": ([0, 0.8, 0.05, 0], [0, 0.2, 0.2, 0], [0, 0.05, 0.7, 0], [0, 0.2, 0.2, 0]),
    # shakes in the lateral plane, stiff (away tendon co-contracted): left, right, back to rest
    "refusing": ([0, 0.0, 0.0, 0], [0, 0.85, 0.05, 0], [0, 0.6, 0.6, 0], [0, 0.05, 0.85, 0]),
    # reaches, curls the tip back toward the robot, reaches again: come closer
    "beckoning": ([0, 0.7, 0.2, 0.7], [0, 0.5, 0.5, 0.5], [0, 0.2, 0.8, 0.2], [0, 0.0, 0.0, 0.0]),
    # extends toward a target on the user's left and holds
    "pointing": ([0, 0.9, 0.9, 0.9], [0, 0.5, 0.55, 0.55], [0, 0.0, 0.0, 0.0], [0, 0.0, 0.0, 0.0]),
    # rises high and back (trumpet-like) with energetic lateral flourishes
    "celebrating": ([0, 0.0, 0.0, 0.0], [0, 0.1, 0.9, 0.1], [0, 0.95, 0.8, 0.95], [0, 0.9, 0.1, 0.9]),
    # relaxes and droops: barely pulled, slow
    "resting": ([0, 0.1, 0.1, 0.1], [0, 0.1, 0.15, 0.15], [0, 0.15, 0.2, 0.2], [0, 0.1, 0.15, 0.15]),
    # reaches toward the user and curls the tip upward (away pull at the end), handing over from its left
    "offering": ([0, 0.7, 0.95, 0.95], [0, 0.4, 0.4, 0.4], [0, 0.0, 0.3, 0.5], [0, 0.0, 0.0, 0.0]),
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

# Gestures that oscillate and come back: they end at rest. The others hold their last pose.
RETURNS = ("nodding", "refusing", "playful_swing")
RETURNS_MASK = np.array([m in RETURNS for m in INTENTS])

REACH = np.array([2 if m in ("withdrawal", "coiling", "resting", "refusing") else 0 for m in INTENTS])
# Intents that lean toward the user without touching: their toward-user pull stays below contact.
NO_CONTACT = np.array(
    [m in ("attentive_listening", "nodding", "celebrating", "greeting", "pointing", "refusing") for m in INTENTS]
)


SUBTLE_SCALE = 0.5  # the subtle end pulls half as hard as the emphatic one
SUBTLE_LAG = 1.0  # and reaches each key pose one key moment later (slower)


def subtle_anchor(poses: np.ndarray, intent: int) -> np.ndarray:
    """The subtle end of a variant: the same gesture with half the pull (less reach and curvature), one key
    moment late (a slower tempo)."""
    p = poses.copy()
    p[:, 1:] = (1 - SUBTLE_LAG) * poses[:, 1:] + SUBTLE_LAG * poses[:, :-1]  # late: a slower tempo
    if RETURNS_MASK[intent]:
        p[:, -1] = REST  # an oscillation still comes back to rest
    return REST + SUBTLE_SCALE * (p - REST)


def emphatic_anchor(poses: np.ndarray) -> np.ndarray:
    """The emphatic end: the gesture as written, full reach and curvature, on time."""
    return poses.copy()


def design_anchors() -> np.ndarray:
    """``(16, 2, 2, 4, 4)``: [intent, variant, end (subtle, emphatic)] key poses before refinement; the
    first key pose is the rest command and the gestures in :data:`RETURNS` end at rest."""
    out = np.zeros((len(INTENTS), 2, 2, 4, 4))
    for m in range(len(INTENTS)):
        out[m, 0] = subtle_anchor(ANCHORS[m], m), emphatic_anchor(ANCHORS[m])
        out[m, 1] = out[m, 0][:, MIRROR]
    out[..., 0] = REST
    out[RETURNS_MASK, ..., -1] = REST
    return out


CODE = code_words.load(3).code  # (16, 2, 2, 4, 4), refined design_anchors() (jgrounding/assets/designs/code_v3.json)


def key_poses(intent: int, variant: int, intensity: int) -> np.ndarray:
    """``(4, 4)`` key poses of the tuple's variant: ``intensity / 3`` of the way from subtle to emphatic."""
    s = intensity / (NUM_INTENSITIES - 1)
    return (1.0 - s) * CODE[intent, variant, 0] + s * CODE[intent, variant, 1]


@dataclasses.dataclass(frozen=True)
class Variation:
    """Spread of the realizations within one variant (SPEC §3): what a person's repetitions vary."""

    onset: float = 0.15  # the motion starts up to this share of the first key interval late (uniform)
    tempo: float = 0.15  # pace, uniform +-: the gesture's time runs as t ** (1 +- tempo), completed in time
    amplitude: float = 0.10  # relative size of every pull, uniform +-
    jitter: float = 0.05  # per key-pose noise (std), after the rest pose
    tilt: float = 0.15  # intents with one form: extra pull of one lateral tendon (coin): tip tilt


_FINE = 600  # resolution of the key-pose curve before the time warp


def candidate(
    rng: np.random.Generator,
    intent: int,
    intensity: int,
    variant: int = 0,
    variation: Variation = Variation(),
    num_steps: int = NUM_STEPS,
    design=None,
) -> np.ndarray:
    """One candidate trajectory ``(T, 4)`` of the tuple's ``variant``, drawn with ``rng``: starts at rest.

    ``design``: a :class:`jgrounding.library.designs.Design` whose key poses to play (None: this module's v3
    code). The variation and its random draws are the same for every design."""
    poses = key_poses(intent, variant, intensity) if design is None else design.key_poses(intent, variant, intensity)
    one_form = not SPLIT[intent] if design is None else design.one_form(intent)
    moving = slice(1, None if not RETURNS_MASK[intent] else -1)  # rest stays rest
    if one_form:
        poses[1 if rng.random() < 0.5 else 3, moving] += variation.tilt * rng.uniform(0.6, 1.0)
    poses[:, moving] = np.clip(poses[:, moving] + rng.normal(0.0, variation.jitter, poses[:, moving].shape), 0, 1)
    # Onset: the motion starts up to ``onset`` of the first key interval late. Tempo: the pace of the
    # gesture changes by up to +-``tempo`` (faster early and slower late, or the reverse); either way it is
    # completed within the trajectory, so a gesture that returns to rest does return.
    onset = rng.uniform(0.0, variation.onset) * KEY_TIMES[1]
    gamma = 1.0 + rng.uniform(-variation.tempo, variation.tempo)
    tau = np.linspace(0.0, 1.0, num_steps)
    warped = np.clip((tau - onset) / (1.0 - onset), 0.0, 1.0) ** gamma
    curve = splines.basis_np(_FINE, poses.shape[1]) @ poses.T  # (_FINE, 4)
    fine = np.linspace(0.0, 1.0, _FINE)
    out = np.stack([np.interp(warped, fine, curve[:, j]) for j in range(curve.shape[1])], axis=-1)
    return REST + (out - REST) * (1.0 + rng.uniform(-variation.amplitude, variation.amplitude))


def variants_of(intent: int, realizations: int = 4) -> np.ndarray:
    """Variant of each realization of a tuple: split evenly (A, B, A, B) or all A."""
    return np.arange(realizations) % 2 if SPLIT[intent] else np.zeros(realizations, int)
