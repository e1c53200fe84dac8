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
    confidence: (
        float  # the probability of the intent given the text, calibrated on dev; mass on "no behaviour" lowers it
    )
    backend: str  # embedded, cues, mllm, or "mllm (escalated)"
    confident: bool  # act on it: confidence reaches the calibrated threshold and the text calls for a motion
    reason: str = ""  # when not confident, why, for a person: e.g. "words addressed to someone else (reads as no behaviour, p = 0.97)", "low confidence: nodding at p = 0.41, below the calibrated threshold 0.72"
    scores: tuple = ()  # per-intent probabilities (embedded) or similarities (cues)
    no_motion: str = ""  # the no-motion decision that held it (jgrounding.semantics.nomotion.REASONS), or ""

    @property
    def intent_index(self) -> int:
        return INTENTS.index(self.intent)

    @property
    def intensity_index(self) -> int:
        return INTENSITIES.index(self.intensity)
