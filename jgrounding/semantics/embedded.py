"""Morphology-aligned semantic reduction (Sec. III-A): response text r -> bounded tuple (m, z), offline.

``ground_embedded`` (the default backend) is Eq. (3) with a learned mismatch: the trained head of
:mod:`jgrounding.semantics.head` over the features below, argmin over the 16 x 4 tuples of
-log p(m | r) - log p(z | r). ``ground_cues`` (backend ``"cues"``, the first reducer, kept as the baseline and
as features of the head) implements Eq. (3) literally with hand-written cue lists:

    (m, z) = argmin_{m, z}  L_sem(r, d_{m,z}),   L_sem = (1 - cos(E(r), E(d_m)))  +  w_z |z - z_hat(r)| / 3

where E is our JAX MiniLM encoder (:mod:`jgrounding.semantics.encoder`), d_m the canonical description of intent
m together with a few cue phrases per intent (both part of the grounding specification C, written
here, never taken from any evaluation set), and z_hat(r) in [0, 3] the intensity the text's degree
cues call for: modifiers ("slightly", "clearly", "wildly"), urgency, exclamation marks and capitals,
combined with the embedding's similarity to the intensity descriptions. ``backend="mllm"`` asks an
OpenAI-compatible server instead (:mod:`jgrounding.semantics.mllm`) and falls back to this one.

``intent_embeddings()`` is E_m of Sec. III-C: the frozen (16, 384) intent embeddings the generators
condition on, shipped in ``assets/intent_embeddings.npz`` (``python -m jgrounding.semantics
--write-assets`` regenerates it).
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

import numpy as np

from jgrounding import vocabulary as voc
from jgrounding.semantics.types import Grounding
from jgrounding.vocabulary import INTENSITIES, INTENTS

ASSET = Path(__file__).resolve().parents[2] / "assets" / "intent_embeddings.npz"
MAX_CHARS = 4000  # ground() reads at most this many characters
MAX_TOKENS = 256  # the encoder truncates here (all-MiniLM-L6-v2's max_seq_length)
CONFIDENCE_THRESHOLD = 0.35  # the cue-list reducer's threshold (the trained head ships its own, calibrated on dev)
MIN_SIMILARITY = 0.30  # best intent score under which nothing in spec C resembles the text
INTENSITY_WEIGHT = 0.6

# Cue phrases of the grounding specification C: action-centred ways people phrase each behaviour.
# Prototypes for Eq. (3) are the canonical description d_m plus these; never evaluation sentences.
CUES = {
    "greeting": [
        "say hello",
        "greet the user",
        "wave hi",
        "welcome them",
        "greet the person who just arrived",
        "give a friendly hello wave to the newcomer",
    ],
    "farewell": [
        "say goodbye",
        "wave farewell",
        "see you later",
        "bid farewell as they leave",
        "the user is leaving, wave bye",
        "send them off with a goodbye",
    ],
    "comforting": [
        "comfort the sad user",
        "console and soothe them gently",
        "pat them reassuringly",
        "respond calmly to sadness",
        "the user is upset or crying, reassure them with a soft touch",
        "stroke their shoulder to calm them down",
    ],
    "attentive_listening": [
        "listen carefully",
        "pay attention to what they say",
        "lean in and listen",
        "show I am listening",
        "stay still and attentive while the user talks",
        "hear them out quietly",
    ],
    "curiosity": [
        "investigate the object",
        "explore with interest",
        "sniff around curiously",
        "check out something new",
        "examine the unfamiliar thing",
        "probe and inspect what is there",
    ],
    "embracing": [
        "give a hug",
        "hug the user",
        "wrap around them warmly",
        "embrace them",
        "hold them close in a cuddle",
        "wrap the trunk around the person",
    ],
    "withdrawal": [
        "back off",
        "give them space",
        "move away",
        "retreat from the user",
        "pull back, they are uncomfortable",
        "retract away from the person",
    ],
    "coiling": [
        "curl up shyly",
        "feel shy and self-soothe",
        "coil up tightly",
        "hide bashfully",
        "curl into itself out of embarrassment",
        "tuck the trunk in, timid and nervous",
    ],
    "playful_swing": [
        "play around",
        "swing playfully",
        "be silly and bouncy",
        "dance to the music",
        "sway back and forth for fun",
        "swing like a pendulum to play with the kids",
    ],
    "nodding": [
        "nod yes",
        "agree",
        "acknowledge with a nod",
        "show understanding",
        "bob up and down to agree",
        "confirm that I understood",
    ],
    "refusing": [
        "say no",
        "refuse",
        "decline the request",
        "shake no",
        "that is not allowed, disagree",
        "reject the offer by shaking the trunk",
    ],
    "beckoning": [
        "invite them to come closer",
        "come here",
        "beckon the user over",
        "ask them to approach",
        "call the person over to us",
        "gesture for them to come near",
    ],
    "pointing": [
        "point at it",
        "show the direction",
        "indicate where it is",
        "point the way",
        "show them which way to go",
        "direct their attention to the object over there",
    ],
    "celebrating": [
        "celebrate",
        "cheer for the good news",
        "congratulate them joyfully",
        "trumpet with excitement",
        "celebrate the victory",
        "party because they succeeded",
    ],
    "resting": [
        "relax",
        "rest quietly",
        "stay calm and idle",
        "take a break and droop",
        "go to sleep",
        "nothing to do, settle down and hang loose",
    ],
    "offering": [
        "hand it over",
        "give them the object",
        "offer something",
        "pass it to them",
        "present the gift to the user",
        "hold out the item for them to take",
    ],
}

# Lexical cues of C: words that name an intent's action outright. A match lowers L_sem for that intent
# by LEXICAL_WEIGHT (once per intent), so the action verb outweighs the situation around it.
LEXICAL = {
    "greeting": r"hello|\bhi\b|greet\w*|welcom\w*|howdy",
    "farewell": r"goodbye|good-bye|\bbye\b|farewell|see you|leaving|send (?:them|him|her) off|depart\w*",
    "comforting": r"comfort\w*|console|consoling|sooth\w*|reassur\w*|\bpat\b|patting|stroke|stroking",
    "attentive_listening": r"listen\w*|attentive\w*|hear (?:them|him|her) out|pay attention",
    "curiosity": r"curious\w*|explor\w*|investigat\w*|sniff\w*|inspect\w*|examin\w*|\bprobe|probing",
    "embracing": r"\bhug\w*|embrac\w*|cuddl\w*|wrap\w* around",
    "withdrawal": r"back off|back away|pull back|retreat\w*|withdraw\w*|give (?:them|him|her) (?:some )?(?:space|room)|move away",
    "coiling": r"\bcoil\w*|curl (?:up|in|into)|curls? (?:the tip )?in(?:ward)?\b|\bshy\w*|bashful\w*|tuck\w* in",
    "playful_swing": r"playful\w*|\bswing\w*|\bsway\w*|bouncy|bounce|\bdanc\w*|pendulum",
    "nodding": r"\bnod\w*|\bagree\w*|acknowledg\w*|\bbob\w*",
    "refusing": r"\brefus\w*|declin\w*|shake no|shaking no|\breject\w*|say no\b|\bdisagree\w*",
    "beckoning": r"beckon\w*|come (?:here|closer|over|near)|come on over|wave (?:them|him|her) over|call (?:them|him|her) over",
    "pointing": r"\bpoint\w*|indicat\w*|direction|which way|show (?:them |him |her )?(?:where|the way)",
    "celebrating": r"celebrat\w*|congratulat\w*|\bcheer\w*|trumpet\w*|hooray|victory|\bparty\b",
    "resting": r"\brest\b|resting|\brelax\w*|\bdroop\w*|\bidle\b|\bnap\b|sleep\w*|settle down",
    "offering": r"\boffer\w*|hand (?:over|them|him|her|the)|\bgive (?:them|him|her) (?:the|a|their)|present (?:the|it)|hold out|\bpass (?:the|it)",
}
LEXICAL_WEIGHT = 0.12
_LEXICAL_RE = {m: re.compile(p, re.IGNORECASE) for m, p in LEXICAL.items()}

# Degree cues: words that pull the intensity estimate toward a level (0 subtle .. 3 emphatic).
DEGREE = {
    0: [
        "slightly",
        "slight",
        "subtly",
        "subtle",
        "barely",
        "a little",
        "a bit",
        "a tiny bit",
        "gently",
        "softly",
        "quietly",
        "small",
        "faint",
        "faintly",
        "tiny",
        "minimal",
        "hint",
        "lightly",
        "light",
        "discreet",
        "discreetly",
        "politely",
        "cautious",
        "cautiously",
        "modest",
        "mostly",
        "just a bit",
        "understated",
        "low-key",
        "restrained",
        "delicately",
        "tentatively",
        "briefly",
    ],
    1: [
        "calmly",
        "moderately",
        "normally",
        "comfortable",
        "relaxed",
        "steady",
        "somewhat",
        "moderate",
        "friendly",
        "simple",
        "simply",
        "casually",
        "some",
        "regular",
        "ordinary",
        "easy",
    ],
    2: [
        "clearly",
        "clear",
        "noticeably",
        "noticeable",
        "expressive",
        "big",
        "lively",
        "strongly",
        "strong",
        "warmly",
        "very",
        "really",
        "obvious",
        "obviously",
        "pronounced",
        "definitely",
        "firm",
        "firmly",
        "eagerly",
        "closely",
        "deliberate",
        "deliberately",
        "heartfelt",
        "tenderly",
        "fully",
        "plenty",
        "visibly",
        "energetic",
        "happily",
        "large",
    ],
    3: [
        "wildly",
        "wild",
        "emphatically",
        "emphatic",
        "enthusiastically",
        "extremely",
        "full energy",
        "as strongly as possible",
        "all out",
        "intensely",
        "intense",
        "huge",
        "ecstatic",
        "urgent",
        "urgently",
        "immediately",
        "overjoyed",
        "maximum",
        "fast and wide",
        "vigorously",
        "enormous",
        "exuberant",
        "biggest",
        "tightest",
        "hardest",
        "as hard as",
        "as far as possible",
        "as you can",
        "possible",
        "like crazy",
        "completely",
        "totally",
        "absolutely",
        "right now",
        "right away",
        "frantic",
        "frantically",
        "explosive",
        "over the top",
        "ever",
    ],
}
_NEGATION = re.compile(r"\b(?:not|no|nothing|never|without|don't|dont|avoid)\b(?:\W+\w+){0,2}\W+$", re.IGNORECASE)
_DEGREE_RE = [
    (level, w, re.compile(r"\b" + re.escape(w) + r"\b", re.IGNORECASE))
    for level, words in DEGREE.items()
    for w in words
]


def embed(texts) -> np.ndarray:
    """Sentence embeddings ``(N, 384)`` float32 (our JAX MiniLM)."""
    from jgrounding.semantics import encoder

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


PROTOTYPES_ASSET = ASSET.with_name("cue_prototypes.npz")


def _prototype_texts() -> tuple[list[str], np.ndarray, list[str]]:
    texts = _intent_texts()
    owner = np.repeat(np.arange(len(INTENTS)), [len(g) for g in texts])
    return (
        [t for group in texts for t in group],
        owner,
        [f"{z}: performed {voc.INTENSITY_DESCRIPTIONS[z]}" for z in INTENSITIES],
    )


def _prototypes_digest() -> str:
    import hashlib

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
    """Embeddings of spec C, loaded once from ``assets/cue_prototypes.npz`` (computed when the asset is missing or
    was made from other cue texts): intent prototypes ``(K, 384)``, their owner ``(K,)``, intensities ``(4, 384)``."""
    if PROTOTYPES_ASSET.exists():
        with np.load(PROTOTYPES_ASSET) as f:
            if str(f["digest"]) == _prototypes_digest():
                return f["prototypes"], f["owner"], f["intensities"]
    p = compute_prototypes()
    return p["prototypes"], p["owner"], p["intensities"]


_INTENSIFIERS = {"very", "really", "so", "extremely", "super", "incredibly"}


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
                word in _INTENSIFIERS
                and re.match(r"\W+(\w+)", text[hit.end() :])
                and any(p.match(text, hit.end() + 1) for _, w, p in _DEGREE_RE if w not in _INTENSIFIERS)
            ):
                continue  # "very" only strengthens the degree word after it
            if prev and prev[-1].lower() in _INTENSIFIERS:
                level = 0.0 if level <= 1 else 3.0
            votes.append(float(level))
    bangs = text.count("!")
    if bangs:
        votes.append(3.0 if bangs >= 2 else 2.0)
    shouted = [w for w in re.findall(r"\b[A-Z]{2,}\b", text) if w not in {"OK", "TV", "AI", "ID"}]
    if len(shouted) >= 2:
        votes.append(3.0)
    return float(np.mean(votes)) if votes else None


def _num_tokens(text: str) -> int:
    from jgrounding.semantics import encoder

    enc = encoder.tokenizer().encode(text)  # the tokenizer truncates; overflow says there was more
    return len(enc.ids) + sum(len(o.ids) for o in enc.overflowing)


def _english_fraction(text: str) -> float:
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
    """The cue-list reducer's evidence for one text ``(20,)``: Eq. (3) intent scores (16) and degree cues
    (degree estimate / 3, whether there was one, exclamation marks / 3, shouting)."""
    return np.concatenate([intent_scores(r, text), degree_features(text)]).astype(np.float32)


def degree_features(text: str) -> np.ndarray:
    """Degree cues ``(4,)``: degree estimate / 3, whether there was one, exclamation marks / 3, shouting."""
    cue = degree_estimate(text)
    shouted = [w for w in re.findall(r"\b[A-Z]{2,}\b", text) if w not in {"OK", "TV", "AI", "ID"}]
    return np.array(
        [
            1.0 / 3 if cue is None else cue / 3,
            float(cue is not None),
            min(text.count("!"), 3) / 3,
            float(len(shouted) >= 2),
        ],
        np.float32,
    )


def features(texts, use_eq3: bool = True) -> np.ndarray:
    """Inputs of the trained head ``(N, 404)``: embedding (384) + :func:`cue_features` (20), or ``(N, 384)``."""
    texts = list(texts)
    emb = embed(texts)
    if not use_eq3:
        return emb
    return np.concatenate([emb, np.stack([cue_features(r, t) for r, t in zip(emb, texts)])], axis=1)


NUM_POOLS = 4  # the sentence, the chosen part, the rejected part, the quoted words
STRUCTURE_FEATURES = NUM_POOLS * 384 + 20 + len(INTENTS)  # + structure.NUM_FLAGS


def structure_features(texts, batch_size: int = 64) -> np.ndarray:
    """Inputs of the structure-aware head ``(N, 1556 + NUM_FLAGS)``, one encoder pass per text.

    The encoder's token states are pooled four ways (:func:`jgrounding.semantics.encoder.pool_ids`): the whole
    sentence, the chosen part (rejected spans left out), the rejected part and the quoted words (zero vectors
    when there are none); then :func:`cue_features` of the chosen part (Eq. (3) scores and degree cues, so a
    rejected "wildly" does not count), the Eq. (3) intent scores of the rejected part, and the structure flags
    (:data:`jgrounding.semantics.structure.FLAGS`). Batched and bucketed like :func:`encoder.embed`.
    """
    from jgrounding.semantics import structure

    texts = list(texts)
    if not texts:
        return np.zeros((0, STRUCTURE_FEATURES + structure.NUM_FLAGS), np.float32)
    structs = [structure.analyse(t) for t in texts]
    return structure_features_from(texts, structs, pooled_embeddings(texts, structs, batch_size))


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


def predict_tuned_many(head, texts, batch_size: int = 64) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tuned head's probabilities of many texts (intent ``(N, 17)``, intensity ``(N, 4)``, reason ``(N, R)``):
    one compiled program per batch (:func:`jgrounding.semantics.head.predict_tuned`), the encoder and the head
    together, with the head's nearest-neighbour vote when it has one (:attr:`head.Head.knn`), so one text costs one
    dispatch."""
    from jgrounding.semantics import structure

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

    extras = np.zeros((1, head.config.num_features - NUM_POOLS * encoder.HIDDEN), np.float32)
    for length in encoder.BUCKETS:
        if length > max(max_tokens, encoder.BUCKETS[0]):
            break
        ids, mask = np.zeros((1, length), np.int32), np.ones((1, length), np.int32)
        pools = np.ones((1, NUM_POOLS, length), np.float32)
        for a in head.run_tuned(ids, mask, pools, extras):
            a.block_until_ready()


