"""Semantic reduction, Sec. III-A: an open-vocabulary response -> a bounded (intent, intensity) tuple.

Backends behind one :func:`ground`: ``embedded`` (offline, the default: a trained head over our JAX MiniLM
encoder, Eq. (3) with a learned mismatch and a confidence calibrated on the dev split), ``cues`` (the first,
cue-list reducer: Eq. (3) with cosine prototypes; the baseline) and ``mllm`` (an OpenAI-compatible server,
Eq. (4), falling back to embedded). A configured MLLM also takes over embedded groundings below the
confidence threshold. Every backend's grounding then passes the act/hold decision
(:mod:`jgrounding.semantics.decision`): the explicit no-motion decision (:mod:`jgrounding.semantics.nomotion`: a
text that rules the motion out, orders the trunk to keep still, is addressed to someone else or only describes
activity, or that the learned detector is confident calls for no motion, comes back held, ``no_motion`` its kind,
``reason`` why, whatever motion words it contains), then the confidence threshold of the text's kind (a text that
names its motion, one that chooses it in other words, a situation to interpret), which guards against a wrong
intent. Apps do not drive the trunk on a non-confident grounding unless forced: they fall back to
:data:`HOLD_STILL`.
``python -m jgrounding.semantics --write-assets`` regenerates ``jgrounding/assets/intent_embeddings.npz`` and
``jgrounding/assets/cue_prototypes.npz`` (the cue-list prototypes, so a fresh process does not embed them).
"""

from __future__ import annotations

import argparse

import numpy as np

from jgrounding.semantics.conditioning import (  # noqa: F401  (re-exported)
    ASSET,
    compute_intent_embeddings,
    embed,
    intent_embeddings,
)
from jgrounding.semantics.cue_reducer import (  # noqa: F401  (re-exported)
    CONFIDENCE_THRESHOLD,
    PROTOTYPES_ASSET,
    compute_prototypes,
    ground_cues,
    intent_scores,
)
from jgrounding.semantics.decision import decide as _decide
from jgrounding.semantics.embedded import (  # noqa: F401
    MAX_CHARS,
    ground_embedded,
    ground_embedded_many,
    ground_embedded_vectors,
)
from jgrounding.semantics.nomotion import sentence_vectors as _sentence_vectors
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENTS

# The neutral behaviour of the apps (CLI, interactive loop) when a grounding is not confident and not forced.
HOLD_STILL = "no motion; the trunk keeps its current command (at rest: every tendon command 0)"
BACKENDS = ("embedded", "cues", "mllm")


def mllm_configured(**mllm_options) -> bool:
    """Whether an MLLM endpoint is set (``url=`` or ``JGROUNDING_MLLM_URL``), so low confidence can escalate."""
    from jgrounding.semantics import mllm

    return bool(mllm.Config.from_env(url=mllm_options.get("url")).url)


def ground(text: str, *, backend: str = "embedded", escalate: bool = True, **mllm_options) -> Grounding:
    """Reduce an open-vocabulary response to a bounded (intent, intensity) tuple (Eq. 3 / Eq. 4).

    ``backend``: ``"embedded"`` (offline: trained head over MiniLM, default), ``"cues"`` (the first
    cue-list reducer, a baseline) or ``"mllm"`` (OpenAI-compatible server; falls back to embedded with a
    logged reason). Every grounding passes the act/hold decision (:func:`jgrounding.semantics.decision.decide`):
    a text the no-motion decision holds (the rule or the learned detector, which reads the embedded pass's sentence
    vector; the other backends pay one encoder pass for it) comes back ``confident=False`` with ``no_motion`` set
    and its reason, from every backend, and is not escalated; an embedded grounding below its kind of text's
    threshold comes back ``confident=False`` with the reason, and with ``escalate`` and an MLLM endpoint configured
    (``url=`` or ``JGROUNDING_MLLM_URL``) is asked of the MLLM instead.
    Empty or non-string input raises; nonsense returns ``confident=False`` with a reason.
    """
    text = _checked(text)
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; valid backends: {', '.join(BACKENDS)}")
    if backend == "cues":
        return _decide(text, ground_cues(text), per_kind=False)
    from jgrounding.semantics import mllm

    if backend == "mllm":
        return _decide(text, mllm.ground_mllm(text, **mllm_options), per_kind=False)
    (g,), vectors = ground_embedded_vectors([text], threshold=0.0)
    vector = None if vectors is None else vectors[0]
    g = _decide(text, g, vector=vector)
    if g.confident or g.no_motion or not escalate or not mllm_configured(**mllm_options):
        return g
    return _decide(text, mllm.ground_mllm(text, fallback=g, **mllm_options), vector=vector, per_kind=False)


