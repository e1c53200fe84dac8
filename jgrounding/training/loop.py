"""Compiled training (Table I): AdamW 1e-3, batch 8, 10,000 steps; every seed at once (a compiled program per
seed, the seeds in threads; ``vmap`` over a device mesh).

``state, metrics = step(state, key)`` is one AdamW update on a random batch; :func:`train` runs it in
chunks of ``lax.scan`` (a progress bar advances per chunk, and a checkpoint can be written between
chunks so an interrupted run resumes and ends with the same parameters as an uninterrupted one).
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax

from jgrounding.config import TrainConfig
from jgrounding.training import distributed

SEED_THREADS = 8  # most seeds of one chunk run at once (make_chunk)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class TrainState:
    params: Any
    opt_state: Any
    step: jax.Array
    key: jax.Array
    ema: Any = None  # EMA of params when TrainConfig.ema_decay > 0, else None (no leaves)


def optimizer(config: TrainConfig) -> optax.GradientTransformation:
    return optax.adamw(config.learning_rate, weight_decay=config.weight_decay)


def make_step(loss_fn: Callable, num_examples: int, config: TrainConfig):
    """``loss_fn(params, batch_index (B,), key) -> scalar``; returns a pure ``step(state) -> (state, loss)``."""
    tx = optimizer(config)

    def step(state: TrainState, _=None):
        key, k_batch, k_loss = jax.random.split(state.key, 3)
        idx = jax.random.randint(k_batch, (config.batch_size,), 0, num_examples)
        loss, grads = jax.value_and_grad(loss_fn)(state.params, idx, k_loss)
        updates, opt_state = tx.update(grads, state.opt_state, state.params)
        params = optax.apply_updates(state.params, updates)
        ema = state.ema
        if config.ema_decay:
            # Warm-up (as in diffusers / timm): early on the average forgets the random initialization
            # fast; the decay reaches its set value after ~10 / (1 - decay) steps.
            d = jnp.minimum(config.ema_decay, (1.0 + state.step) / (10.0 + state.step))
            ema = jax.tree.map(lambda e, p: d * e + (1.0 - d) * p, state.ema, params)
        return TrainState(params, opt_state, state.step + 1, key, ema), loss

    return step


def init_state(params, key, config: TrainConfig) -> TrainState:
    ema = jax.tree.map(jnp.array, params) if config.ema_decay else None
    return TrainState(params, optimizer(config).init(params), jnp.zeros((), jnp.int32), key, ema)


def eval_params(state: TrainState):
    """The parameters a trained model is evaluated and shipped with: the EMA when it was kept."""
    return state.params if state.ema is None else state.ema


def make_chunk(step, length: int, mesh=None):
    """``(state[S]) -> (state[S], losses (S, length))``: ``length`` steps of every seed, compiled.

    Without a mesh each seed runs its own compiled ``scan(step)`` (one program for a single seed, compiled once),
    the seeds concurrently in threads: under ``vmap`` every matmul becomes a batched dot, which XLA's CPU backend
    runs slowly, and a training step of these small networks is a chain of small operations that one program
    leaves the second core idle between; per-seed programs in threads overlap them (Table II's five seeds train
    about 1.4x faster on 2 cores, ``docs/testing.md``). The result is the seeds' own computation, the same whatever
    the threads' order. On an accelerator, ``jit(vmap(scan(step)))``; with a ``mesh``, the same with the seed axis of
    the state and of the losses split over its devices.
    """

    def run(state):
        return jax.lax.scan(step, state, None, length=length)

    if mesh is not None:
        seeds = distributed.sharding(mesh, distributed.AXIS)
        return jax.jit(jax.vmap(run), in_shardings=(seeds,), out_shardings=(seeds, seeds))
    if jax.default_backend() != "cpu":  # an accelerator runs the batched program as one launch: keep vmap there
        return jax.jit(jax.vmap(run))
    one = jax.jit(run)
    compiled = {}

    def per_seed(states):
        num = int(np.shape(jax.tree.leaves(states)[0])[0])
        parts = [jax.tree.map(lambda x, i=i: x[i], states) for i in range(num)]
        if "program" not in compiled:  # compiled ahead of the threads, so they never compile it twice
            compiled["program"] = one.lower(parts[0]).compile()
        program = compiled["program"]
        if num == 1:
            outs = [program(parts[0])]
        else:
            with concurrent.futures.ThreadPoolExecutor(min(num, SEED_THREADS)) as pool:
                outs = list(pool.map(program, parts))
        return jax.tree.map(lambda *x: jnp.stack(x), *outs)

    return per_seed


def train(
    states: TrainState,
    step,
    config: TrainConfig,
    *,
    desc: str = "train",
    progress: bool = True,
    on_chunk: Callable | None = None,
    mesh=None,
) -> tuple[TrainState, jax.Array]:
    """Run ``config.steps`` updates (minus those already done) of vmapped ``states`` in compiled chunks.

    ``mesh`` (:func:`jgrounding.training.distributed.make_mesh`): the seeds are split over its devices, padded
    to a multiple of the device count with copies of seed 0 that are dropped again; ``on_chunk`` and
    the caller then receive the full, unpadded states on every process.
    """
    from tqdm import tqdm

    done = int(np.asarray(jax.device_get(states.step)).reshape(-1)[0])
    num_seeds = int(np.shape(states.step)[0])
    if mesh is not None:
        states = distributed.shard(distributed.pad_leading(states, mesh.size), mesh)

    def unpadded(tree):
        return tree if mesh is None else distributed.take_leading(distributed.gather(tree), num_seeds)

    losses = []
    chunk_fns = {}
    bar = tqdm(total=config.steps, initial=done, desc=desc, disable=not progress, unit="step", leave=False)
    while done < config.steps:
        n = min(config.chunk, config.steps - done)
        if n not in chunk_fns:
            chunk_fns[n] = make_chunk(step, n, mesh)
        states, loss = chunk_fns[n](states)
        losses.append(loss)
        done += n
        bar.update(n)
        bar.set_postfix(loss=f"{float(loss[:, -50:].mean()):.4f}")
        if on_chunk is not None:
            on_chunk(unpadded(states), done)
    bar.close()
    losses = jnp.concatenate(losses, axis=1) if losses else jnp.zeros((num_seeds, 0))
    if mesh is None:
        return states, losses
    return jax.tree.map(jnp.asarray, unpadded(states)), jnp.asarray(unpadded(losses))
