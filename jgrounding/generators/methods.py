"""The method registry: *Semantic Condition + Actuation Representation + Generator*, and nothing else.

Table II's five methods are ``raw_dense_cnn``, ``tuple_dense_cnn``, ``tuple_spline_cnn``, ``tuple_spline_ddpm``
and ``tuple_spline_rf``. Tuple conditioning is (E_m(m), E_z(z)); raw conditioning is the response text's
embedding. Spline methods work on the N_u x P controls (normalized to [-1, 1]) and reconstruct u = R(c); dense
methods predict the 150 x N_u trajectory directly.

Beyond Table II, registered the same way: the one-step generators (``tuple_spline_meanflow``,
``tuple_spline_shortcut``: :data:`FEW_STEP`, :mod:`jgrounding.generators.few_step`) and the physics-aware RF
(``tuple_spline_rf_physics``: the RF fine-tuned on its own screened samples; its ``recipe`` names how
:mod:`jgrounding.training` makes it). :data:`METHODS` stays the five rows of Table II and :data:`ABLATION_ROWS`
what the ablation reports.

The parts live in files named for them: the conditions in :mod:`jgrounding.generators.conditions`, the
representations in :mod:`jgrounding.generators.representations`, the generators in
:mod:`jgrounding.generators.regressor`, :mod:`jgrounding.generators.flows` and
:mod:`jgrounding.generators.few_step` (their abilities declared on :class:`jgrounding.generators.base.Generator`),
the [0, 1] <-> [-1, 1] normalization in :mod:`jgrounding.generators.encoding`.
A trained model (parameters, sizes, sampling defaults, library identity) and its sampling live in
:mod:`jgrounding.generators.trained`; training and reflow in :mod:`jgrounding.training.trainer`; checkpoints in
:mod:`jgrounding.training.checkpoints`; batch generation for evaluation in :mod:`jgrounding.evaluation.generate`.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from flax import nnx

from jgrounding.config import NUM_CONTROLS, NUM_TENDONS, ModelConfig, TrainConfig
from jgrounding.generators.base import Generator
from jgrounding.generators.conditions import RAW, TUPLE, RawText, TupleCondition
from jgrounding.generators.few_step import MeanFlow, Shortcut
from jgrounding.generators.flows import DDPM, RectifiedFlow
from jgrounding.generators.regressor import Regressor
from jgrounding.generators.representations import Dense, Spline


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
        # Beyond Table II: one-step generators (generators/few_step.py)
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
    """``ValueError`` for a generator option that does not apply to ``method``'s generator (its declared
    abilities: :class:`jgrounding.generators.base.Generator`)."""
    generator = spec(method).generator
    if config.condition_dropout and not generator.null_condition:
        raise ValueError(
            f"condition_dropout (classifier-free guidance) needs a flow or diffusion generator; "
            f"{method} is a deterministic regressor"
        )
    if config.time_sampler != "uniform" and not generator.flow_times:
        raise ValueError(
            f"time_sampler {config.time_sampler!r} applies to rectified flow and the few-step flows (MeanFlow, "
            f"shortcut); {method} is none of them"
        )


def can_start_condition(method: str) -> bool:
    """Whether ``method`` samples from a given start: a generator that inpaints (``Generator.inpaints``) over
    flat spline controls, whose first control column it fixes."""
    s = spec(method)
    return s.generator.inpaints and isinstance(s.representation, Spline) and not s.generator.sequence


def check_start_conditioning(method: str) -> None:
    """``ValueError`` unless ``method`` can sample from a given start (:func:`can_start_condition`: rectified
    flow, MeanFlow, shortcut)."""
    if not can_start_condition(method):
        capable = ", ".join(n for n in REGISTRY if can_start_condition(n))
        raise ValueError(
            f"start-conditioned sampling inpaints the first spline control of a rectified flow; {method} is not "
            f"one (methods that can: {capable}); use the default blend (start_conditioned=False) instead"
        )
