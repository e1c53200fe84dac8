"""The cue-list reducer (backend ``"cues"``, the first reducer): Eq. (3) literally, with the cue words of
:mod:`jgrounding.semantics.cues`; kept as the baseline, and its evidence is part of the trained head's inputs
(:mod:`jgrounding.semantics.features`).

    (m, z) = argmin_{m, z}  L_sem(r, d_{m,z}),   L_sem = (1 - cos(E(r), E(d_m)))  +  w_z |z - z_hat(r)| / 3

where E is our JAX MiniLM encoder (:mod:`jgrounding.semantics.encoder`), d_m the canonical description of intent
m together with its cue phrases (both part of the grounding specification C, never taken from any evaluation
set), and z_hat(r) in [0, 3] the intensity the text's degree cues call for: modifiers ("slightly", "clearly",
"wildly"), urgency, exclamation marks and capitals, combined with the embedding's similarity to the intensity
descriptions. The text checks at the end (:func:`english_fraction`, :func:`num_tokens`) serve the embedded reducer
too.
"""

from __future__ import annotations

import functools
import hashlib
import re

import numpy as np

from jgrounding import vocabulary as voc
from jgrounding.semantics.conditioning import ASSET, embed, intent_text
from jgrounding.semantics.cues import CUES, DEGREE, INTENSIFIERS, LEXICAL, NEGATION, NOT_SHOUTING
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENSITIES, INTENTS

PROTOTYPES_ASSET = ASSET.with_name("cue_prototypes.npz")
MAX_TOKENS = 256  # the encoder truncates here (all-MiniLM-L6-v2's max_seq_length)
CONFIDENCE_THRESHOLD = 0.35  # the cue-list reducer's threshold (the trained head ships its own, calibrated on dev)
MIN_SIMILARITY = 0.30  # best intent score under which nothing in spec C resembles the text
INTENSITY_WEIGHT = 0.6
LEXICAL_WEIGHT = 0.12  # how much naming an intent's action outright lowers its L_sem (once per intent)
DEGREE_FEATURES = 4  # width of :func:`degree_features`
CUE_FEATURES = len(INTENTS) + DEGREE_FEATURES  # width of :func:`cue_features`

_LEXICAL_RE = {m: re.compile(p, re.IGNORECASE) for m, p in LEXICAL.items()}
_NEGATION = re.compile(NEGATION, re.IGNORECASE)
_DEGREE_RE = [
    (level, w, re.compile(r"\b" + re.escape(w) + r"\b", re.IGNORECASE))
    for level, words in DEGREE.items()
    for w in words
]


def _prototype_texts() -> tuple[list[str], np.ndarray, list[str]]:
    texts = [[intent_text(m)] + CUES[m] for m in INTENTS]
    owner = np.repeat(np.arange(len(INTENTS)), [len(g) for g in texts])
    return (
        [t for group in texts for t in group],
        owner,
        [f"{z}: performed {voc.INTENSITY_DESCRIPTIONS[z]}" for z in INTENSITIES],
    )


def _prototypes_digest() -> str:
    intents, _, intensities = _prototype_texts()
    return hashlib.sha256("\n".join(intents + ["--"] + intensities).encode()).hexdigest()[:16]


def compute_prototypes() -> dict:
    """Embeddings of spec C: intent prototypes ``(K, 384)``, their owner intent ``(K,)``, the intensity
    descriptions ``(4, 384)`` and the digest of the texts they embed."""
    intents, owner, intensities = _prototype_texts()
    return {
        "prototypes": embed(intents),
        "owner": owner,
        "intensities": embed(intensities),
        "digest": np.array(_prototypes_digest()),
    }


