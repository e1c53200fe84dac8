"""The bounded semantic space M x Z of Sec. III-A: sixteen intents, four intensities.

This is the one place that maps names to indices (STYLE habit 11). Every public entry point that
takes an intent or an intensity calls :func:`intent_index` / :func:`intensity_index`, which accept
a name (case- and separator-insensitive) or an integer index and raise a ``ValueError`` naming the
valid choices otherwise.
"""

from __future__ import annotations

import numbers

INTENTS: tuple[str, ...] = (
    "greeting",
    "farewell",
    "comforting",
    "attentive_listening",
    "curiosity",
    "embracing",
    "withdrawal",
    "coiling",
    "playful_swing",
    "nodding",
    "refusing",
    "beckoning",
    "pointing",
    "celebrating",
    "resting",
    "offering",
)

INTENSITIES: tuple[str, ...] = ("subtle", "moderate", "pronounced", "emphatic")

NUM_INTENTS = len(INTENTS)
NUM_INTENSITIES = len(INTENSITIES)
NUM_TUPLES = NUM_INTENTS * NUM_INTENSITIES

# Canonical morphology-aligned description of each intent (SPEC §2): what the whole trunk does,
# phrased with the elephant primitives (bending, curling, extension, retraction, compliant contact).
INTENT_DESCRIPTIONS: dict[str, str] = {
    "greeting": "the trunk rises toward the user and waves side to side to say hello",
    "farewell": "the trunk makes a slow lowering wave and ends retracted, saying goodbye",
    "comforting": "the trunk slowly approaches the user, then gently strokes or pats them with the tip",
    "attentive_listening": "the trunk leans toward the user and holds nearly still with the tip slightly tilted, listening",
    "curiosity": "the trunk extends and probes with the tip, sniffing from side to side",
    "embracing": "the trunk curls widely around the user in a hug-like wrap",
    "withdrawal": "the trunk retracts and bends away from the user",
    "coiling": "the trunk curls its tip inward into a tight spiral near the body, shy and self-soothing",
    "playful_swing": "the trunk swings loosely side to side like a bouncy pendulum, playful",
    "nodding": "the trunk bobs up and down in agreement or acknowledgement",
    "refusing": "the trunk shakes from side to side to say no",
    "beckoning": "the trunk repeatedly curls its tip back toward the robot, inviting the user to come closer",
    "pointing": "the trunk extends straight toward a direction and holds",
    "celebrating": "the trunk rises high with energetic flourishes, like a trumpeting elephant",
    "resting": "the trunk relaxes and droops with minimal slow motion",
    "offering": "the trunk reaches toward the user with the tip curled upward, as if handing something over",
}

# How each intensity level changes execution (Sec. III-A): reach, curvature, tempo, proximity.
INTENSITY_DESCRIPTIONS: dict[str, str] = {
    "subtle": "barely, with a small reach, gentle curvature, slow tempo and a respectful distance",
    "moderate": "moderately, with a medium reach, clear curvature, a calm tempo and a comfortable distance",
    "pronounced": "clearly and noticeably, with a large reach, strong curvature, a lively tempo and close proximity",
    "emphatic": "emphatically and intensely, with full reach, maximal curvature, a fast energetic tempo and closest proximity",
}


def normalise(name: str) -> str:
    """How names are matched: case-insensitive, with "-" and " " read as "_" ("Attentive listening")."""
    return name.strip().lower().replace("-", "_").replace(" ", "_")


def _index(value, names: tuple[str, ...], kind: str) -> int:
    if isinstance(value, bool):  # bool is an int; refuse it explicitly.
        raise ValueError(f"{kind} must be a name or an index, got bool {value!r}; valid: {', '.join(names)}")
    if isinstance(value, numbers.Integral) or (
        hasattr(value, "dtype") and getattr(value, "ndim", 1) == 0 and "int" in str(value.dtype)
    ):
        i = int(value)
        if 0 <= i < len(names):
            return i
        raise ValueError(f"{kind} index {i} is out of range 0..{len(names) - 1}; valid: {', '.join(names)}")
    if isinstance(value, str):
        key = normalise(value)
        if key in names:
            return names.index(key)
        plural = "intensities" if kind == "intensity" else f"{kind}s"
        raise ValueError(f"unknown {kind} {value!r}; valid {plural}: {', '.join(names)}")
    raise ValueError(
        f"{kind} must be a name (str) or an index (int), got {type(value).__name__}; valid: {', '.join(names)}"
    )


def intent_index(intent: str | int) -> int:
    """Index in :data:`INTENTS` of an intent name or index; ``ValueError`` listing the valid ones."""
    return _index(intent, INTENTS, "intent")


def intensity_index(intensity: str | int) -> int:
    """Index in :data:`INTENSITIES` of an intensity name or index; ``ValueError`` listing them."""
    return _index(intensity, INTENSITIES, "intensity")


def tuple_index(intent: str | int, intensity: str | int) -> int:
    """Flat index ``intent * 4 + intensity`` of an (intent, intensity) tuple, in 0..63."""
    return intent_index(intent) * NUM_INTENSITIES + intensity_index(intensity)


def describe(intent: str | int, intensity: str | int | None = None) -> str:
    """Canonical description d_m (or d_{m,z} when an intensity is given) of Eq. (3)."""
    m = INTENTS[intent_index(intent)]
    text = INTENT_DESCRIPTIONS[m]
    if intensity is None:
        return text
    z = INTENSITIES[intensity_index(intensity)]
    return f"{z}: {text}, performed {INTENSITY_DESCRIPTIONS[z]}"
