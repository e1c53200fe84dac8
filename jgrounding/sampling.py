"""The public sampler: ``jg.sample(key, intent, intensity, num_samples=1)`` -> ``(150, 4)`` / ``(K, 150, 4)``.

Loads the shipped pretrained Tuple + Spline + RF checkpoint (``assets/checkpoints/tuple_spline_rf``)
once per process, compiles one sampler per (sampler, S, K-bucket), and returns numpy float32
trajectories through the one safety gate (:func:`jgrounding.safety.emit`): inside [0, 1], slew-limited,
never NaN. Deterministic for a key.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding import flows, methods, safety
from jgrounding.vocabulary import INTENSITIES, INTENTS, intensity_index, intent_index

DEFAULT_CHECKPOINT = Path(__file__).resolve().parent.parent / "assets" / "checkpoints" / "tuple_spline_rf"
MAX_SAMPLES = 4096
_K_BUCKETS = (1, 8, 32, 128, 512, 4096)


@functools.lru_cache(maxsize=4)
def load(checkpoint: str | None = None):
    """(Trained for one seed, intent embeddings ``(16, 384)``) from a checkpoint directory (cached).

    Refuses (``ValueError`` naming the directory) a checkpoint of an unknown method, another
    vocabulary, wrong array shapes or non-finite weights (:func:`jgrounding.methods.restore`), and one whose
    model fails a self-test: one sample of the first tuple must be a finite ``(150, 4)`` trajectory.
    """
    from jgrounding import semantics

    if checkpoint is not None and not isinstance(checkpoint, (str, Path)):
        raise TypeError(f"checkpoint must be a directory path (str or pathlib.Path), got {type(checkpoint).__name__}")
    path = Path(checkpoint) if checkpoint else DEFAULT_CHECKPOINT
    check_library(path)
    trained = methods.restore(path)
    if len(trained.seeds) > 1:  # an ablation checkpoint: sample with its first seed
        trained = dataclasses.replace(trained, params=jax.tree.map(lambda x: x[:1], trained.params),
                                      seeds=trained.seeds[:1])
    intent_emb = semantics.intent_embeddings()
    _self_test(path, trained, intent_emb)
    return trained, intent_emb


def _self_test(path: Path, trained, intent_emb) -> None:
    """Sample tuple (0, 0) once with the default sampler (the executable the first ``sample`` reuses)."""
    fn = methods._generate_fn(trained.method, trained.graphdef, "euler", 50, trained.num_controls,
                              num_tendons=trained.num_tendons)
    u = np.asarray(fn(trained.params, jnp.asarray(intent_emb[:1]), jnp.zeros((1,), jnp.int32),
                      jax.random.key(0)[None]))
    shape = (1, 1, methods.T, trained.num_tendons)
    if u.shape != shape or not np.all(np.isfinite(u)):
        bad = "non-finite values" if u.shape == shape else f"shape {u.shape}"
        raise ValueError(f"checkpoint {path} failed its load self-test: a sample of "
                         f"({INTENTS[0]}, {INTENSITIES[0]}) has {bad}; refusing to use it")


def check_library(path: Path) -> None:
    """Refuse a checkpoint whose recorded library file (``library_path`` in its meta.json, written by
    ``experiments.train``) exists but no longer has the sha256 the checkpoint was trained on."""
    from jgrounding import checkpoints, library

    meta = checkpoints.read_meta(path) if (Path(path) / "meta.json").exists() else {}
    lib_path, digest = meta.get("library_path"), meta.get("library_sha256")
    if lib_path and digest and Path(lib_path).is_file() and library.file_hash(lib_path) != digest:
        raise ValueError(f"checkpoint {path} was trained on library {lib_path} with sha256 {digest[:12]}..., but that "
                         f"file now has sha256 {library.file_hash(lib_path)[:12]}...; retrain on the current library "
                         "(python -m experiments.train --library ...) or restore the library it was trained on")


def trained_tuples(checkpoint) -> tuple[tuple[int, int], ...] | None:
    """The (intent, intensity) tuples a checkpoint's library holds (``None``: all 64, or not recorded)."""
    from jgrounding import checkpoints

    path = Path(checkpoint) if checkpoint else DEFAULT_CHECKPOINT
    tuples = checkpoints.read_meta(path).get("tuples")
    if not tuples:
        return None
    return tuple((intent_index(t.split("/")[0]), intensity_index(t.split("/")[1])) for t in tuples)


def _as_key(key):
    accepted = "a typed key from jax.random.key(seed) or a raw uint32[2] key from jax.random.PRNGKey(seed)"
    if isinstance(key, jax.Array) and jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        if key.shape != ():
            raise ValueError(f"key must be a single key ({accepted}), got a key array of shape {key.shape}")
        return key
    arr = np.asarray(key) if isinstance(key, (jax.Array, np.ndarray)) else None
    if arr is not None and arr.dtype == np.uint32 and arr.shape == (2,):
        return jax.random.wrap_key_data(jnp.asarray(arr))
    got = f"{arr.dtype}{list(arr.shape)} array" if arr is not None else type(key).__name__
    raise TypeError(f"key must be {accepted}; got {got}")


def _compiled(checkpoint, sampler, steps):
    trained, _ = load(checkpoint)
    # The cached executable itself (not a jit around it), so the load self-test warms the default one;
    # it compiles once per K bucket.
    return methods._generate_fn(trained.method, trained.graphdef, sampler, steps, trained.num_controls,
                              num_tendons=trained.num_tendons)


def sample(key, intent, intensity, num_samples: int = 1, *, sampler: str = "euler", steps: int = 50,
           checkpoint: str | None = None) -> np.ndarray:
    """Sample tendon actuation for an (intent, intensity) tuple (names or indices).

    Returns ``(150, N_u)`` when ``num_samples == 1`` and ``(num_samples, 150, N_u)`` otherwise, float32,
    inside [0, 1]; N_u = 4 for the shipped checkpoint, else the number of tendons of the checkpoint's library.
    A ``checkpoint`` trained on a library without this tuple (an imported library covers only the tuples
    recorded) is refused with a ``ValueError`` listing its tuples. ``sampler``: euler | midpoint | rk4; ``steps``: S Euler steps (1..1000).
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
    covered = _covered(checkpoint)
    if covered is not None and (m, z) not in covered:
        names = ", ".join(f"{INTENTS[a]}/{INTENSITIES[b]}" for a, b in covered)
        raise ValueError(f"checkpoint {checkpoint} was trained on a library without ({INTENTS[m]}, {INTENSITIES[z]}); "
                         f"its tuples: {names}")
    k = next(b for b in _K_BUCKETS if b >= num_samples)
    fn = _compiled(checkpoint, sampler, int(steps))
    cond = jnp.broadcast_to(jnp.asarray(intent_emb[m]), (k, intent_emb.shape[1]))
    u = fn(trained.params, cond, jnp.full((k,), z, jnp.int32), key[None])[0, :num_samples]
    u = safety.emit(u, num_channels=trained.num_tendons)
    return u[0] if num_samples == 1 else u


@functools.lru_cache(maxsize=4)
def _covered(checkpoint):
    return trained_tuples(checkpoint)