def ground_many(texts, *, backend: str = "embedded") -> list[Grounding]:
    """:func:`ground` of many texts at once, offline (no escalation): one batched encoder pass for the
    ``embedded`` backend (the evaluation scripts use this), one text at a time for ``cues``.

    Each text is checked as :func:`ground` checks it and passes the same act/hold decision; the results are in
    the order given.
    """
    if isinstance(texts, str):
        raise TypeError("ground_many takes a sequence of strings; use ground(text) for one text")
    if backend not in ("embedded", "cues"):
        raise ValueError(f"unknown backend {backend!r} for ground_many; valid backends: embedded, cues")
    texts = [_checked(t) for t in texts]
    per_kind = backend == "embedded"
    if backend == "cues":
        groundings, vectors = [ground_cues(t) for t in texts], _sentence_vectors(texts) if texts else None
    else:
        groundings, vectors = ground_embedded_vectors(texts, threshold=0.0)
    if vectors is None:
        return [_decide(t, g, per_kind=per_kind) for t, g in zip(texts, groundings)]
    return [_decide(t, g, vector=v, per_kind=per_kind) for t, g, v in zip(texts, groundings, vectors)]


def warmup(max_tokens: int = 128) -> None:
    """Load the weights and compile (or load from the compilation cache) the shipped head's programs for every
    token bucket up to ``max_tokens``, so no later ``ground`` call waits for a compile (servers, benchmarks)."""
    from jgrounding.semantics import encoder
    from jgrounding.semantics import head as semantic_head

    head = semantic_head.load()
    if head.config.features.one_program:  # one program per bucket: the tuned encoder and the head together
        from jgrounding.semantics.embedded import warmup_tuned

        warmup_tuned(head, max_tokens)
    else:
        encoder.warmup(max_tokens, pools=head.config.features.pools)
    ground_embedded("warm up")


def _checked(text) -> str:
    if not isinstance(text, str):
        raise TypeError(f"text must be a str, got {type(text).__name__}")
    if not text.strip():
        raise ValueError("text is empty; give a response such as 'User seems sad; respond calmly'")
    if len(text) > MAX_CHARS:
        text = text[:MAX_CHARS]
    try:  # the tokenizer (and any server) needs text that encodes as UTF-8
        text.encode("utf-8")
    except UnicodeEncodeError as e:
        raise ValueError(
            f"text is not valid Unicode: unpaired surrogate {text[e.start]!r} at position {e.start}; "
            "give a str that encodes as UTF-8"
        ) from None
    return text


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="Semantic reduction utilities.")
    p.add_argument(
        "--write-assets",
        action="store_true",
        help="regenerate jgrounding/assets/intent_embeddings.npz and jgrounding/assets/cue_prototypes.npz",
    )
    p.add_argument("text", nargs="*")
    args = p.parse_args(argv)
    if args.write_assets:
        import io

        from jgrounding.io import write_atomic

        buf = io.BytesIO()
        np.savez(buf, intent_embeddings=compute_intent_embeddings(), intents=np.array(INTENTS))
        write_atomic(ASSET, buf.getvalue())
        print(f"wrote {ASSET}")
        buf = io.BytesIO()
        np.savez(buf, **compute_prototypes())
        write_atomic(PROTOTYPES_ASSET, buf.getvalue())
        print(f"wrote {PROTOTYPES_ASSET}")
    for t in args.text:
        print(ground(t))
    return 0
