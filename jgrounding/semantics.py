"""Morphology-aligned semantic reduction (Sec. III-A): response text r -> bounded tuple (m, z).

The embedded backend implements Eq. (3) literally, offline:

    (m, z) = argmin_{m, z}  L_sem(r, d_{m,z}),   L_sem = (1 - cos(E(r), E(d_m)))  +  w_z |z - z_hat(r)| / 3

where E is our JAX MiniLM encoder (:mod:`jgrounding.encoder`), d_m the canonical description of intent
m together with a few cue phrases per intent (both part of the grounding specification C, written
here, never taken from any evaluation set), and z_hat(r) in [0, 3] the intensity the text's degree
cues call for: modifiers ("slightly", "clearly", "wildly"), urgency, exclamation marks and capitals,
combined with the embedding's similarity to the intensity descriptions. ``backend="mllm"`` asks an
OpenAI-compatible server instead (:mod:`jgrounding.mllm`) and falls back to this one.

``intent_embeddings()`` is E_m of Sec. III-C: the frozen (16, 384) intent embeddings the generators
condition on, shipped in ``assets/intent_embeddings.npz`` (``python -m jgrounding.semantics
--write-assets`` regenerates it).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import re
from pathlib import Path

import numpy as np

from jgrounding import vocabulary as voc
from jgrounding.vocabulary import INTENSITIES, INTENTS

ASSET = Path(__file__).resolve().parent.parent / "assets" / "intent_embeddings.npz"
MAX_CHARS = 4000
CONFIDENCE_THRESHOLD = 0.35
INTENSITY_WEIGHT = 0.6

# Cue phrases of the grounding specification C: how people phrase each behaviour.
CUES = {
    "greeting": ["say hello", "greet the user", "wave hi", "welcome them"],
    "farewell": ["say goodbye", "wave farewell", "see you later", "bid farewell as they leave"],
    "comforting": ["comfort the sad user", "console and soothe them gently", "pat them reassuringly", "respond calmly to sadness"],
    "attentive_listening": ["listen carefully", "pay attention to what they say", "lean in and listen", "show I am listening"],
    "curiosity": ["investigate the object", "explore with interest", "sniff around curiously", "check out something new"],
    "embracing": ["give a hug", "hug the user", "wrap around them warmly", "embrace them"],
    "withdrawal": ["back off", "give them space", "move away", "retreat from the user"],
    "coiling": ["curl up shyly", "feel shy and self-soothe", "coil up tightly", "hide bashfully"],
    "playful_swing": ["play around", "swing playfully", "be silly and bouncy", "dance to the music"],
    "nodding": ["nod yes", "agree", "acknowledge with a nod", "show understanding"],
    "refusing": ["say no", "refuse", "decline the request", "shake no"],
    "beckoning": ["invite them to come closer", "come here", "beckon the user over", "ask them to approach"],
    "pointing": ["point at it", "show the direction", "indicate where it is", "point the way"],
    "celebrating": ["celebrate", "cheer for the good news", "congratulate them joyfully", "trumpet with excitement"],
    "resting": ["relax", "rest quietly", "stay calm and idle", "take a break and droop"],
    "offering": ["hand it over", "give them the object", "offer something", "pass it to them"],
}

# Degree cues: words that pull the intensity estimate toward a level (0 subtle .. 3 emphatic).
DEGREE = {
    0: ["slightly", "subtly", "barely", "a little", "a bit", "gently", "softly", "quietly", "small", "faint",
        "tiny", "minimal", "hint", "lightly", "discreet"],
    1: ["calmly", "moderately", "normally", "comfortable", "relaxed", "steady", "modest", "somewhat", "moderate"],
    2: ["clearly", "noticeably", "expressive", "big", "lively", "strongly", "warmly", "very", "really", "obvious",
        "well toward", "pronounced", "definitely"],
    3: ["wildly", "emphatically", "enthusiastically", "extremely", "full energy", "as strongly as possible",
        "all out", "intensely", "huge", "ecstatic", "urgent", "immediately", "overjoyed", "maximum", "fast and wide"],
}


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


def embed(texts) -> np.ndarray:
    """Sentence embeddings ``(N, 384)`` float32 (our JAX MiniLM)."""
    from jgrounding import encoder

    return encoder.embed(texts)


def _intent_texts() -> list[list[str]]:
    return [[f"{m.replace('_', ' ')}: {voc.describe(m)}"] + CUES[m] for m in INTENTS]


def compute_intent_embeddings() -> np.ndarray:
    """E_m: our encoder on each intent's label + canonical description -> ``(16, 384)``."""
    return embed([t[0] for t in _intent_texts()])


@functools.lru_cache(maxsize=1)
def intent_embeddings() -> np.ndarray:
    """The shipped, frozen E_m ``(16, 384)`` (assets/intent_embeddings.npz)."""
    if not ASSET.exists():
        raise FileNotFoundError(f"{ASSET} missing; regenerate with `python -m jgrounding.semantics --write-assets`")
    with np.load(ASSET) as f:
        e = f["intent_embeddings"]
        if tuple(str(x) for x in f["intents"]) != INTENTS:
            raise ValueError(f"{ASSET} was made for another vocabulary; regenerate it")
    return e.astype(np.float32)


