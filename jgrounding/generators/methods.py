"""The method registry: *Semantic Condition + Actuation Representation + Generator*, and nothing else.

Table II's five methods are ``raw_dense_cnn``, ``tuple_dense_cnn``, ``tuple_spline_cnn``, ``tuple_spline_ddpm``
and ``tuple_spline_rf``. Tuple conditioning is (E_m(m), E_z(z)); raw conditioning is the response text's
embedding. Spline methods work on the N_u x P controls (normalized to [-1, 1]) and reconstruct u = R(c); dense
methods predict the 150 x N_u trajectory directly.

Beyond Table II, registered the same way: the one-step generators of issue #25 (``tuple_spline_meanflow``,
``tuple_spline_shortcut``: :data:`FEW_STEP`, :mod:`jgrounding.generators.few_step`) and the physics-aware RF
(``tuple_spline_rf_physics``: the RF fine-tuned on its own screened samples; its ``recipe`` names how
:mod:`jgrounding.training` makes it). :data:`METHODS` stays the five rows of Table II and :data:`ABLATION_ROWS`
what the ablation reports.

A trained model (parameters, sizes, sampling defaults, library identity) and its sampling live in
:mod:`jgrounding.generators.trained`; training and reflow in :mod:`jgrounding.training.trainer`; checkpoints in
:mod:`jgrounding.training.checkpoints`; batch generation for evaluation in :mod:`jgrounding.evaluation.generate`.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jgrounding.actuation import splines
from jgrounding.config import NUM_CONTROLS, NUM_STEPS, NUM_TENDONS, ModelConfig, SampleConfig, TrainConfig
from jgrounding.generators.base import Generator
from jgrounding.generators.few_step import MeanFlow, Shortcut
from jgrounding.generators.flows import DDPM, RectifiedFlow
from jgrounding.generators.networks import CNNRegressor

T = NUM_STEPS


class Regressor:
    """The deterministic 1-D CNN regressors of Table II: squared error to the demonstration."""

    sequence = True
    iterative = False
    samplers = ("none",)  # one deterministic forward pass

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

    def sample(self, model, cond, intensity, key, dim: int, config: SampleConfig):
        del key, dim, config
        return model(cond, intensity)


@dataclasses.dataclass(frozen=True)
class Spline:
    """Actuation as N_u x P Catmull-Rom controls, u = R(c) (Eq. ci)."""

    name: str = "spline"

    def length(self, num_controls: int) -> int:
        return num_controls

    def cnn_channels(self, config: ModelConfig) -> int:
        return config.cnn_channels

    def target(self, split, num_controls: int, sequence: bool) -> np.ndarray:
        c = (
            split.controls
            if num_controls == split.controls.shape[-1]
            else np.asarray(splines.fit(split.u, num_controls=num_controls))
        )  # (N, N_u, P)
        return np.swapaxes(c, -1, -2) if sequence else c.reshape(len(split), -1)

    def actuation(self, y, sequence: bool, num_tendons: int, num_controls: int):
        c = jnp.swapaxes(y, -1, -2) if sequence else y.reshape(y.shape[0], num_tendons, num_controls)
        return splines.reconstruct(c)


@dataclasses.dataclass(frozen=True)
class Dense:
    """Actuation as the T x N_u trajectory itself."""

    name: str = "dense"

    def length(self, num_controls: int) -> int:
        del num_controls
        return T

    def cnn_channels(self, config: ModelConfig) -> int:
        return config.dense_cnn_channels

    def target(self, split, num_controls: int, sequence: bool) -> np.ndarray:
        del num_controls
        return split.u if sequence else split.u.reshape(len(split), -1)

    def actuation(self, y, sequence: bool, num_tendons: int, num_controls: int):
        del num_controls
        return y if sequence else y.reshape(y.shape[0], T, num_tendons)


@dataclasses.dataclass(frozen=True)
class TupleCondition:
    """(E_m(m), E_z(z)): the intent's sentence embedding and a learned intensity embedding."""

    name: str = "tuple"
    use_intensity: bool = True
    needs_text: bool = False  # conditions come from the intent embeddings, not from response texts

    def examples(self, split, intent_emb: np.ndarray, text_emb, target: np.ndarray):
        """(condition ``(N, E)``, intensity ``(N,)``, target) of the records of ``split``."""
        del text_emb
        return intent_emb[split.intent], split.intensity, target

    def conditions(self, split, intent_emb: np.ndarray, text_emb) -> np.ndarray:
        """One evaluation condition per record of ``split`` (its intent's embedding)."""
        del text_emb
        return intent_emb[split.intent]


