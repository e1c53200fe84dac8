"""The compiled training chunk (jgrounding.training.loop.make_chunk): every seed runs its own program, the seeds
in threads (issue #37: Table II's training about 1.4x faster on 2 cores than under vmap), and what a seed gets is
its own computation, whatever the other seeds and the threads' order."""

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding.config import TrainConfig
from jgrounding.training import loop


def _states(num_seeds: int, cfg: TrainConfig):
    def init(seed):
        k = jax.random.key(seed)
        params = {"w": jax.random.normal(k, (6, 5)), "b": jnp.zeros(5)}
        return loop.init_state(params, jax.random.fold_in(k, 1), cfg)

    return jax.tree.map(lambda *x: jnp.stack(x), *[init(s) for s in range(num_seeds)])


def _step(cfg: TrainConfig):
    x = jax.random.normal(jax.random.key(9), (32, 6))
    y = jnp.sin(x @ jnp.arange(30.0).reshape(6, 5) / 10.0)

    def loss(params, idx, key):
        del key
        return jnp.mean((jnp.tanh(x[idx] @ params["w"] + params["b"]) - y[idx]) ** 2)

    return loop.make_step(loss, 32, cfg)


def test_each_seed_gets_exactly_its_own_run_and_the_vmapped_result():
    cfg = TrainConfig(steps=40, chunk=20, batch_size=4)
    step = _step(cfg)
    states = _states(3, cfg)
    out, losses = loop.make_chunk(step, 20)(states)
    assert losses.shape == (3, 20) and np.shape(out.step) == (3,)
    for i in range(3):  # one seed alone: bit for bit the same
        alone, alone_loss = loop.make_chunk(step, 20)(jax.tree.map(lambda x, i=i: x[i : i + 1], states))
        for a, b in zip(jax.tree.leaves(alone.params), jax.tree.leaves(out.params)):
            np.testing.assert_array_equal(np.asarray(a)[0], np.asarray(b)[i])
        np.testing.assert_array_equal(np.asarray(alone_loss)[0], np.asarray(losses)[i])
    vmapped, vloss = jax.jit(jax.vmap(lambda s: jax.lax.scan(step, s, None, length=20)))(states)
    for a, b in zip(jax.tree.leaves(vmapped.params), jax.tree.leaves(out.params)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(vloss), np.asarray(losses), rtol=1e-5, atol=1e-7)
    assert not np.array_equal(np.asarray(out.params["w"])[0], np.asarray(out.params["w"])[1])  # seeds differ


def test_train_runs_chunks_and_repeats_exactly():
    cfg = TrainConfig(steps=50, chunk=20, batch_size=4)
    seen = []
    a, la = loop.train(_states(2, cfg), _step(cfg), cfg, progress=False, on_chunk=lambda s, d: seen.append(d))
    b, lb = loop.train(_states(2, cfg), _step(cfg), cfg, progress=False)
    assert seen == [20, 40, 50] and la.shape == (2, 50)
    assert np.asarray(a.step).tolist() == [50, 50]
    for x, y in zip(jax.tree.leaves(a.params), jax.tree.leaves(b.params)):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
