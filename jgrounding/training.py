"""Compiled training (Table I): AdamW 1e-3, batch 8, 10,000 steps; seeds trained at once with vmap.

``state, metrics = step(state, key)`` is one AdamW update on a random batch; :func:`train` runs it in
chunks of ``lax.scan`` (a progress bar advances per chunk, and a checkpoint can be written between
chunks so an interrupted run resumes and ends with the same parameters as an uninterrupted one).
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable

import jax
import jax.numpy as jnp
import optax


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """Defaults are the paper's Table I."""

    steps: int = 10_000
    batch_size: int = 8
    learning_rate: float = 1e-3
    weight_decay: float = 1e-4
    chunk: int = 1_000  # steps per compiled chunk (progress / checkpoint granularity)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class TrainState:
    params: Any
    opt_state: Any
    step: jax.Array
    key: jax.Array


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
        return TrainState(params, opt_state, state.step + 1, key), loss

    return step


def init_state(params, key, config: TrainConfig) -> TrainState:
    return TrainState(params, optimizer(config).init(params), jnp.zeros((), jnp.int32), key)


def make_chunk(step, length: int):
    """``jit(vmap(scan(step)))`` over seeds: ``(state[S]) -> (state[S], losses (S, length))``."""

    def run(state):
        return jax.lax.scan(step, state, None, length=length)

    return jax.jit(jax.vmap(run))


def train(states: TrainState, step, config: TrainConfig, *, desc: str = "train", progress: bool = True,
          on_chunk: Callable | None = None) -> tuple[TrainState, jax.Array]:
    """Run ``config.steps`` updates (minus those already done) of vmapped ``states`` in compiled chunks."""
    from tqdm import tqdm

    done = int(jax.device_get(states.step).reshape(-1)[0])
    losses = []
    chunk_fns = {}
    bar = tqdm(total=config.steps, initial=done, desc=desc, disable=not progress, unit="step", leave=False)
    while done < config.steps:
        n = min(config.chunk, config.steps - done)
        if n not in chunk_fns:
            chunk_fns[n] = make_chunk(step, n)
        states, loss = chunk_fns[n](states)
        losses.append(loss)
        done += n
        bar.update(n)
        bar.set_postfix(loss=f"{float(loss[:, -50:].mean()):.4f}")
        if on_chunk is not None:
            on_chunk(states, done)
    bar.close()
    return states, (jnp.concatenate(losses, axis=1) if losses else jnp.zeros((1, 0)))
