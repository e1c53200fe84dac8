"""The result of semantic reduction (Eq. 3): shared by every backend, imports nothing else of the package
but the vocabulary."""

from __future__ import annotations

import dataclasses

from jgrounding.vocabulary import INTENSITIES, INTENTS


@dataclasses.dataclass(frozen=True)
class Grounding:
    """The bounded tuple a text was reduced to, with how sure the reducer is. Act on it only when ``confident``;
    otherwise hold still and show ``reason``."""

    intent: str  # one of the 16 intents (the most likely, even when not acted on)
    intensity: str  # one of the 4 intensities
    confidence: float  # the probability of the intent given the text, calibrated on dev; mass on "no behaviour" lowers it (a text that names its motion: the probability among the gestures it names)
    backend: str  # embedded, cues, mllm, or "mllm (escalated)"
    confident: bool  # act on it: the text calls for a motion and confidence reaches its kind of text's threshold
    reason: str = ""  # when not confident, why, for a person: e.g. "words addressed to someone else (reads as no behaviour, p = 0.97)", "unsure which motion: nodding at p = 0.41, below 0.78 for a situation to interpret"
    scores: tuple = ()  # per-intent probabilities (embedded) or similarities (cues)
    no_motion: str = ""  # the no-motion decision that held it (jgrounding.semantics.nomotion.REASONS), or ""

    @property
    def intent_index(self) -> int:
        return INTENTS.index(self.intent)

    @property
    def intensity_index(self) -> int:
        return INTENSITIES.index(self.intensity)
