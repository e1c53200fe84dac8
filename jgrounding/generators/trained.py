"""A trained model owns its sampling: :class:`Trained` holds a method's network, its parameters (one leading
axis per training seed), its sizes, its sampling defaults and the identity of the library it learned from,
and :meth:`Trained.sample` turns conditions into gated actuation.

Like openpi's model (``sample_actions`` on the model itself): the public sampler
(:mod:`jgrounding.policy`), the evaluation's batch generation (:mod:`jgrounding.evaluation.generate`), the
physics-aware fine-tuning and the benches all call :meth:`Trained.actuation` / :meth:`Trained.sample` with a
:class:`~jgrounding.config.SampleConfig`, never the generator with loose arguments.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jgrounding import safety
from jgrounding.config import NUM_CONTROLS, NUM_TENDONS, ModelConfig, SampleConfig
from jgrounding.generators import methods
from jgrounding.vocabulary import NUM_INTENSITIES


@dataclasses.dataclass(frozen=True)
class Trained:
    """Parameters of ``len(seeds)`` runs of one method (leading axis = seed) and what sampling them needs.

    ``sample_config``: the sampling defaults it was chosen with (e.g. the guidance w of a shipped model), and
    ``noise_scales`` the initial-noise temperature chosen for particular step counts (issue #25);
    ``library``: the identity of the library it was trained on as its checkpoint records it
    (``version``, ``sha256``, ``path`` and ``tuples`` where known; empty for a model trained in memory)."""

    method: str
    graphdef: Any
    params: Any
    seeds: tuple[int, ...]
    num_controls: int = NUM_CONTROLS
    losses: Any = None
    num_tendons: int = NUM_TENDONS  # N_u of the library it was trained on
    model: ModelConfig = ModelConfig()  # network sizes (recorded in its checkpoints)
    sample_config: SampleConfig = SampleConfig()
    library: dict = dataclasses.field(default_factory=dict)
    noise_scales: dict = dataclasses.field(default_factory=dict)  # {steps: noise scale} recorded per step count

    @property
    def spec(self) -> methods.MethodSpec:
        return methods.spec(self.method)

    @property
    def dim(self) -> int:
        """Flat size D = N_u x L of the generator's target."""
        return self.num_tendons * self.spec.representation.length(self.num_controls)

    def seed_params(self, i: int = 0):
        """The parameters of seed position ``i`` (no seed axis)."""
        return jax.tree.map(lambda x: x[i], self.params)

    def first_seed(self) -> Trained:
        """This model restricted to its first seed (the seed axis kept, size 1)."""
        if len(self.seeds) == 1:
            return self
        return dataclasses.replace(self, params=jax.tree.map(lambda x: x[:1], self.params), seeds=self.seeds[:1])

    def noise_scale_for(self, steps: int) -> float:
        """The initial-noise scale for ``steps`` steps: the one recorded for the smallest listed step count >=
        ``steps`` (as the shipped routing), beyond the largest that of the largest; without per-step scales,
        :attr:`sample_config`'s."""
        if not self.noise_scales:
            return self.sample_config.noise_scale
        listed = sorted(self.noise_scales)
        return self.noise_scales[next((s for s in listed if s >= steps), listed[-1])]

    def resolve(self, config: SampleConfig | None = None) -> SampleConfig:
        """``config`` (default: this model's own :attr:`sample_config`) with the generator's default sampler
        filled in; ``ValueError`` naming the valid samplers for one this generator does not have."""
        config = self.sample_config if config is None else config
        valid = self.spec.generator.samplers  # the first is the generator's default
        if config.sampler is None:
            return dataclasses.replace(config, sampler=valid[0])
        if config.sampler not in valid:
            raise ValueError(f"unknown sampler {config.sampler!r} for {self.method}; valid: {', '.join(valid)}")
        return config

    def contexts(self, intent_emb, params=None):
        """The first-layer context rows of every (intent, intensity) tuple, ``(num_intents * 4, H)`` in
        intent-major order, for a tuple-conditioned generator that takes them (``uses_context``): what
        :meth:`actuation` would compute from the intent embeddings, once instead of on every call. ``None``
        for a method without them (regressors, raw-text conditioning)."""
        if not getattr(self.spec.generator, "uses_context", False) or self.spec.condition.needs_text:
            return None
        params = self.seed_params(0) if params is None else params
        m, z = np.divmod(np.arange(len(intent_emb) * NUM_INTENSITIES), NUM_INTENSITIES)

        @jax.jit  # one program (a first jg.sample lowers it once instead of one per operation)
        def table(params, emb):
            return nnx.merge(self.graphdef, params).context(methods.bound_condition(emb[m]), z)

        return table(params, jnp.asarray(intent_emb, jnp.float32))

    def actuation(
        self, key, cond, intensity, config: SampleConfig | None = None, *, params=None, start=None, context=None
    ):
        """Ungated actuation for a batch of conditions: the generator's sample decoded to [0, 1] and, for a
        spline method, reconstructed u = R(c). Pure: jit and vmap it (over ``params`` for several seeds).

        Args:
          key: one key for the batch; cond: condition embeddings ``(B, E)``; intensity: ``(B,)`` int32.
          config: sampler, steps and guidance (default: :attr:`sample_config`; :meth:`resolve`).
          params: one seed's parameters (default: the first seed's).
          start: ``(B, N_u)`` commands in [0, 1] or None. Given, the first Catmull-Rom control column is fixed
            to it by inpainting during the flow integration (:func:`flows.rf_sample`), so ``u[:, 0] == start``
            and the rest of the motion is generated from that state.
          context: the conditions' precomputed first-layer rows ``(B, H)`` (rows of :meth:`contexts`), or
            None; given, ``cond`` is not read.
        Returns:
          u ``(B, 150, N_u)``, not yet through the safety gate (:meth:`sample` gates it).
        """
        s, config = self.spec, self.resolve(config)
        model = nnx.merge(self.graphdef, self.seed_params(0) if params is None else params)
        cond = None if context is not None else methods.bound_condition(cond)
        extra = {} if context is None else {"context": context}
        if start is None:
            y = s.generator.sample(model, cond, intensity, key, self.dim, config, **extra)
        else:
            methods.check_start_conditioning(self.method)
            # Flat layout of the targets: (N_u, P) row-major, so tendon j's first control is coordinate j * P.
            mask = (jnp.arange(self.dim) % self.num_controls) == 0
            first = jnp.repeat(methods.encode(jnp.asarray(start, jnp.float32)), self.num_controls, axis=-1)
            y = s.generator.sample(model, cond, intensity, key, self.dim, config, known=(mask, first), **extra)
        return s.representation.actuation(methods.decode(y), s.generator.sequence, self.num_tendons, self.num_controls)

    def sample(self, key, cond, intensity, config: SampleConfig | None = None, **kwargs):
        """:meth:`actuation` (same arguments: ``params``, ``start``, ``context``) through the one safety gate
        (:func:`jgrounding.safety.make_safe`): ``(B, 150, N_u)`` inside the actuation bounds, slew-limited."""
        return safety.make_safe(self.actuation(key, cond, intensity, config, **kwargs))
