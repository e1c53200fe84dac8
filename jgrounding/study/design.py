"""The study's design (``study.toml``, read with :mod:`tomllib`): its conditions, its episodes and its
questionnaire, checked at the boundary with errors that name the field.

Conditions (Sec. IV-B; ``scripted`` is the paper's future work):

- ``av_only``: the audiovisual response only; the trunk holds still.
- ``trunk``: the motion jgrounding generates for the episode (:func:`jgrounding.sample`, its seed recorded).
- ``scripted``: a library demonstration of the same (intent, intensity) (:func:`jgrounding.load_library`,
  a training realization chosen by the episode's seed).

An episode is a response text (grounded by the server, as the CLI does) or an (intent, intensity) tuple, with
what the robot ``say``s on its audiovisual channel. Every participant sees every condition, one block per
condition, in a counterbalanced order (:mod:`jgrounding.study.latin`); a block plays all episodes, then the
participant answers the questionnaire once for that block.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import tomllib
from pathlib import Path

from jgrounding.vocabulary import INTENSITIES, INTENTS

CONDITIONS = ("av_only", "trunk", "scripted")

# The paper's six questionnaire dimensions (Sec. IV-B, Fig. 6) and the default wording of each item.
DIMENSIONS = (
    "naturalness",
    "appropriateness",
    "expressiveness",
    "perceived_safety",
    "engagement",
    "overall_satisfaction",
)
DEFAULT_WORDING = {
    "naturalness": "The robot's response felt natural.",
    "appropriateness": "The robot's response was appropriate to the situation.",
    "expressiveness": "The robot's response was expressive.",
    "perceived_safety": "I felt safe during the interaction.",
    "engagement": "The interaction was engaging.",
    "overall_satisfaction": "Overall, I was satisfied with the interaction.",
}
DEFAULT_LABELS = ("strongly disagree", "disagree", "neutral", "agree", "strongly agree")
POSITIVE_FROM = 4  # the paper's positive rating: 4 or 5 on the 5-point scale


class DesignError(ValueError):
    """A design file that is not a valid study design; the message names the field."""


@dataclasses.dataclass(frozen=True)
class Episode:
    """One interaction: a response ``text`` (grounded by the server) or an ``intent`` / ``intensity``."""

    say: str  # what the robot says (the audiovisual channel; shown to the operator)
    text: str | None = None  # a response text to ground; None: the tuple below
    intent: str | None = None
    intensity: str | None = None

    def label(self) -> str:
        return self.text if self.text is not None else f"({self.intent}, {self.intensity})"


@dataclasses.dataclass(frozen=True)
class Question:
    dimension: str  # a key: the analysis' and the database's name of the item
    wording: str  # what the participant reads


@dataclasses.dataclass(frozen=True)
class Design:
    """A within-subject study; the defaults are the paper's (two conditions, six 5-point Likert items)."""

    name: str = "study"
    conditions: tuple[str, ...] = ("av_only", "trunk")
    episodes: tuple[Episode, ...] = (
        Episode(say="Hello! It is nice to meet you.", intent="greeting", intensity="moderate"),
    )
    questions: tuple[Question, ...] = tuple(Question(d, DEFAULT_WORDING[d]) for d in DIMENSIONS)
    labels: tuple[str, ...] = DEFAULT_LABELS  # one per scale point, 1..len(labels)
    seed: int = 0  # with the participant, block and episode: each execution's seed
    sim: bool = True  # stream the simulated trunk's backbone (the online variant; the operator's page draws it)
    stall_s: float = 1.0  # a stream nobody acknowledges for this long glides to rest (jgrounding.serving.Stream)
    steps: int | None = None  # sampler steps (None: the model's default)

    @property
    def scale(self) -> int:
        return len(self.labels)

    @property
    def dimensions(self) -> tuple[str, ...]:
        return tuple(q.dimension for q in self.questions)

    @property
    def needs_model(self) -> bool:
        """Whether serving it needs the model: a ``trunk`` condition or a text to ground."""
        return "trunk" in self.conditions or any(e.text is not None for e in self.episodes)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def digest(self) -> str:
        """sha256 of the design's canonical JSON: a session is resumed only with the design it was run with."""
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode()).hexdigest()

    @classmethod
    def from_dict(cls, raw: dict) -> Design:
        """A design from a parsed TOML (or :meth:`to_dict`) map; :class:`DesignError` names what is wrong."""
        if not isinstance(raw, dict):
            raise DesignError(f"a design is a table, got {type(raw).__name__}")
        known = {"name", "conditions", "episodes", "questionnaire", "questions", "labels", "seed", "sim", "stall_s"}
        unknown = set(raw) - known - {"steps"}
        if unknown:
            raise DesignError(f"unknown design fields {sorted(unknown)}; known: {sorted(known | {'steps'})}")
        default = cls()
        name = raw.get("name", default.name)
        if not isinstance(name, str) or not name.strip() or len(name) > 100:
            raise DesignError(f"name must be a non-empty string of at most 100 characters, got {name!r}")
        conditions = _conditions(raw.get("conditions", list(default.conditions)))
        episodes = _episodes(raw.get("episodes"), default.episodes)
        questions, labels = _questionnaire(raw)
        seed = raw.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**31:
            raise DesignError(f"seed must be an integer in 0..2**31-1, got {seed!r}")
        sim = raw.get("sim", default.sim)
        if not isinstance(sim, bool):
            raise DesignError(f"sim must be true or false, got {sim!r}")
        stall_s = raw.get("stall_s", default.stall_s)
        if isinstance(stall_s, bool) or not isinstance(stall_s, (int, float)) or not 0.1 <= stall_s <= 60:
            raise DesignError(f"stall_s must be a number of seconds in 0.1..60, got {stall_s!r}")
        steps = raw.get("steps")
        if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or not 1 <= steps <= 100):
            raise DesignError(f"steps must be an integer in 1..100, got {steps!r}")
        return cls(name.strip(), conditions, episodes, questions, labels, seed, sim, float(stall_s), steps)