@functools.lru_cache(maxsize=1)
def prototypes():
    """Embeddings of spec C, loaded once from ``jgrounding/assets/cue_prototypes.npz`` (computed when the asset is missing or
    was made from other cue texts): intent prototypes ``(K, 384)``, their owner ``(K,)``, intensities ``(4, 384)``."""
    if PROTOTYPES_ASSET.exists():
        with np.load(PROTOTYPES_ASSET) as f:
            if str(f["digest"]) == _prototypes_digest():
                return f["prototypes"], f["owner"], f["intensities"]
    p = compute_prototypes()
    return p["prototypes"], p["owner"], p["intensities"]


def degree_estimate(text: str) -> float | None:
    """Intensity level in [0, 3] called for by the text's degree cues, or None if it has none.

    Cues: degree words (a negated strong word, "nothing big", counts as subtle; an intensifier before a
    degree word pushes that word's level outward), exclamation marks and words in capitals.
    """
    votes = []
    spans = []
    # Substring presence is a cheap necessary condition for an ASCII text (case-insensitive matching of other
    # scripts can fold characters, so those read every pattern): most texts hold a few of the ~120 cue words.
    lower = text.lower() if text.isascii() else None
    for level, word, pattern in _DEGREE_RE:
        if lower is not None and word not in lower:
            continue
        for hit in pattern.finditer(text):
            if any(a <= hit.start() < b for a, b in spans):  # "a tiny bit" already counted, skip "a bit"
                continue
            spans.append((hit.start(), hit.end()))
            before = text[: hit.start()]
            if level >= 2 and _NEGATION.search(before):
                votes.append(0.0)
                continue
            prev = re.findall(r"[A-Za-z']+", before[-20:])
            if (
                word in INTENSIFIERS
                and re.match(r"\W+(\w+)", text[hit.end() :])
                and any(p.match(text, hit.end() + 1) for _, w, p in _DEGREE_RE if w not in INTENSIFIERS)
            ):
                continue  # "very" only strengthens the degree word after it
            if prev and prev[-1].lower() in INTENSIFIERS:
                level = 0.0 if level <= 1 else 3.0
            votes.append(float(level))
    bangs = text.count("!")
    if bangs:
        votes.append(3.0 if bangs >= 2 else 2.0)
    if shouts(text):
        votes.append(3.0)
    return float(np.mean(votes)) if votes else None


def shouts(text: str) -> bool:
    """Whether the text has two or more words in capitals (not :data:`jgrounding.semantics.cues.NOT_SHOUTING`)."""
    return len([w for w in re.findall(r"\b[A-Z]{2,}\b", text) if w not in NOT_SHOUTING]) >= 2


def num_tokens(text: str) -> int:
    """How many tokens the text has before the encoder truncates it at :data:`MAX_TOKENS`."""
    from jgrounding.semantics import encoder

    enc = encoder.tokenizer().encode(text)  # the tokenizer truncates; overflow says there was more
    return len(enc.ids) + sum(len(o.ids) for o in enc.overflowing)


def english_fraction(text: str) -> float:
    """The share of the text's letters that are ASCII (0 without letters)."""
    letters = [c for c in text if c.isalpha()]
    if not letters:
        return 0.0
    return sum(c.isascii() for c in letters) / len(letters)


def intent_scores(r: np.ndarray, text: str) -> np.ndarray:
    """Similarity of the response to each intent's part of spec C ``(16,)``: a soft maximum of the cosine
    to its prototypes plus ``LEXICAL_WEIGHT`` when the text names the intent's action."""
    e, owner, _ = prototypes()
    sims = e @ r
    scores = np.empty(len(INTENTS))
    for m in range(len(INTENTS)):
        s = sims[owner == m]
        # Soft maximum (temperature 0.05): close to the best prototype, rewards several matching ones.
        scores[m] = s.max() + 0.05 * np.log(np.mean(np.exp((s - s.max()) / 0.05)))
    lexical = np.array([bool(_LEXICAL_RE[m].search(text)) for m in INTENTS], dtype=float)
    return scores + LEXICAL_WEIGHT * lexical


