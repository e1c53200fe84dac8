"""Batch generation for evaluation: every seed of a :class:`~jgrounding.generators.trained.Trained` sampled for
many conditions at once (``jit(vmap over seeds(Trained.sample))``), optionally split over a device mesh.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding.config import NUM_STEPS, SampleConfig
from jgrounding.generators.trained import Trained
from jgrounding.training import distributed


def generate(
    trained: Trained,
    cond: np.ndarray,
    intensity: np.ndarray,
    key,
    num_samples: int = 30,
    config: SampleConfig | None = None,
    *,
    batch: int = 640,
    mesh=None,
) -> np.ndarray:
    """u ``(num_seeds, N, K, 150, N_u)`` for conditions ``cond (N, E)``, ``intensity (N,)``, gated.

    ``config``: sampler, steps, guidance (default: the model's own :attr:`Trained.sample_config`).
    ``mesh``: a :func:`jgrounding.training.distributed.make_mesh` mesh; the flattened (condition x sample)
    batch is then split over its devices. ``batch`` is rounded up to a multiple of the device count;
    the noise depends on the batch layout, so the result equals the single-device run with that batch.
    """
    n = cond.shape[0]
    cond_k = jnp.repeat(jnp.asarray(cond, jnp.float32), num_samples, axis=0)
    inten_k = jnp.repeat(jnp.asarray(intensity, jnp.int32), num_samples, axis=0)
    fn = generate_fn(trained, trained.resolve(config), mesh)
    keys = jax.random.split(key, len(trained.seeds))
    params = trained.params
    if mesh is not None:
        batch = -(-batch // mesh.size) * mesh.size
        params = distributed.replicate(params, mesh)
    outs = []
    for i in range(0, n * num_samples, batch):
        sub = jax.vmap(lambda k: jax.random.fold_in(k, i))(keys)
        c, z = cond_k[i : i + batch], inten_k[i : i + batch]
        pad = batch - c.shape[0]
        c, z = jnp.pad(c, ((0, pad), (0, 0))), jnp.pad(z, (0, pad))
        if mesh is not None:
            (c, z), sub = distributed.shard((c, z), mesh), distributed.replicate(sub, mesh)
        outs.append(distributed.gather(fn(params, c, z, sub))[:, : batch - pad])
    u = np.concatenate(outs, axis=1)
    return u.reshape(len(trained.seeds), n, num_samples, NUM_STEPS, trained.num_tendons)


_GEN_CACHE: dict = {}


def generate_fn(trained: Trained, config: SampleConfig, mesh=None):
    """``jit(vmap over seeds(trained.sample))``: ``(params[S], cond (B, E), intensity (B,), keys[S]) -> u``;
    with a mesh the batch axis is split over its devices. Compiled once per (network, sizes, config, mesh)."""
    cache_key = (trained.method, id(trained.graphdef), trained.num_controls, trained.num_tendons, config, mesh)
    if cache_key not in _GEN_CACHE:

        def one(params, cond, inten, k):
            return trained.sample(k, cond, inten, config, params=params)

        fn = jax.vmap(one, in_axes=(0, None, None, 0))
        if mesh is None:
            _GEN_CACHE[cache_key] = jax.jit(fn)
        else:
            rep, split = distributed.sharding(mesh), distributed.sharding(mesh, distributed.AXIS)
            _GEN_CACHE[cache_key] = jax.jit(
                fn,
                in_shardings=(rep, split, split, rep),
                out_shardings=distributed.sharding(mesh, None, distributed.AXIS),
            )
    return _GEN_CACHE[cache_key]