def structure_features_from(texts, structs, pooled, tuned: bool = False) -> np.ndarray:
    """:func:`structure_features` from the texts, their structures and :func:`pooled_embeddings`.

    ``tuned``: the inputs of the head trained with the encoder's top layers (:func:`tuned_extras`): the Eq. (3)
    similarities to the frozen encoder's prototypes are left out (a tuned encoder's embeddings no longer live
    in their space); what the text names outright (:data:`LEXICAL`) stays."""
    out = []
    for text, st, p in zip(texts, structs, pooled):
        if tuned:
            out.append(np.concatenate([p.reshape(-1), tuned_extras(text, st)]))
            continue
        chosen, rejected = st.chosen_text(text), st.rejected_text(text)
        rej_scores = intent_scores(p[2], rejected) if st.rejected else np.zeros(len(INTENTS))
        out.append(np.concatenate([p.reshape(-1), cue_features(p[1], chosen), rej_scores, st.flags]))
    return np.stack(out).astype(np.float32)


def lexical(text: str) -> np.ndarray:
    """Which intents' actions the text names outright (:data:`LEXICAL`) ``(16,)`` of 0/1."""
    return np.array([bool(_LEXICAL_RE[m].search(text)) for m in INTENTS], np.float32)


def tuned_extras(text: str, st) -> np.ndarray:
    """The non-encoder inputs of the tuned head ``(36 + NUM_FLAGS,)``: the chosen part's named actions (16) and
    degree cues (4), the rejected part's named actions (16), the structure flags."""
    chosen = st.chosen_text(text)
    rejected = lexical(st.rejected_text(text)) if st.rejected else np.zeros(len(INTENTS), np.float32)
    return np.concatenate([lexical(chosen), degree_features(chosen), rejected, st.flags]).astype(np.float32)


