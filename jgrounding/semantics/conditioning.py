"""The generators' intent conditioning (Sec. III-C): E_m, the frozen ``(16, 384)`` intent embeddings.

E is our JAX MiniLM sentence encoder (:mod:`jgrounding.semantics.encoder`); E_m is E of each intent's label and
canonical description (:func:`intent_text`). The generators condition on E_m; it is shipped in
``jgrounding/assets/intent_embeddings.npz`` so training and sampling read the same vectors (``python -m jgrounding.semantics
--write-assets`` regenerates it). Text-conditioned variants (the ablations) condition on E of the texts themselves.
"""

from __future__ import annotations

import functools

import numpy as np

from jgrounding import vocabulary as voc
from jgrounding.io import asset
from jgrounding.vocabulary import INTENTS

ASSET = asset("intent_embeddings.npz")


def embed(texts) -> np.ndarray:
    """E: sentence embeddings ``(N, 384)`` float32 (our JAX MiniLM, imported on first use)."""
    from jgrounding.semantics import encoder

    return encoder.embed(texts)


def intent_text(intent: str) -> str:
    """The text E_m embeds: the intent's label and its canonical description d_m."""
    return f"{intent.replace('_', ' ')}: {voc.describe(intent)}"


def compute_intent_embeddings() -> np.ndarray:
    """E_m computed afresh: our encoder on each intent's :func:`intent_text` -> ``(16, 384)``."""
    return embed([intent_text(m) for m in INTENTS])


@functools.lru_cache(maxsize=1)
def intent_embeddings() -> np.ndarray:
    """The shipped, frozen E_m ``(16, 384)`` (jgrounding/assets/intent_embeddings.npz)."""
    if not ASSET.exists():
        raise FileNotFoundError(f"{ASSET} missing; regenerate with `python -m jgrounding.semantics --write-assets`")
    with np.load(ASSET) as f:
        e = f["intent_embeddings"]
        if tuple(str(x) for x in f["intents"]) != INTENTS:
            raise ValueError(f"{ASSET} was made for another vocabulary; regenerate it")
    return e.astype(np.float32)
