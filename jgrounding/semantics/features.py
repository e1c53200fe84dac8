"""The trained head's input features (:mod:`jgrounding.semantics.head`), one named pipeline per kind of head.

:data:`INPUTS` registers them by the name a head's config records (``HeadConfig.inputs``), each with its width
(computed here, once) and how it is computed. ``python -m tools.train_semantics`` compares heads over them
(docs/how_it_works.md, section 1); ``tuned`` ships:

- ``embedding``: the frozen sentence embedding (384);
- ``eq3``: the embedding and the cue-list reducer's evidence (:func:`jgrounding.semantics.cue_reducer.cue_features`:
  Eq. (3) intent scores and degree cues), the inputs of the first trained head (``assets/semantics/bench/head_v1/semantic_head_v1.npz``);
- ``structure``: the frozen encoder pooled four ways (the sentence, its chosen part, its rejected part, the quoted
  words; :mod:`jgrounding.semantics.structure`), the chosen part's Eq. (3) evidence, the rejected part's intent
  scores and the structure flags (:func:`structure_features`);
- ``tuned``: the same poolings from the encoder with its top layers trained with the head, and in place of the
  Eq. (3) similarities (they live in the frozen encoder's space) what the text names outright
  (:func:`tuned_extras`). Its encoder and head run as one compiled program (:meth:`jgrounding.semantics.head.Head.run_tuned`).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from jgrounding.semantics import structure
from jgrounding.semantics.conditioning import embed
from jgrounding.semantics.cue_reducer import (
    CUE_FEATURES,
    DEGREE_FEATURES,
    cue_features,
    degree_features,
    intent_scores,
    lexical,
)
from jgrounding.vocabulary import NUM_INTENTS

EMBED_DIM = 384  # the encoder's width (jgrounding.semantics.encoder.HIDDEN), not imported: that loads JAX
NUM_POOLS = 4  # the sentence, the chosen part, the rejected part, the quoted words
POOLED_FEATURES = NUM_POOLS * EMBED_DIM  # the poolings, first in the structure and tuned inputs
# Beside the poolings: the chosen part's Eq. (3) evidence, the rejected part's intent scores, the flags.
STRUCTURE_EXTRAS = CUE_FEATURES + NUM_INTENTS + structure.NUM_FLAGS
# Beside the tuned poolings: the chosen part's named actions and degree cues, the rejected part's named actions, then
# (from column TUNED_FLAGS_START of the extras) the flags.
TUNED_FLAGS_START = 2 * NUM_INTENTS + DEGREE_FEATURES
TUNED_EXTRAS = TUNED_FLAGS_START + structure.NUM_FLAGS


def embedding_features(texts) -> np.ndarray:
    """The ``embedding`` inputs ``(N, 384)``: the frozen sentence embedding."""
    return embed(list(texts))


def eq3_features(texts) -> np.ndarray:
    """The ``eq3`` inputs ``(N, 404)``: the sentence embedding (384) and its :func:`cue_features` (20)."""
    texts = list(texts)
    emb = embed(texts)
    return np.concatenate([emb, np.stack([cue_features(r, t) for r, t in zip(emb, texts)])], axis=1)


def structure_features(texts, batch_size: int = 64) -> np.ndarray:
    """The ``structure`` inputs ``(N, 4 * 384 + STRUCTURE_EXTRAS)``, one encoder pass per text.

    The frozen encoder's token states are pooled four ways (:func:`jgrounding.semantics.encoder.pool_ids`): the
    whole sentence, the chosen part (rejected spans left out), the rejected part and the quoted words (zero vectors
    when there are none); then :func:`cue_features` of the chosen part (Eq. (3) scores and degree cues, so a
    rejected "wildly" does not count), the Eq. (3) intent scores of the rejected part, and the structure flags
    (:data:`jgrounding.semantics.structure.FLAGS`). Batched and bucketed like :func:`encoder.embed`.
    """
    texts = list(texts)
    if not texts:
        return np.zeros((0, INPUTS["structure"].width), np.float32)
    structs = [structure.analyse(t) for t in texts]
    return structure_features_from(texts, structs, pooled_embeddings(texts, structs, batch_size))


def structure_features_from(texts, structs, pooled) -> np.ndarray:
    """:func:`structure_features` from the texts, their structures and :func:`pooled_embeddings`."""
    out = []
    for text, st, p in zip(texts, structs, pooled):
        chosen, rejected = st.chosen_text(text), st.rejected_text(text)
        rej_scores = intent_scores(p[2], rejected) if st.rejected else np.zeros(NUM_INTENTS)
        out.append(np.concatenate([p.reshape(-1), cue_features(p[1], chosen), rej_scores, st.flags]))
    return np.stack(out).astype(np.float32)


def tuned_features(head, texts) -> np.ndarray:
    """The ``tuned`` inputs ``(N, 4 * 384 + TUNED_EXTRAS)`` of ``head`` in two steps (its encoder's poolings, then
    :func:`tuned_extras`): what its one compiled program (:meth:`jgrounding.semantics.head.Head.run_tuned`)
    computes inside, for training, calibration and the nearest-neighbour tables."""
    texts = list(texts)
    structs = [structure.analyse(t) for t in texts]
    pooled = pooled_embeddings(texts, structs, params=head.encoder_params())
    extras = [tuned_extras(t, st) for t, st in zip(texts, structs)]
    return np.stack([np.concatenate([p.reshape(-1), x]) for p, x in zip(pooled, extras)]).astype(np.float32)


def tuned_extras(text: str, st) -> np.ndarray:
    """The non-encoder inputs of the tuned head ``(TUNED_EXTRAS,)``: the chosen part's named actions (16) and
    degree cues (4), the rejected part's named actions (16), the structure flags."""
    chosen = st.chosen_text(text)
    rejected = lexical(st.rejected_text(text)) if st.rejected else np.zeros(NUM_INTENTS, np.float32)
    return np.concatenate([lexical(chosen), degree_features(chosen), rejected, st.flags]).astype(np.float32)


