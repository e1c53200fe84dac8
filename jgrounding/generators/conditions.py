"""Semantic conditions (Sec. III-A, Table II's first column): what a generator is conditioned on.

:class:`TupleCondition` (E_m(m), E_z(z)): the intent's sentence embedding and a learned intensity embedding;
:class:`RawText`: the response text's own embedding. :func:`bound_condition` keeps any condition on or inside
the unit sphere before it reaches a network.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np


@dataclasses.dataclass(frozen=True)
class TupleCondition:
    """(E_m(m), E_z(z)): the intent's sentence embedding and a learned intensity embedding."""

    name: str = "tuple"
    use_intensity: bool = True
    needs_text: bool = False  # conditions come from the intent embeddings, not from response texts

    def examples(self, split, intent_emb: np.ndarray, text_emb, target: np.ndarray):
        """(condition ``(N, E)``, intensity ``(N,)``, target) of the records of ``split``."""
        del text_emb
        return intent_emb[split.intent], split.intensity, target

    def conditions(self, split, intent_emb: np.ndarray, text_emb) -> np.ndarray:
        """One evaluation condition per record of ``split`` (its intent's embedding)."""
        del text_emb
        return intent_emb[split.intent]


@dataclasses.dataclass(frozen=True)
class RawText:
    """The response text's own embedding (Table II's first row): no tuple, no intensity input."""

    name: str = "raw"
    use_intensity: bool = False
    needs_text: bool = True  # conditions are the embeddings of the records' response texts

    def examples(self, split, intent_emb, text_emb, target: np.ndarray):
        """One example per (record, text): ``text_emb (N, n_text, E)`` flattened, targets repeated."""
        del intent_emb
        if text_emb is None:
            raise ValueError("raw conditioning needs text embeddings of the records' response texts")
        n_text = text_emb.shape[1]
        return (
            text_emb.reshape(-1, text_emb.shape[-1]),
            np.repeat(split.intensity, n_text),
            np.repeat(target, n_text, axis=0),
        )

    def conditions(self, split, intent_emb, text_emb) -> np.ndarray:
        """One evaluation condition per record of ``split``: the embedding of its first response text."""
        del intent_emb
        if text_emb is None:
            raise ValueError("raw conditioning needs text embeddings of the records' response texts")
        return text_emb[:, 0] if text_emb.ndim == 3 else text_emb


TUPLE, RAW = TupleCondition(), RawText()

COND_NORM = 1.0  # sentence embeddings (MiniLM, mean-pooled and normalized) are unit vectors


def bound_condition(cond):
    """Conditions longer than a unit vector scaled back onto the unit sphere; every real one (an intent or a
    text embedding, norm 1, or the null condition 0) passes unchanged. Without it a condition of norm ~1e3
    (fuzzing) drives the integrated flow to overflow in 50 Euler steps; the gate would then refuse the
    non-finite output, but a sampler that cannot overflow is the better guarantee."""
    cond = jnp.asarray(cond, jnp.float32)
    norm = jnp.linalg.norm(cond, axis=-1, keepdims=True)
    return jnp.where(norm > COND_NORM * (1.0 + 1e-3), cond * (COND_NORM / jnp.maximum(norm, 1e-30)), cond)
