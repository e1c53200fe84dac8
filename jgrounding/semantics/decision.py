"""Act or hold: the one decision, per kind of text, that every front end's grounding passes
(:func:`jgrounding.semantics.ground`, so the Responder, the CLI, the interactive loop, the server, its stream and
the page all get it).

Two questions, two parts of the decision:

1. **Move at all?** That is the no-motion decision's job (:mod:`jgrounding.semantics.nomotion`): the rule, the
   learned detector (at the operating point's threshold) and the head's no-behaviour class. A text that chooses a
   motion outside what it rules out (:func:`jgrounding.semantics.nomotion.chosen_motion`: "wave back!", "a tiny
   nod", "don't hug; just nod") is not held by the rule or the detector: the text names the gesture it wants.
2. **Which motion?** The confidence threshold guards only against acting on a wrong intent, and how much a
   confidence says depends on the kind of text (:func:`kind`):

   - ``order``: the text chooses a motion and the clause that chooses it names a gesture of the intent the head
     read ("wave back enthusiastically!" read as greeting, "give a small nod" as nodding);
   - ``chosen``: the text chooses a motion, but its words do not name the head's intent outright (a contrast's
     "...; normal hello", slang, a gesture the head read as another intent);
   - ``situation``: no motion is chosen; the reaction is the head's reading of a situation to interpret.

   Each kind has its own threshold (:class:`OperatingPoint`), fitted on the dev sets by ``python -m
   tools.nomotion_frontier --write`` to the least expected cost (:data:`COSTS`).

The costs (:data:`COSTS`), one unit being a motion text held (the user asked and the robot did nothing, a miss the
user notices and can repeat or force):

- a motion text held: **1**;
- a text that calls for no motion acted on: **3** (the trunk moves when told to keep still, while someone else is
  spoken to, while it is being serviced: an intrusion and sometimes a safety matter, worse than a miss);
- a motion text acted on with a wrong intent: **5** (the robot does something other than asked, e.g. a refusal
  shake for a nod or a hug for a wave: it misleads the person, and the person also did not get the motion).

The point written by the tool (``jgrounding/assets/operating_point.json``) names the head it was fitted for; for
another head it is ignored, with a warning, and every kind falls back to the head's calibrated threshold.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import re

from jgrounding.io import asset
from jgrounding.semantics import nomotion, structure
from jgrounding.semantics.cues import LEXICAL
from jgrounding.semantics.types import Grounding

COSTS = {"held_motion": 1.0, "acted_no_motion": 3.0, "acted_wrong": 5.0}
COST_REASONS = {
    "held_motion": "a motion text held: the user asked and nothing moved; noticed, and repeated or forced",
    "acted_no_motion": "a text that calls for no motion acted on: the trunk moves when told to keep still, while "
    "someone else is spoken to or while it is serviced",
    "acted_wrong": "a motion text acted on with a wrong intent: another gesture than asked, which misleads, and "
    "the asked one is missed too",
}
KINDS = ("order", "chosen", "situation")
KIND_WORDS = {
    "order": "a text that names its motion",
    "chosen": "a text that chooses a motion in other words",
    "situation": "a situation to interpret",
}
POINT_ASSET = asset("operating_point.json")

# Gestures named outright that the cue lists of :data:`jgrounding.semantics.cues.LEXICAL` leave out because they
# belong to more than one intent ("wave": hello, goodbye or come over): each names every intent it can mean.
_GESTURES = {
    "greeting": r"\bwav\w*|\braise\w*|\blift\w*|\bhigh-five",
    "farewell": r"\bwav\w*|\bbow\w*",
    "comforting": r"\bcaress\w*|\bnuzzl\w*|\blean\w* in\b|\bgentle touch",
    "attentive_listening": r"\blean\w*|\btilt\w*|\bfocus\w*|\bturn\w* toward",
    "curiosity": r"\bsnuffl\w*|\bprob\w*|\breach\w*|\bextend\w*",
    "embracing": r"\bwrap\w*|\benvelop\w*|\bcurl\w* around",
    "withdrawal": r"\bretract\w*|\bpull\w* back|\bdraw back|\brecoil\w*|\bshrink\w*",
    "coiling": r"\bcurl\w*|\bspiral\w*|\btuck\w*",
    "playful_swing": r"\bwiggl\w*|\bshimmy|\brock\w*|\bwag\w*|\btwirl\w*|\bspin\w*",
    "nodding": r"\bdip\w*|\bbow\w*|\byes\b",
    "refusing": r"\bshak\w*|\bno way\b",
    "beckoning": r"\bwav\w*|\bcurl\w*|\bcome-closer|\binvit\w*",
    "pointing": r"\bextend\w*|\bshow\w*|\bstretch\w*|\baim\w*",
    "celebrating": r"\bflourish\w*|\bclap\w*|\bapplau\w*|\braise\w*|\blift\w*|\berupt\w*",
    "resting": r"\blower\w*|\bsink\w*|\bgo limp|\btake it easy|\bsettle\w*",
    "offering": r"\breach\w*|\bextend\w*|\bpresent\w*|\bhand\w* (?:it|over)",
}
_NAMES = {m: re.compile(f"{LEXICAL[m]}|{_GESTURES[m]}", re.IGNORECASE) for m in LEXICAL}


def named_intents(clause: str) -> set[str]:
    """The intents whose gestures ``clause`` names outright ("wave back" names greeting, farewell, beckoning)."""
    return {m for m, pattern in _NAMES.items() if pattern.search(clause)}


def kind(text: str, intent: str, st: structure.Structure | None = None) -> tuple[str, set[str]]:
    """The kind of ``text`` (one of :data:`KINDS`) for a grounding whose intent is ``intent``, and the intents its
    chosen clause names: ``order`` when the clause that chooses its motion
    (:func:`jgrounding.semantics.nomotion.chosen_motion`) names a gesture of ``intent``, ``chosen`` when a clause
    chooses a motion but names none of ``intent``'s gestures, else ``situation`` (no intents named)."""
    clause = nomotion.chosen_motion(text, st or structure.spans(text))
    if clause is None:
        return "situation", set()
    named = named_intents(clause)
    return ("order" if intent in named else "chosen"), named


