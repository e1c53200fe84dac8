"""The embedded reducer (the default backend, Sec. III-A): response text r -> bounded tuple (m, z), offline.

``ground_embedded`` is Eq. (3) with a learned mismatch: the trained head of :mod:`jgrounding.semantics.head` over
its input features (:mod:`jgrounding.semantics.features`), argmin over the 16 x 4 tuples of -log p(m | r) - log p(z | r).
The shipped head is ``tuned``: the encoder with its tuned top layers and the head run as one compiled program per
batch (:func:`predict_tuned_many`). The cue-list reducer (backend ``"cues"``) is :mod:`jgrounding.semantics.cue_reducer`,
the generators' intent conditioning :mod:`jgrounding.semantics.conditioning`; ``backend="mllm"`` asks an
OpenAI-compatible server instead (:mod:`jgrounding.semantics.mllm`) and falls back to this one.
"""

from __future__ import annotations

import re

import numpy as np

from jgrounding.semantics import structure
from jgrounding.semantics.cue_reducer import MAX_TOKENS, english_fraction, num_tokens
from jgrounding.semantics.features import NUM_POOLS, TUNED_EXTRAS, encoder_batches, head_inputs, tuned_extras
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENSITIES, INTENTS

MAX_CHARS = 4000  # ground() reads at most this many characters


def predict_tuned_many(head, texts, batch_size: int = 64) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The tuned head's probabilities of many texts (intent ``(N, 17)``, intensity ``(N, 4)``, reason ``(N, R)``)
    and their sentence vectors ``(N, 384)`` (what the learned no-motion detector reads): one compiled program per
    batch (:func:`jgrounding.semantics.head.predict_tuned`), the encoder and the head together, with the head's
    nearest-neighbour vote when it has one (:attr:`head.Head.knn`), so one text costs one dispatch."""
    texts = list(texts)
    structs = [structure.analyse(t) for t in texts]
    extras = np.stack([tuned_extras(t, st) for t, st in zip(texts, structs)])
    out = None
    for idx, ids, mask, pools in encoder_batches(texts, structs, batch_size):
        x = np.zeros((len(ids), extras.shape[1]), np.float32)
        x[: len(idx)] = extras[idx]
        probs = head.run_tuned(ids, mask, pools, x)
        probs = [np.asarray(a)[: len(idx)] for a in probs]  # (3.8 us for three ready arrays; device_get: 28 us)
        if out is None:
            out = [np.zeros((len(texts), a.shape[1]), np.float32) for a in probs]
        for o, a in zip(out, probs):
            o[idx] = a
    return tuple(out)


def warmup_tuned(head, max_tokens: int = 128) -> None:
    """Compile (or load from the compilation cache) the tuned head's program for one text in every token bucket up
    to ``max_tokens``, so no later single-text ``ground`` waits for a compile."""
    from jgrounding.semantics import encoder

    extras = np.zeros((1, TUNED_EXTRAS), np.float32)
    for length in encoder.BUCKETS:
        if length > max(max_tokens, encoder.BUCKETS[0]):
            break
        ids, mask = np.zeros((1, length), np.int32), np.ones((1, length), np.int32)
        pools = np.ones((1, NUM_POOLS, length), np.float32)
        for a in head.run_tuned(ids, mask, pools, extras):
            a.block_until_ready()


def caveats(text: str) -> list[str]:
    """Reasons, independent of the model, why a text cannot be grounded with confidence."""
    reasons = []
    if english_fraction(text) < 0.5:
        reasons.append("mostly non-English text")
    if not re.findall(r"[A-Za-z]{2,}", text):
        reasons.append("no words")
    if len(text) > 250 and num_tokens(text) > MAX_TOKENS:  # a token spans at least one character
        reasons.append(f"long text: only its first {MAX_TOKENS} tokens were read")
    return reasons


def ground_embedded(text: str) -> Grounding:
    """Eq. (3) offline with the trained head (:mod:`jgrounding.semantics.head`): argmin over the 16 x 4 tuples
    of -log p(m | r) - log p(z | r); confident when p(m | r) reaches the threshold calibrated on dev and the
    text does not read as no behaviour. The reason says why a grounding is not acted on."""
    return ground_embedded_many([text])[0]


def ground_embedded_many(texts, head=None) -> list[Grounding]:
    """:func:`ground_embedded` of many texts at once (one batched, bucketed encoder pass); ``head``: a loaded
    :class:`jgrounding.semantics.head.Head` (default: the shipped one)."""
    return ground_embedded_vectors(texts, head)[0]


def ground_embedded_vectors(
    texts, head=None, threshold: float | None = None
) -> tuple[list[Grounding], np.ndarray | None]:
    """:func:`ground_embedded_many` and the texts' sentence vectors ``(N, 384)`` from the same pass, which the
    learned no-motion detector reads (:func:`jgrounding.semantics.nomotion.apply`); None for a head that does not
    run as one program (no tuned encoder: its vectors are not the detector's). ``threshold``: the confidence below
    which a grounding is not acted on (None: the head's calibrated one; 0: none, only the caveats and the
    no-behaviour class hold, as :mod:`jgrounding.semantics.decision` wants it before its own threshold per kind of
    text)."""
    from jgrounding.semantics import head as semantic_head

    texts = list(texts)
    if not texts:
        return [], None
    head = head or semantic_head.load()
    threshold = head.threshold if threshold is None else float(threshold)
    vectors = None
    if head.config.features.one_program:
        p_intent, p_intensity, p_why, vectors = predict_tuned_many(head, texts)
    else:
        x = head_inputs(head, texts)
        p_intent, p_intensity, p_why = (
            np.asarray(a) for a in semantic_head.predict_all(head.params, x, head.temperature)
        )
    p_why = p_why if "why_w" in head.params else None
    ms, zs, confs = semantic_head.decide(p_intent, p_intensity)
    out = []
    for i, text in enumerate(texts):
        m, z, conf = int(ms[i]), int(zs[i]), float(confs[i])
        reasons = caveats(text)
        p_none = float(p_intent[i, semantic_head.NONE])
        if p_none > conf:
            why = "none"
            if p_why is not None:
                why = head.meta["reasons"][int(np.argmax(p_why[i]))]
            text_why = head.meta.get("reason_text", {}).get(why, "no behaviour requested")
            reasons.append(f"{text_why} (reads as no behaviour, p = {p_none:.2f})")
        if conf < threshold and not reasons:
            reasons.append(
                f"low confidence: {INTENTS[m].replace('_', ' ')} at p = {conf:.2f}, below the calibrated "
                f"threshold {threshold:.2f}"
            )
        out.append(
            Grounding(
                intent=INTENTS[m],
                intensity=INTENSITIES[z],
                confidence=round(conf, 4),
                backend="embedded",
                confident=not reasons,
                reason="; ".join(reasons),
                scores=tuple(round(float(p), 4) for p in p_intent[i, : len(INTENTS)]),
            )
        )
    return out, vectors