@functools.lru_cache(maxsize=1)
def _prototypes():
    texts = _intent_texts()
    flat = [t for group in texts for t in group]
    e = embed(flat)
    owner = np.repeat(np.arange(len(INTENTS)), [len(g) for g in texts])
    inten = embed([voc.INTENSITY_DESCRIPTIONS[z] for z in INTENSITIES])
    return e, owner, inten


def degree_estimate(text: str) -> float | None:
    """Intensity level in [0, 3] called for by the text's degree cues, or None if it has none."""
    low = text.lower()
    votes = []
    for level, words in DEGREE.items():
        for w in words:
            if re.search(r"\b" + re.escape(w) + r"\b", low):
                votes.append(level)
    bangs = text.count("!")
    if bangs:
        votes.append(min(3, 1.5 + bangs))
    letters = [c for c in text if c.isalpha()]
    if len(letters) > 8 and sum(c.isupper() for c in letters) / len(letters) > 0.6:
        votes.append(3)
    return float(np.mean(votes)) if votes else None


def _english_fraction(text: str) -> float:
    letters = [c for c in text if c.isalpha()]
    if not letters:
        return 0.0
    return sum(c.isascii() for c in letters) / len(letters)


def ground_embedded(text: str) -> Grounding:
    e, owner, inten = _prototypes()
    r = embed([text])[0]
    sims = e @ r
    intent_sim = np.array([sims[owner == m].max() for m in range(len(INTENTS))])
    cue = degree_estimate(text)
    emb_level = float(np.dot(np.arange(4), _softmax(inten @ r / 0.05)))
    z_hat = emb_level if cue is None else 0.75 * cue + 0.25 * emb_level
    # Eq. (3): argmin over the tuple space of the semantic mismatch.
    loss = (1.0 - intent_sim)[:, None] + INTENSITY_WEIGHT * np.abs(np.arange(4)[None] - z_hat)[None, :] / 3.0
    m, z = np.unravel_index(np.argmin(loss[0] if loss.ndim == 3 else loss), (len(INTENTS), 4))
    top2 = np.sort(intent_sim)[-2:]
    margin = float(top2[1] - top2[0])
    confidence = float(np.clip(2.0 * (top2[1] - 0.2) + 4.0 * margin, 0.0, 1.0))
    reasons = []
    if _english_fraction(text) < 0.5:
        confidence *= 0.3
        reasons.append("mostly non-English text")
    words = re.findall(r"[A-Za-z]{2,}", text)
    if len(words) < 2:
        confidence *= 0.3
        reasons.append("too few words")
    if top2[1] < 0.2:
        reasons.append("no intent is similar to the text")
    confident = confidence >= CONFIDENCE_THRESHOLD and not reasons
    if not confident and not reasons:
        reasons.append("ambiguous between intents")
    return Grounding(intent=INTENTS[int(m)], intensity=INTENSITIES[int(z)], confidence=round(confidence, 4),
                     backend="embedded", confident=confident, reason="; ".join(reasons),
                     scores=tuple(float(s) for s in intent_sim))


def _softmax(x):
    x = np.exp(x - x.max())
    return x / x.sum()


def ground(text: str, *, backend: str = "embedded", **mllm_options) -> Grounding:
    """Reduce an open-vocabulary response to a bounded (intent, intensity) tuple (Eq. 3 / Eq. 4).

    ``backend``: ``"embedded"`` (offline MiniLM, default) or ``"mllm"`` (OpenAI-compatible server;
    falls back to embedded with a logged reason). Empty or non-string input raises; nonsense returns
    ``confident=False`` with a reason.
    """
    if not isinstance(text, str):
        raise TypeError(f"text must be a str, got {type(text).__name__}")
    if not text.strip():
        raise ValueError("text is empty; give a response such as 'User seems sad; respond calmly'")
    if len(text) > MAX_CHARS:
        text = text[:MAX_CHARS]
    if backend == "embedded":
        return ground_embedded(text)
    if backend == "mllm":
        from jgrounding import mllm

        return mllm.ground_mllm(text, **mllm_options)
    raise ValueError(f"unknown backend {backend!r}; valid backends: embedded, mllm")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="Semantic reduction utilities.")
    p.add_argument("--write-assets", action="store_true", help="regenerate assets/intent_embeddings.npz")
    p.add_argument("text", nargs="*")
    args = p.parse_args(argv)
    if args.write_assets:
        import io

        from jgrounding.export import write_atomic

        buf = io.BytesIO()
        np.savez(buf, intent_embeddings=compute_intent_embeddings(), intents=np.array(INTENTS))
        write_atomic(ASSET, buf.getvalue())
        print(f"wrote {ASSET}")
    for t in args.text:
        print(ground(t))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
