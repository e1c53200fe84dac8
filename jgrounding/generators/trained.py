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
from jgrounding.config import MAX_SAMPLE_STEPS, NUM_CONTROLS, NUM_TENDONS, ModelConfig, SampleConfig
from jgrounding.generators import methods
from jgrounding.generators.base import Generator
from jgrounding.generators.conditions import bound_condition
from jgrounding.generators.encoding import decode, encode
from jgrounding.vocabulary import NUM_INTENSITIES


@dataclasses.dataclass(frozen=True)
class Trained:
    """Parameters of ``len(seeds)`` runs of one method (leading axis = seed) and what sampling them needs.

    ``sample_config``: the sampling defaults it was chosen with (e.g. the guidance w of a shipped model), and
    ``noise_scales`` the initial-noise temperature chosen for particular step counts (``experiments.ship``);
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
    def generator(self) -> Generator:
        """The method's generator; what it can do is declared on it (``inpaints``, ``uses_context``, ...)."""
        return self.spec.generator

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

    def settings(self, sampler=None, steps=SampleConfig.steps) -> tuple[str, int]:
        """The one check of sampling settings against this model's generator: ``(sampler, steps)`` with the
        generator's default sampler for None and ``steps`` 1 for a generator that takes none (a regressor);
        ``ValueError`` naming the valid samplers, or the valid steps 1..``MAX_SAMPLE_STEPS``."""
        valid = self.generator.samplers  # the first is the generator's default
        chosen = valid[0] if sampler is None else sampler
        if not isinstance(chosen, str) or chosen not in valid:
            raise ValueError(f"unknown sampler {sampler!r} for {self.method}; valid: {', '.join(valid)}")
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 1 <= steps <= MAX_SAMPLE_STEPS:
            raise ValueError(f"steps must be an integer in 1..{MAX_SAMPLE_STEPS}, got {steps!r}")
        return chosen, int(steps) if self.generator.iterative else 1

    def resolve(self, config: SampleConfig | None = None) -> SampleConfig:
        """``config`` (default: this model's own :attr:`sample_config`) checked by :meth:`settings` and filled
        in: what every sampling boundary (``jg.sample``, evaluation, the benches) does once before the
        compiled sampler, which checks nothing again. ``TypeError`` for anything but a :class:`SampleConfig`."""
        config = self.sample_config if config is None else config
        if not isinstance(config, SampleConfig):
            raise TypeError(f"config must be a jgrounding.config.SampleConfig, got {type(config).__name__}")
        sampler, steps = self.settings(config.sampler, config.steps)
        if (sampler, steps) == (config.sampler, config.steps) and type(config.steps) is int:
            return config
        return dataclasses.replace(config, sampler=sampler, steps=steps)

    def contexts(self, intent_emb, params=None):
        """The first-layer context rows of every (intent, intensity) tuple, ``(num_intents * 4, H)`` in
        intent-major order, for a tuple-conditioned generator that takes them (``Generator.uses_context``): what
        :meth:`actuation` would compute from the intent embeddings, once instead of on every call. ``None``
        for a method without them (regressors, raw-text conditioning)."""
        if not self.generator.uses_context or self.spec.condition.needs_text:
            return None
        params = self.seed_params(0) if params is None else params
        m, z = np.divmod(np.arange(len(intent_emb) * NUM_INTENSITIES), NUM_INTENSITIES)

        @jax.jit  # one program (a first jg.sample lowers it once instead of one per operation)
        def table(params, emb):
            return nnx.merge(self.graphdef, params).context(bound_condition(emb[m]), z)

        return table(params, jnp.asarray(intent_emb, jnp.float32))

    def actuation(
        self, key, cond, intensity, config: SampleConfig | None = None, *, params=None, start=None, context=None
    ):
        """Ungated actuation for a batch of conditions: the generator's sample decoded to [0, 1] and, for a
        spline method, reconstructed u = R(c). Pure: jit and vmap it (over ``params`` for several seeds).

        Args:
          key: one key for the batch; cond: condition embeddings ``(B, E)``; intensity: ``(B,)`` int32.
          config: sampler, steps, guidance and noise scale, already through :meth:`resolve` (default: this
            model's own :attr:`sample_config`, whose sampler None is the generator's default); nothing is
            checked here, inside the compiled sampler.
          params: one seed's parameters (default: the first seed's).
          start: ``(B, N_u)`` commands in [0, 1] or None. Given, the first Catmull-Rom control column is fixed
            to it by inpainting during the flow integration (:func:`flows.rf_sample`), so ``u[:, 0] == start``
            and the rest of the motion is generated from that state. Only for a method that can
            (:func:`methods.check_start_conditioning`, checked at the boundary).
          context: the conditions' precomputed first-layer rows ``(B, H)`` (rows of :meth:`contexts`), or
            None; given, ``cond`` is not read.
        Returns:
          u ``(B, 150, N_u)``, not yet through the safety gate (:meth:`sample` gates it).
        """
        s = self.spec
        config = self.sample_config if config is None else config
        model = nnx.merge(self.graphdef, self.seed_params(0) if params is None else params)
        cond = None if context is not None else bound_condition(cond)
        known = None
        if start is not None:
            # Flat layout of the targets: (N_u, P) row-major, so tendon j's first control is coordinate j * P.
            mask = (jnp.arange(self.dim) % self.num_controls) == 0
            known = mask, jnp.repeat(encode(jnp.asarray(start, jnp.float32)), self.num_controls, axis=-1)
        y = s.generator.sample(model, cond, intensity, key, self.dim, config, known=known, context=context)
        return s.representation.actuation(decode(y), s.generator.sequence, self.num_tendons, self.num_controls)

    def sample(self, key, cond, intensity, config: SampleConfig | None = None, **kwargs):
        """:meth:`actuation` (same arguments: ``params``, ``start``, ``context``) through the one safety gate
        (:func:`jgrounding.safety.make_safe`): ``(B, 150, N_u)`` inside the actuation bounds, slew-limited."""
        return safety.make_safe(self.actuation(key, cond, intensity, config, **kwargs))