@dataclasses.dataclass(frozen=True)
class RawText:
    """The response text's own embedding (Table II's first row): no tuple, no intensity input."""

    name: str = "raw"
    use_intensity: bool = False
    needs_text: bool = True  # conditions are the embeddings of the records' response texts

    def examples(self, split, intent_emb, text_emb, target: np.ndarray):
        """One example per (record, text): ``text_emb (N, n_text, E)`` flattened, targets repeated."""
        del intent_emb
        if text_emb is None:
            raise ValueError("raw conditioning needs text embeddings of the records' response texts")
        n_text = text_emb.shape[1]
        return (
            text_emb.reshape(-1, text_emb.shape[-1]),
            np.repeat(split.intensity, n_text),
            np.repeat(target, n_text, axis=0),
        )

    def conditions(self, split, intent_emb, text_emb) -> np.ndarray:
        """One evaluation condition per record of ``split``: the embedding of its first response text."""
        del intent_emb
        if text_emb is None:
            raise ValueError("raw conditioning needs text embeddings of the records' response texts")
        return text_emb[:, 0] if text_emb.ndim == 3 else text_emb


TUPLE, RAW = TupleCondition(), RawText()


@dataclasses.dataclass(frozen=True)
class MethodSpec:
    """A registered method: *Semantic Condition + Actuation Representation + Generator*.

    ``recipe``: how :mod:`jgrounding.training` makes it (``"fit"``: trained from scratch on the library;
    ``"physics_finetune"``: fine-tunes the trained ``base`` method on its own screened samples)."""

    name: str
    display: str
    condition: TupleCondition | RawText
    representation: Spline | Dense
    generator: Generator
    recipe: str = "fit"
    base: str | None = None  # the method a fine-tuning recipe starts from

    @property
    def use_intensity(self) -> bool:
        return self.condition.use_intensity


REGISTRY = {
    s.name: s
    for s in (
        MethodSpec("raw_dense_cnn", "Raw + Dense + CNN", RAW, Dense(), Regressor()),
        MethodSpec("tuple_dense_cnn", "Tuple + Dense + CNN", TUPLE, Dense(), Regressor()),
        MethodSpec("tuple_spline_cnn", "Tuple + Spline + CNN", TUPLE, Spline(), Regressor()),
        MethodSpec("tuple_spline_ddpm", "Tuple + Spline + DDPM", TUPLE, Spline(), DDPM()),
        MethodSpec("tuple_spline_rf", "Tuple + Spline + RF", TUPLE, Spline(), RectifiedFlow()),
        # Beyond Table II: one-step generators (issue #25, generators/few_step.py)
        MethodSpec("tuple_spline_meanflow", "Tuple + Spline + MeanFlow", TUPLE, Spline(), MeanFlow()),
        MethodSpec("tuple_spline_shortcut", "Tuple + Spline + Shortcut", TUPLE, Spline(), Shortcut()),
        # Beyond Table II: the RF fine-tuned on its own screened samples (training/physics.py)
        MethodSpec(
            "tuple_spline_rf_physics",
            "Tuple + Spline + RF, physics-aware (RFT)",
            TUPLE,
            Spline(),
            RectifiedFlow(),
            recipe="physics_finetune",
            base="tuple_spline_rf",
        ),
    )
}
ALL_METHODS = tuple(REGISTRY)
RECIPES = ("fit", "physics_finetune")
INPAINTING = (RectifiedFlow, MeanFlow, Shortcut)  # samplers that take ``known`` (start-conditioned sampling)
METHODS = ALL_METHODS[:5]  # Table II
FEW_STEP = ALL_METHODS[5:7]  # the few-step generators, compared apart (experiments.sweep fewstep)
ABLATION_ROWS = (*METHODS, "tuple_spline_rf_physics")  # what experiments.ablation reports by default
DISPLAY = {name: s.display for name, s in REGISTRY.items()}


