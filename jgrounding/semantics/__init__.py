"""Semantic reduction, Sec. III-A: an open-vocabulary response -> a bounded (intent, intensity) tuple.

Backends behind one :func:`ground`: ``embedded`` (our JAX MiniLM encoder and Eq. (3), offline; the
default) and ``mllm`` (an OpenAI-compatible server, Eq. (4), falling back to embedded).
``python -m jgrounding.semantics --write-assets`` regenerates ``assets/intent_embeddings.npz``.
"""

from __future__ import annotations

import argparse

import numpy as np

from jgrounding.semantics.embedded import (  # noqa: F401  (re-exported)
    ASSET, CONFIDENCE_THRESHOLD, MAX_CHARS, compute_intent_embeddings, embed, ground_embedded, intent_embeddings,
    intent_scores,
)
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENTS

BACKENDS = ("embedded", "mllm")


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
    try:  # the tokenizer (and any server) needs text that encodes as UTF-8
        text.encode("utf-8")
    except UnicodeEncodeError as e:
        raise ValueError(f"text is not valid Unicode: unpaired surrogate {text[e.start]!r} at position {e.start}; "
                         "give a str that encodes as UTF-8") from None
    if backend == "embedded":
        return ground_embedded(text)
    if backend == "mllm":
        from jgrounding.semantics import mllm

        return mllm.ground_mllm(text, **mllm_options)
    raise ValueError(f"unknown backend {backend!r}; valid backends: embedded, mllm")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="Semantic reduction utilities.")
    p.add_argument("--write-assets", action="store_true", help="regenerate assets/intent_embeddings.npz")
    p.add_argument("text", nargs="*")
    args = p.parse_args(argv)
    if args.write_assets:
        import io

        from jgrounding.io import write_atomic

        buf = io.BytesIO()
        np.savez(buf, intent_embeddings=compute_intent_embeddings(), intents=np.array(INTENTS))
        write_atomic(ASSET, buf.getvalue())
        print(f"wrote {ASSET}")
    for t in args.text:
        print(ground(t))
    return 0