def _conditions(raw) -> tuple[str, ...]:
    if not isinstance(raw, list) or not 1 <= len(raw) <= len(CONDITIONS):
        raise DesignError(f"conditions must be a list of 1..{len(CONDITIONS)} of {', '.join(CONDITIONS)}; got {raw!r}")
    bad = [c for c in raw if c not in CONDITIONS]
    if bad or len(set(raw)) != len(raw):
        raise DesignError(f"conditions must be distinct names from {', '.join(CONDITIONS)}; got {raw!r}")
    return tuple(raw)


def _episodes(raw, default) -> tuple[Episode, ...]:
    if raw is None:
        return default
    if not isinstance(raw, list) or not raw:
        raise DesignError("episodes must be a non-empty array of tables ([[episodes]])")
    out = []
    for i, e in enumerate(raw):
        where = f"episodes[{i}]"
        if not isinstance(e, dict) or set(e) - {"say", "text", "intent", "intensity"}:
            raise DesignError(f"{where} must be a table with say and either text or intent/intensity, got {e!r}")
        text, intent, intensity = e.get("text"), e.get("intent"), e.get("intensity")
        if (text is None) == (intent is None):
            raise DesignError(f"{where}: give either text or intent (with intensity), not both or neither")
        if text is not None:
            if not isinstance(text, str) or not text.strip() or len(text) > 1000 or intensity is not None:
                raise DesignError(f"{where}.text must be a non-empty string of at most 1000 characters, alone")
        else:
            if intent not in INTENTS:
                raise DesignError(f"{where}.intent must be one of {', '.join(INTENTS)}; got {intent!r}")
            intensity = "moderate" if intensity is None else intensity
            if intensity not in INTENSITIES:
                raise DesignError(f"{where}.intensity must be one of {', '.join(INTENSITIES)}; got {intensity!r}")
        say = e.get("say", text)
        if not isinstance(say, str) or not say.strip():
            raise DesignError(f"{where}.say (what the robot says) must be a non-empty string")
        out.append(Episode(say, text, intent, intensity))
    return tuple(out)


def _questionnaire(raw: dict) -> tuple[tuple[Question, ...], tuple[str, ...]]:
    """``[questionnaire]`` with ``labels`` and ``[[questionnaire.items]]`` (dimension, wording); or a
    ``questions`` list as :meth:`Design.to_dict` writes it. The default: the paper's six items."""
    q = raw.get("questionnaire", {})
    if not isinstance(q, dict) or set(q) - {"items", "labels"}:
        raise DesignError("questionnaire must be a table with items and labels")
    items = q.get("items", raw.get("questions"))
    labels = q.get("labels", raw.get("labels", list(DEFAULT_LABELS)))
    if not isinstance(labels, list) or not 3 <= len(labels) <= 11 or not all(isinstance(x, str) for x in labels):
        raise DesignError(f"questionnaire.labels must be 3..11 strings, one per scale point; got {labels!r}")
    if len(labels) < POSITIVE_FROM + 1:
        raise DesignError(f"the positive-rating ratio counts ratings >= {POSITIVE_FROM}: give at least 5 labels")
    if items is None:
        return tuple(Question(d, DEFAULT_WORDING[d]) for d in DIMENSIONS), tuple(labels)
    if not isinstance(items, list) or not items:
        raise DesignError("questionnaire.items must be a non-empty array of tables with dimension and wording")
    out = []
    for i, item in enumerate(items):
        if not isinstance(item, dict) or not isinstance(item.get("dimension"), str):
            raise DesignError(f"questionnaire.items[{i}] needs a dimension (a name such as 'naturalness')")
        dim = item["dimension"]
        if not dim.replace("_", "").isalnum() or not dim.islower() or len(dim) > 40:
            raise DesignError(f"questionnaire.items[{i}].dimension must be lower_snake_case, got {dim!r}")
        wording = item.get("wording", DEFAULT_WORDING.get(dim))
        if not isinstance(wording, str) or not wording.strip():
            raise DesignError(f"questionnaire.items[{i}] ({dim}) needs its wording")
        out.append(Question(dim, wording))
    if len({q.dimension for q in out}) != len(out):
        raise DesignError("questionnaire dimensions must be distinct")
    return tuple(out), tuple(labels)


def load_design(path: str | Path) -> Design:
    """Read a ``study.toml``; :class:`DesignError` for a file that is not a valid design."""
    try:
        raw = tomllib.loads(Path(path).read_text())
    except OSError as e:
        raise DesignError(f"cannot read the design {path}: {e}") from None
    except tomllib.TOMLDecodeError as e:
        raise DesignError(f"{path} is not valid TOML: {e}") from None
    return Design.from_dict(raw)