def spec(method: str) -> MethodSpec:
    """The registered :class:`MethodSpec`; ``ValueError`` listing the valid names."""
    if method not in REGISTRY:
        raise ValueError(f"unknown method {method!r}; valid methods: {', '.join(ALL_METHODS)}")
    return REGISTRY[method]


def build_model(
    method: str, num_controls: int, key, num_tendons: int = NUM_TENDONS, model: ModelConfig = ModelConfig()
) -> nnx.Module:
    """The network of ``method`` for ``num_tendons`` (N_u, from the library) and P = ``num_controls``."""
    s = spec(method)
    return s.generator.init(key, s.representation, num_controls, num_tendons, s.use_intensity, model)


def encode(y):
    """Controls / actuation in ~[0, 1] -> the generators' normalized [-1, 1]."""
    return 2.0 * y - 1.0


def decode(x):
    """The generators' normalized [-1, 1] -> controls / actuation in ~[0, 1]."""
    return 0.5 * (x + 1.0)


def init(
    method: str,
    seeds,
    num_controls: int = NUM_CONTROLS,
    num_tendons: int = NUM_TENDONS,
    model: ModelConfig = ModelConfig(),
    *,
    abstract: bool = False,
):
    """(graphdef, params stacked over seeds). ``abstract``: the parameters as ``jax.ShapeDtypeStruct``, traced
    but never computed (a checkpoint restore needs nothing more; no start-up compiles)."""
    if abstract:
        net = nnx.eval_shape(lambda: build_model(method, num_controls, jax.random.key(0), num_tendons, model))
        graphdef, state = nnx.split(net)
        return graphdef, jax.tree.map(lambda x: jax.ShapeDtypeStruct((len(seeds), *x.shape), x.dtype), state)
    keys = jnp.stack([jax.random.key(int(s)) for s in seeds])
    graphdef, _ = nnx.split(build_model(method, num_controls, keys[0], num_tendons, model))
    params = jax.vmap(lambda k: nnx.split(build_model(method, num_controls, k, num_tendons, model))[1])(keys)
    return graphdef, params


def check_options(method: str, config: TrainConfig) -> None:
    """``ValueError`` for a generator option that does not apply to ``method``'s generator."""
    generator = spec(method).generator
    if config.condition_dropout and not isinstance(generator, (RectifiedFlow, DDPM, MeanFlow, Shortcut)):
        raise ValueError(
            f"condition_dropout (classifier-free guidance) needs a flow or diffusion generator; "
            f"{method} is a deterministic regressor"
        )
    if config.time_sampler != "uniform" and not isinstance(generator, (RectifiedFlow, MeanFlow, Shortcut)):
        raise ValueError(
            f"time_sampler {config.time_sampler!r} applies to rectified flow and the few-step flows (MeanFlow, "
            f"shortcut); {method} is none of them"
        )


COND_NORM = 1.0  # sentence embeddings (MiniLM, mean-pooled and normalized) are unit vectors


def bound_condition(cond):
    """Conditions longer than a unit vector scaled back onto the unit sphere; every real one (an intent or a
    text embedding, norm 1, or the null condition 0) passes unchanged. Without it a condition of norm ~1e3
    (fuzzing) drives the integrated flow to overflow in 50 Euler steps; the gate would then refuse the
    non-finite output, but a sampler that cannot overflow is the better guarantee."""
    cond = jnp.asarray(cond, jnp.float32)
    norm = jnp.linalg.norm(cond, axis=-1, keepdims=True)
    return jnp.where(norm > COND_NORM * (1.0 + 1e-3), cond * (COND_NORM / jnp.maximum(norm, 1e-30)), cond)


def check_start_conditioning(method: str) -> None:
    """``ValueError`` unless ``method`` can sample from a given start (a flow over spline controls whose
    sampler inpaints: rectified flow, MeanFlow, shortcut)."""
    s = spec(method)
    if not (isinstance(s.generator, INPAINTING) and isinstance(s.representation, Spline) and not s.generator.sequence):
        capable = ", ".join(
            n
            for n, m in REGISTRY.items()
            if isinstance(m.generator, INPAINTING) and isinstance(m.representation, Spline)
        )
        raise ValueError(
            f"start-conditioned sampling inpaints the first spline control of a rectified flow; {method} is not "
            f"one (methods that can: {capable}); use the default blend (start_conditioned=False) instead"
        )