def order_confidence(g: Grounding, named: set[str]) -> float:
    """How sure the head is of an order's intent: its probability among the gestures the order names, p(m) / the
    sum of p(n) over the named intents ("wave back" names greeting, farewell and beckoning; the head's reading
    chooses among them). The order has already answered whether to move, so "no behaviour" takes no mass."""
    from jgrounding.vocabulary import INTENTS

    if len(g.scores) != len(INTENTS):
        return g.confidence
    mass = sum(g.scores[INTENTS.index(m)] for m in named)
    return float(g.confidence / mass) if mass > 0 else 0.0


def reads_as_no_behaviour(text: str, g: Grounding) -> bool:
    """Whether the embedded head held ``g`` only because no behaviour is its most likely class (no caveat of
    :func:`jgrounding.semantics.embedded.caveats`): an order overrides that, the text names the gesture it wants."""
    from jgrounding.semantics.embedded import caveats

    return not g.confident and not g.no_motion and not caveats(text) and g.backend == "embedded"


@dataclasses.dataclass(frozen=True)
class OperatingPoint:
    """The thresholds of the decision: ``thresholds`` (the confidence an intent needs, per kind of :data:`KINDS`)
    and ``detector`` (the learned no-motion detector holds at p >= it); ``meta``: what it was fitted on."""

    thresholds: dict
    detector: float
    meta: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if set(self.thresholds) != set(KINDS):
            raise ValueError(
                f"thresholds must name every kind of text ({', '.join(KINDS)}), got {sorted(self.thresholds)}"
            )
        for k, t in (*self.thresholds.items(), ("detector", self.detector)):
            if not 0.0 <= float(t) <= 1.01:
                raise ValueError(f"threshold {k} must be in [0, 1.01] (1.01: never), got {t}")

    def to_json(self) -> str:
        payload = {"thresholds": {k: float(self.thresholds[k]) for k in KINDS}, "detector": float(self.detector)}
        return json.dumps({**payload, "costs": COSTS, "meta": self.meta}, indent=1, sort_keys=True) + "\n"