def _caveats(text: str) -> list[str]:
    """Reasons, independent of the model, why a text cannot be grounded with confidence."""
    reasons = []
    if _english_fraction(text) < 0.5:
        reasons.append("mostly non-English text")
    if not re.findall(r"[A-Za-z]{2,}", text):
        reasons.append("no words")
    if len(text) > 250 and _num_tokens(text) > MAX_TOKENS:  # a token spans at least one character
        reasons.append(f"long text: only its first {MAX_TOKENS} tokens were read")
    return reasons


def head_inputs(head, texts) -> np.ndarray:
    """The input features the shipped head was trained on, for a batch of texts."""
    if head.config.inputs == "structure":
        return structure_features(texts)
    if head.config.inputs == "tuned":
        from jgrounding.semantics import structure

        texts = list(texts)
        structs = [structure.analyse(t) for t in texts]
        pooled = pooled_embeddings(texts, structs, params=head.encoder_params())
        return structure_features_from(texts, structs, pooled, tuned=True)
    return features(texts, head.config.use_eq3)


def ground_embedded(text: str) -> Grounding:
    """Eq. (3) offline with the trained head (:mod:`jgrounding.semantics.head`): argmin over the 16 x 4 tuples
    of -log p(m | r) - log p(z | r); confident when p(m | r) reaches the threshold calibrated on dev and the
    text does not read as no behaviour. The reason says why a grounding is not acted on."""
    return ground_embedded_many([text])[0]