def pooled_embeddings(texts, structs, batch_size: int = 64, params=None) -> np.ndarray:
    """The encoder's four poolings ``(N, 4, 384)`` of each text (see :func:`structure_features`); ``params``:
    encoder weights (default: the frozen MiniLM)."""
    from jgrounding.semantics import encoder

    params = params or encoder.load_params()
    pooled = np.zeros((len(texts), NUM_POOLS, encoder.HIDDEN), np.float32)
    for idx, ids, mask, pools in encoder_batches(texts, structs, batch_size):
        pooled[idx] = np.asarray(encoder.pool_ids(params, ids, mask, pools))[: len(idx)]
    return pooled


def encoder_batches(texts, structs, batch_size: int = 64):
    """Batches of the encoder's inputs: yields ``(idx, ids, mask, pools)``, the texts' indices and their token ids,
    attention mask ``(B, L)`` and the four span pools ``(B, 4, L)``.

    Texts are sorted by token count, so each batch is padded only to the bucket of its own longest text
    (:func:`jgrounding.semantics.encoder.bucket_length`) and to 1, 8 or ``batch_size`` rows: a text alone runs a
    ``(1, L)`` program with the shortest bucket that holds it. Padded positions are masked out of attention and
    pooling, so the bucket does not change the result (to float rounding)."""
    from jgrounding.semantics import encoder

    enc = encoder.tokenizer().encode_batch(list(texts))
    order = np.argsort([len(e.ids) for e in enc], kind="stable")
    for start in range(0, len(enc), batch_size):
        idx = order[start : start + batch_size]
        chunk = [enc[i] for i in idx]
        rows = next(b for b in (1, 8, batch_size) if b >= len(chunk))
        length = encoder.bucket_length(max(len(e.ids) for e in chunk))
        ids, mask = encoder.pad_rows(chunk, length, rows)
        pools = np.zeros((rows, NUM_POOLS, length), np.float32)
        pools[:, 0, 0] = 1.0  # padding rows
        for row, i in enumerate(idx):
            st = structs[i]
            pools[row] = encoder.span_pools(enc[i], [("except", st.rejected), st.rejected, st.quoted], length)
        yield idx, ids, mask, pools


@dataclasses.dataclass(frozen=True)
class Inputs:
    """One registered input pipeline of the head."""

    name: str
    width: int  # features per text: the head's input width
    compute: Callable  # (head, texts) -> (N, width) float32
    pools: int  # encoder poolings its encoder pass reads (0: the sentence embedding), for the warm-up
    one_program: bool = False  # the encoder and the head run as one compiled program (Head.run_tuned)


INPUTS = {
    spec.name: spec
    for spec in (
        Inputs("embedding", EMBED_DIM, lambda head, texts: embedding_features(texts), pools=0),
        Inputs("eq3", EMBED_DIM + CUE_FEATURES, lambda head, texts: eq3_features(texts), pools=0),
        Inputs(
            "structure",
            POOLED_FEATURES + STRUCTURE_EXTRAS,
            lambda head, texts: structure_features(texts),
            pools=NUM_POOLS,
        ),
        Inputs("tuned", POOLED_FEATURES + TUNED_EXTRAS, tuned_features, pools=NUM_POOLS, one_program=True),
    )
}


def inputs_named(name: str) -> Inputs:
    """The registered pipeline ``name``; ``ValueError`` naming the valid ones otherwise."""
    if name not in INPUTS:
        raise ValueError(f"unknown head inputs {name!r}; valid inputs: {', '.join(INPUTS)}")
    return INPUTS[name]


def head_inputs(head, texts) -> np.ndarray:
    """The input features ``(N, width)`` that ``head`` (:class:`jgrounding.semantics.head.Head`) was trained on."""
    return head.config.features.compute(head, texts)
