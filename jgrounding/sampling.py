"""The public sampler: ``jg.sample(key, intent, intensity, num_samples=1)`` -> ``(150, 4)`` / ``(K, 150, 4)``.

Loads the shipped pretrained Tuple + Spline + RF checkpoint (``assets/checkpoints/tuple_spline_rf``)
once per process, compiles one sampler per (sampler, S, K-bucket), and returns numpy float32
trajectories through the one safety gate (:func:`jgrounding.safety.emit`): inside [0, 1], slew-limited,
never NaN. Deterministic for a key.
"""

from __future__ import annotations

import functools
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding import checkpoints, flows, methods, safety
from jgrounding.vocabulary import intensity_index, intent_index

DEFAULT_CHECKPOINT = Path(__file__).resolve().parent.parent / "assets" / "checkpoints" / "tuple_spline_rf"
MAX_SAMPLES = 4096
_K_BUCKETS = (1, 8, 32, 128, 512, 4096)


@functools.lru_cache(maxsize=4)
def load(checkpoint: str | None = None):
    """(Trained for one seed, meta) from a checkpoint directory (cached)."""
    from jgrounding import semantics

    path = Path(checkpoint) if checkpoint else DEFAULT_CHECKPOINT
    meta = checkpoints.read_meta(path)
    method = meta.get("method")
    if method not in methods.METHODS:
        raise ValueError(f"checkpoint {path} names unknown method {method!r}")
    graphdef, params = methods.init(method, (0,), meta.get("num_controls", 4))
    params, meta = checkpoints.restore(path, params)
    trained = methods.Trained(method, graphdef, params, (0,), meta.get("num_controls", 4))
    return trained, semantics.intent_embeddings()


def _as_key(key):
    if isinstance(key, jax.Array) and jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        if key.shape != ():
            raise ValueError(f"key must be a single key, got shape {key.shape}")
        return key
    arr = np.asarray(key) if isinstance(key, (jax.Array, np.ndarray)) else None
    if arr is not None and arr.dtype == np.uint32 and arr.shape == (2,):
        return jax.random.wrap_key_data(jnp.asarray(arr))
    raise TypeError("key must be a typed key from jax.random.key(seed) or a raw uint32[2] key from "
                    f"jax.random.PRNGKey(seed); got {type(key).__name__}")


@functools.lru_cache(maxsize=32)
def _compiled(checkpoint, sampler, steps, k):
    trained, _ = load(checkpoint)
    fn = methods._generate_fn(trained.method, trained.graphdef, sampler, steps, trained.num_controls)
    return jax.jit(lambda params, cond, z, key: fn(params, cond, z, key[None])[0])


def sample(key, intent, intensity, num_samples: int = 1, *, sampler: str = "euler", steps: int = 50,
           checkpoint: str | None = None) -> np.ndarray:
    """Sample tendon actuation for an (intent, intensity) tuple (names or indices).

    Returns ``(150, 4)`` when ``num_samples == 1`` and ``(num_samples, 150, 4)`` otherwise, float32,
    inside [0, 1]. ``sampler``: euler | midpoint | rk4; ``steps``: S Euler steps (1..1000).
    """
    m, z = intent_index(intent), intensity_index(intensity)
    if isinstance(num_samples, bool) or not isinstance(num_samples, (int, np.integer)) \
            or not 1 <= num_samples <= MAX_SAMPLES:
        raise ValueError(f"num_samples must be an integer in 1..{MAX_SAMPLES}, got {num_samples!r}")
    if sampler not in flows.SAMPLERS:
        raise ValueError(f"unknown sampler {sampler!r}; valid: {', '.join(flows.SAMPLERS)}")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 1 <= steps <= 1000:
        raise ValueError(f"steps must be an integer in 1..1000, got {steps!r}")
    key = _as_key(key)
    trained, intent_emb = load(checkpoint)
    k = next(b for b in _K_BUCKETS if b >= num_samples)
    fn = _compiled(checkpoint, sampler, int(steps), k)
    cond = jnp.broadcast_to(jnp.asarray(intent_emb[m]), (k, intent_emb.shape[1]))
    u = fn(trained.params, cond, jnp.full((k,), z, jnp.int32), key)[:num_samples]
    u = safety.emit(u)
    return u[0] if num_samples == 1 else u