def ground_embedded_many(texts, head=None) -> list[Grounding]:
    """:func:`ground_embedded` of many texts at once (one batched, bucketed encoder pass); ``head``: a loaded
    :class:`jgrounding.semantics.head.Head` (default: the shipped one)."""
    from jgrounding.semantics import head as semantic_head

    texts = list(texts)
    if not texts:
        return []
    head = head or semantic_head.load()
    if head.config.inputs == "tuned":
        p_intent, p_intensity, p_why = predict_tuned_many(head, texts)
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
        reasons = _caveats(text)
        p_none = float(p_intent[i, semantic_head.NONE])
        if p_none > conf:
            why = "none"
            if p_why is not None:
                why = head.meta["reasons"][int(np.argmax(p_why[i]))]
            text_why = head.meta.get("reason_text", {}).get(why, "no behaviour requested")
            reasons.append(f"{text_why} (reads as no behaviour, p = {p_none:.2f})")
        if conf < head.threshold and not reasons:
            reasons.append(
                f"low confidence: {INTENTS[m].replace('_', ' ')} at p = {conf:.2f}, below the calibrated "
                f"threshold {head.threshold:.2f}"
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
    return out


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
    if _english_fraction(text) < 0.5:
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
    if len(text) > 250 and _num_tokens(text) > MAX_TOKENS:  # a token spans at least one character
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