def read_point(path=None) -> OperatingPoint:
    """The operating point stored at ``path`` (default: the shipped one)."""
    from pathlib import Path

    path = Path(path or POINT_ASSET)
    if not path.exists():
        raise FileNotFoundError(f"{path} missing; regenerate it with `python -m tools.nomotion_frontier --write`")
    d = json.loads(path.read_text())
    return OperatingPoint(dict(d["thresholds"]), float(d["detector"]), d.get("meta", {}))


def fallback_point() -> OperatingPoint:
    """The head's calibrated threshold for every kind and the detector's own threshold: the decision as one
    threshold makes it (what a head without a fitted point gets)."""
    from jgrounding.semantics import head as semantic_head

    d = nomotion.detector()
    t = semantic_head.load().threshold
    return OperatingPoint(dict.fromkeys(KINDS, t), d.threshold if d else 1.01, {"fallback": True})


@functools.lru_cache(maxsize=1)
def point() -> OperatingPoint:
    """The shipped operating point, or (with a warning) :func:`fallback_point` when it was fitted for another head."""
    from jgrounding.semantics import head as semantic_head

    p = read_point()
    if semantic_head.made_for_another_head(
        p.meta,
        f"{POINT_ASSET.name} was fitted for head {{made}}, the shipped head is {{shipped}}: every kind of text uses the "
        "head's calibrated threshold until `python -m tools.nomotion_frontier --write` fits it again",
    ):
        return fallback_point()
    return p


def detector_at(p: OperatingPoint):
    """The shipped learned detector at ``p``'s threshold (None when it is off)."""
    d = nomotion.detector()
    return None if d is None else dataclasses.replace(d, threshold=p.detector)


def decide(
    text: str,
    g: Grounding,
    st: structure.Structure | None = None,
    vector=None,
    *,
    p: OperatingPoint | None = None,
    per_kind: bool = True,
) -> Grounding:
    """The grounding ``g`` of ``text`` acted on or held (see the module docstring).

    ``g``: the reducer's grounding with no confidence threshold applied (for the embedded head:
    ``ground_embedded_vectors(texts, threshold=0.0)``; its caveats and no-behaviour class already hold it);
    ``vector``: the text's sentence vector when the reducer computed it; ``p``: the operating point (default: the
    shipped one); ``per_kind``: apply the threshold per kind (False for backends whose confidence is on another
    scale than the head's, ``cues`` and ``mllm``, which keep their own thresholds)."""
    p = p or point()
    st = st or structure.spans(text)
    held = nomotion.apply(text, g, st, vector, learned=True, learned_detector=detector_at(p))
    if held.no_motion or not per_kind:
        return held
    k, named = kind(text, g.intent, st)
    if not held.confident and not (k == "order" and reads_as_no_behaviour(text, g)):
        return held
    conf = order_confidence(g, named) if k == "order" else g.confidence
    t = float(p.thresholds[k])
    if conf >= t:
        return dataclasses.replace(g, confident=True, reason="", confidence=round(conf, 4))
    reason = f"unsure which motion: {g.intent.replace('_', ' ')} at p = {conf:.2f}, below {t:.2f} for {KIND_WORDS[k]}"
    return dataclasses.replace(g, confident=False, reason=reason, confidence=round(conf, 4))


def cost(motion: bool, acted: bool, right: bool) -> float:
    """The cost (:data:`COSTS`) of one decision on one text: ``motion`` (the text calls for a motion), ``acted``,
    ``right`` (the intent acted on is the text's)."""
    if not motion:
        return COSTS["acted_no_motion"] if acted else 0.0
    if not acted:
        return COSTS["held_motion"]
    return 0.0 if right else COSTS["acted_wrong"]
