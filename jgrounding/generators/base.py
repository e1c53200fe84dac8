"""The one generator interface: every Table II generator is ``init``, ``loss`` and ``sample``.

Like openpi's ``BaseModel`` (``compute_loss`` / ``sample_actions``): the method registry
(:mod:`jgrounding.generators.methods`) pairs a generator with a condition and an actuation representation, and
training, sampling and checkpoints call only these three functions, never a generator's name.
Implementations: ``regressor.Regressor`` (the deterministic CNNs), and on the one flow base
``flows.ConditionalFlow``: ``flows.RectifiedFlow``, ``flows.DDPM`` and the one-step ``few_step.MeanFlow`` and
``few_step.Shortcut``. What a generator can do is declared once, as attributes of the protocol; the registry,
training, sampling and the server read them, never a generator's class. Shared types only; imports nothing
from the package but the config.
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
    """A generator of Table II and what it can do, each ability declared once here:

    - ``sequence``: its network reads and writes targets as ``(B, L, N_u)`` sequences (the CNNs) instead of
      flat ``(B, N_u * L)`` vectors (the MLPs);
    - ``iterative``: sampling takes steps S (``SampleConfig.steps``; otherwise it is one forward pass);
    - ``samplers``: the sampler names it accepts, its default first;
    - ``uses_context``: the condition enters its network as a first-layer context row, so ``sample`` takes
      ``context=`` rows computed beforehand (:meth:`jgrounding.generators.trained.Trained.contexts`);
    - ``inpaints``: ``sample`` takes ``known=`` coordinates and keeps them (start-conditioned sampling);
    - ``null_condition``: it can train a null condition (``TrainConfig.condition_dropout``), so
      classifier-free guidance (``SampleConfig.guidance``) applies;
    - ``flow_times``: its loss draws flow times (``TrainConfig.time_sampler`` applies);
    - ``reflows``: its loss trains on coupled (noise, data) pairs and its sampler is a deterministic ODE, so it
      can be reflowed (:func:`jgrounding.training.trainer.reflow`)."""

    sequence: bool
    iterative: bool
    samplers: tuple[str, ...]
    uses_context: bool
    inpaints: bool
    null_condition: bool
    flow_times: bool
    reflows: bool

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
        self,
        model: nnx.Module,
        cond: jax.Array | None,
        intensity: jax.Array,
        key: jax.Array,
        dim: int,
        config: SampleConfig,
        *,
        known: tuple[jax.Array, jax.Array] | None = None,
        context: jax.Array | None = None,
    ) -> jax.Array:
        """Normalized targets ``(B, D)`` or ``(B, L, N_u)`` for conditions ``cond (B, E)``, ``intensity (B,)``;
        ``dim`` D = N_u * L is the flat target size; ``config`` already resolved for this generator
        (:meth:`jgrounding.generators.trained.Trained.resolve`: nothing is checked here).

        ``known``: ``(mask (D,) or (B, D) bool, values (B, D))`` coordinates to keep (only where ``inpaints``).
        ``context``: the conditions' first-layer rows ``(B, H)`` (only where ``uses_context``); given, ``cond``
        is not read."""
