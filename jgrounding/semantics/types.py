"""The result of semantic reduction (Eq. 3): shared by every backend, imports nothing else of the package
but the vocabulary."""

from __future__ import annotations

import dataclasses

from jgrounding.vocabulary import INTENSITIES, INTENTS


@dataclasses.dataclass(frozen=True)
class Grounding:
    """The bounded tuple a text was reduced to, with how sure the reducer is."""

    intent: str
    intensity: str
    confidence: float
    backend: str
    confident: bool
    reason: str = ""
    scores: tuple = ()

    @property
    def intent_index(self) -> int:
        return INTENTS.index(self.intent)

    @property
    def intensity_index(self) -> int:
        return INTENSITIES.index(self.intensity)