def cue_features(r: np.ndarray, text: str) -> np.ndarray:
    """The cue-list reducer's evidence for one text ``(CUE_FEATURES,)`` = ``(20,)``: Eq. (3) intent scores (16) and degree cues
    (degree estimate / 3, whether there was one, exclamation marks / 3, shouting)."""
    return np.concatenate([intent_scores(r, text), degree_features(text)]).astype(np.float32)


def degree_features(text: str) -> np.ndarray:
    """Degree cues ``(DEGREE_FEATURES,)`` = ``(4,)``: degree estimate / 3, whether there was one, exclamation marks / 3, shouting."""
    cue = degree_estimate(text)
    return np.array(
        [
            1.0 / 3 if cue is None else cue / 3,
            float(cue is not None),
            min(text.count("!"), 3) / 3,
            float(shouts(text)),
        ],
        np.float32,
    )


def lexical(text: str) -> np.ndarray:
    """Which intents' actions the text names outright (:data:`jgrounding.semantics.cues.LEXICAL`) ``(16,)`` of 0/1."""
    return np.array([bool(_LEXICAL_RE[m].search(text)) for m in INTENTS], np.float32)


def ground_cues(text: str) -> Grounding:
    """Eq. (3) literally, with cue-list prototypes (the first embedded reducer, kept as a baseline and as
    features of the trained head): argmin over (m, z) of L_sem(r, d_{m,z}); see the module docstring."""
    _, _, inten = prototypes()
    r = embed([text])[0]
    intent_sim = intent_scores(r, text)
    cue = degree_estimate(text)
    emb_level = float(np.dot(np.arange(4), _softmax(inten @ r / 0.05)))
    # Degree words are the strong evidence; without any, lean on "moderate" and let the embedding nudge.
    z_hat = 0.8 * cue + 0.2 * emb_level if cue is not None else 0.7 * 1.0 + 0.3 * emb_level
    # Eq. (3): argmin over the tuple space M x Z of the semantic mismatch.
    loss = (1.0 - intent_sim)[:, None] + INTENSITY_WEIGHT * np.abs(np.arange(4)[None] - z_hat) / 3.0
    m, z = np.unravel_index(np.argmin(loss), loss.shape)
    top2 = np.sort(intent_sim)[-2:]
    margin = float(top2[1] - top2[0])
    # Sure only when the best intent is both similar in absolute terms and ahead of the runner-up.
    confidence = float(np.clip((top2[1] - MIN_SIMILARITY) / 0.25, 0.0, 1.0) * np.clip(margin / 0.06, 0.0, 1.0) ** 0.5)
    reasons = []
    if english_fraction(text) < 0.5:
        confidence *= 0.3
        reasons.append("mostly non-English text")
    words = re.findall(r"[A-Za-z]{2,}", text)
    if len(words) < 2:
        confidence *= 0.3
        reasons.append("too few words")
    named = [INTENTS[m] for m in range(len(INTENTS)) if _LEXICAL_RE[INTENTS[m]].search(text)]
    if len(named) >= 3:
        confidence *= 0.5
        reasons.append("names several behaviours: " + ", ".join(named))
    if top2[1] < MIN_SIMILARITY:
        reasons.append("no intent is similar to the text")
    if len(text) > 250 and num_tokens(text) > MAX_TOKENS:  # a token spans at least one character
        reasons.append(f"long text: only its first {MAX_TOKENS} tokens were read")
    confident = confidence >= CONFIDENCE_THRESHOLD and not reasons
    if not confident and not reasons:
        reasons.append("ambiguous between intents")
    return Grounding(
        intent=INTENTS[int(m)],
        intensity=INTENSITIES[int(z)],
        confidence=round(confidence, 4),
        backend="cues",
        confident=confident,
        reason="; ".join(reasons),
        scores=tuple(round(float(s), 4) for s in intent_sim),
    )


def _softmax(x):
    x = np.exp(x - x.max())
    return x / x.sum()
