"""The deterministic 1-D CNN regressors of Table II (``*_cnn`` methods): one forward pass, no noise."""

from __future__ import annotations

import jax.numpy as jnp
from flax import nnx

from jgrounding.config import ModelConfig, SampleConfig, TrainConfig
from jgrounding.generators.networks import CNNRegressor


class Regressor:
    """Squared error to the demonstration; sampling is the network's output. Takes no context, no known
    controls, no null condition and no steps (:class:`jgrounding.generators.base.Generator`)."""

    sequence = True
    samplers = ("none",)  # one deterministic forward pass: none of the abilities below
    iterative = uses_context = inpaints = null_condition = flow_times = reflows = False

    def init(self, key, representation, num_controls: int, num_tendons: int, use_intensity: bool, config: ModelConfig):
        return CNNRegressor(
            representation.length(num_controls),
            use_intensity,
            representation.cnn_channels(config),
            num_tendons,
            config,
            rngs=nnx.Rngs(key),
        )

    def loss(self, model, batch, key, config: TrainConfig):
        del key, config  # deterministic
        return jnp.mean((model(batch["cond"], batch["intensity"]) - batch["target"]) ** 2)

    def sample(self, model, cond, intensity, key, dim: int, config: SampleConfig, *, known=None, context=None):
        del key, dim, config, known, context  # neither is ever given: inpaints and uses_context are False
        return model(cond, intensity)
