"""The one generator interface (issue #12): every Table II generator is ``init``, ``loss`` and ``sample``.

Like openpi's ``BaseModel`` (``compute_loss`` / ``sample_actions``): the method registry
(:mod:`jgrounding.generators.methods`) pairs a generator with a condition and an actuation representation, and
training, sampling and checkpoints call only these three functions, never a generator's name.
Implementations: ``methods.Regressor`` (the deterministic CNNs), ``flows.RectifiedFlow``,
``flows.DDPM``, and the one-step ``few_step.MeanFlow`` and ``few_step.Shortcut``. Shared types only; imports nothing from the package but the config.
"""

from __future__ import annotations

from typing import Protocol

import jax
from flax import nnx

from jgrounding.config import ModelConfig, SampleConfig, TrainConfig


class Representation(Protocol):
    """How actuation is represented as a network target (spline controls or the dense trajectory)."""

    def length(self, num_controls: int) -> int:
        """Sequence length L of the target: P controls or T steps."""

    def cnn_channels(self, config: ModelConfig) -> int:
        """Channels of a 1-D CNN over this target."""


class Generator(Protocol):
    """A generator of Table II. ``sequence``: its network reads and writes targets as ``(B, L, N_u)``
    sequences (the CNNs) instead of flat ``(B, N_u * L)`` vectors (the MLPs); ``iterative``: sampling
    takes steps S; ``samplers``: the sampler names it accepts, its default first."""

    sequence: bool
    iterative: bool
    samplers: tuple[str, ...]

    def init(
        self,
        key: jax.Array,
        representation: Representation,
        num_controls: int,
        num_tendons: int,
        use_intensity: bool,
        config: ModelConfig,
    ) -> nnx.Module:
        """The network, its parameters drawn from ``key``."""

    def loss(self, model: nnx.Module, batch: dict, key: jax.Array, config: TrainConfig) -> jax.Array:
        """Scalar training loss of a batch ``{"cond" (B, E), "intensity" (B,), "target" (B, ...)}`` (and
        ``"noise"`` (B, D) for coupled reflow pairs)."""

    def sample(
        self, model: nnx.Module, cond: jax.Array, intensity: jax.Array, key: jax.Array, dim: int, config: SampleConfig
    ) -> jax.Array:
        """Normalized targets ``(B, D)`` or ``(B, L, N_u)`` for conditions ``cond (B, E)``, ``intensity (B,)``;
        ``dim`` D = N_u * L is the flat target size. A generator whose network takes the condition as a
        first-layer context (``uses_context = True``: the flows and the few-step generators) also accepts
        ``context=`` rows ``(B, H)`` computed beforehand (:meth:`Trained.contexts`), and the flows ``known=``
        coordinates to inpaint."""
