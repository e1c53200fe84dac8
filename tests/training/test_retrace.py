"""Nothing is traced again per call (STYLE habit 5): the training chunk and the compiled sampler."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

import jgrounding as jg
from jgrounding import semantics, training
from jgrounding.config import SampleConfig
from jgrounding.evaluation import generate
from jgrounding.generators import methods
from jgrounding.generators.flows import RectifiedFlow
from jgrounding.training import trainer


def test_training_chunk_traces_once_across_repeated_chunks():
    traces = []

    def loss(params, idx, key):
        traces.append(1)  # runs only while JAX traces the step
        return jnp.mean((params[:, None] - idx.astype(jnp.float32)) ** 2)

    cfg = training.TrainConfig(steps=40, chunk=10)
    step = training.make_step(loss, 4, cfg)
    states = jax.vmap(lambda k: training.init_state(jnp.zeros(3), k, cfg))(jax.random.split(jax.random.key(0), 2))
    states, losses = training.train(states, step, cfg, progress=False)
    assert losses.shape == (2, 40) and int(states.step[0]) == 40
    assert len(traces) == 1  # 4 chunks, one trace


class CountingFlow(RectifiedFlow):
    traces = 0

    def sample(self, *args, **kwargs):
        CountingFlow.traces += 1
        return super().sample(*args, **kwargs)


def test_sampler_traces_once_across_calls(monkeypatch):
    lib = jg.load_library()
    name = "tuple_spline_rf"
    monkeypatch.setitem(methods.REGISTRY, name, dataclasses.replace(methods.REGISTRY[name], generator=CountingFlow()))
    tr = trainer.fit(name, lib, (0,), training.TrainConfig(steps=2, chunk=2), progress=False)
    emb = semantics.intent_embeddings()
    for i in range(3):  # new keys, conditions and intensities of the same shapes
        u = generate.generate(
            tr, emb[[i, i + 1]], np.array([i, 3 - i]), jax.random.key(i), num_samples=2, config=SampleConfig(steps=3)
        )
        assert u.shape == (1, 2, 2, 150, 4)
    assert CountingFlow.traces == 1
