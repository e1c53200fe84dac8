"""The five methods of Table II behind one interface: ``train`` and ``generate``.

Name pattern *Semantic Condition + Actuation Representation + Generator*:
``raw_dense_cnn``, ``tuple_dense_cnn``, ``tuple_spline_cnn``, ``tuple_spline_ddpm``, ``tuple_spline_rf``.
Tuple conditioning is (E_m(m), E_z(z)); raw conditioning is the response text's embedding. Spline
methods work on the 4 x P controls (normalized to [-1, 1]) and reconstruct u = R(c); dense methods
predict the 150 x 4 trajectory directly. Every output passes through ``safety.make_safe``.

Beyond Table II, the one-step generators of issue #25 are registered the same way
(``tuple_spline_meanflow``, ``tuple_spline_shortcut``: :data:`FEW_STEP`, :mod:`jgrounding.generators.few_step`);
:data:`METHODS` stays the five rows of Table II.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jgrounding import io, safety, training
from jgrounding.actuation import splines
from jgrounding.config import ModelConfig, SampleConfig, TrainConfig
from jgrounding.generators.base import Generator
from jgrounding.generators.few_step import MeanFlow, Shortcut
from jgrounding.generators.flows import DDPM, RectifiedFlow
from jgrounding.generators.networks import CNNRegressor
from jgrounding.training import checkpoints, distributed

T = splines.NUM_STEPS


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
class MethodSpec:
    """A Table II method: *Semantic Condition + Actuation Representation + Generator*."""

    name: str
    display: str
    condition: str  # "tuple": (E_m(m), E_z(z)); "raw": the response text's embedding
    representation: Spline | Dense
    generator: Generator

    @property
    def use_intensity(self) -> bool:
        return self.condition == "tuple"


REGISTRY = {
    s.name: s
    for s in (
        MethodSpec("raw_dense_cnn", "Raw + Dense + CNN", "raw", Dense(), Regressor()),
        MethodSpec("tuple_dense_cnn", "Tuple + Dense + CNN", "tuple", Dense(), Regressor()),
        MethodSpec("tuple_spline_cnn", "Tuple + Spline + CNN", "tuple", Spline(), Regressor()),
        MethodSpec("tuple_spline_ddpm", "Tuple + Spline + DDPM", "tuple", Spline(), DDPM()),
        MethodSpec("tuple_spline_rf", "Tuple + Spline + RF", "tuple", Spline(), RectifiedFlow()),
        # Beyond Table II: one-step generators (issue #25, generators/few_step.py)
        MethodSpec("tuple_spline_meanflow", "Tuple + Spline + MeanFlow", "tuple", Spline(), MeanFlow()),
        MethodSpec("tuple_spline_shortcut", "Tuple + Spline + Shortcut", "tuple", Spline(), Shortcut()),
    )
}
ALL_METHODS = tuple(REGISTRY)
INPAINTING = (RectifiedFlow, MeanFlow, Shortcut)  # samplers that take ``known`` (start-conditioned sampling)
METHODS = ALL_METHODS[:5]  # Table II (the ablation's rows); the few-step generators are compared apart
FEW_STEP = ALL_METHODS[5:]
DISPLAY = {name: s.display for name, s in REGISTRY.items()}


def spec(method: str) -> MethodSpec:
    """The registered :class:`MethodSpec`; ``ValueError`` listing the valid names."""
    if method not in REGISTRY:
        raise ValueError(f"unknown method {method!r}; valid methods: {', '.join(ALL_METHODS)}")
    return REGISTRY[method]


def build_model(
    method: str, num_controls: int, key, num_tendons: int = 4, model: ModelConfig = ModelConfig()
) -> nnx.Module:
    """The network of ``method`` for ``num_tendons`` (N_u, from the library) and P = ``num_controls``."""
    s = spec(method)
    return s.generator.init(key, s.representation, num_controls, num_tendons, s.use_intensity, model)


@dataclasses.dataclass(frozen=True)
class Trained:
    """Parameters of ``len(seeds)`` runs of one method (leading axis = seed)."""

    method: str
    graphdef: Any
    params: Any
    seeds: tuple[int, ...]
    num_controls: int
    losses: Any = None
    num_tendons: int = 4  # N_u of the library it was trained on
    model: ModelConfig = ModelConfig()  # network sizes (recorded in its checkpoints)


def _encode(y):  # controls / actuation in ~[0, 1] -> [-1, 1]
    return 2.0 * y - 1.0


def _decode(x):
    return 0.5 * (x + 1.0)


def training_data(method: str, split, intent_emb: np.ndarray, text_emb: np.ndarray | None, num_controls: int):
    """Arrays the loss reads: condition embedding, intensity, normalized target (flat or sequence)."""
    s = spec(method)
    target = s.representation.target(split, num_controls, s.generator.sequence)
    if s.condition == "raw":
        if text_emb is None:
            raise ValueError("raw conditioning needs text embeddings of the records' response texts")
        n_text = text_emb.shape[1]
        cond = text_emb.reshape(-1, text_emb.shape[-1])  # one example per (record, text)
        target = np.repeat(target, n_text, axis=0)
        intensity = np.repeat(split.intensity, n_text)
    else:
        cond = intent_emb[split.intent]
        intensity = split.intensity
    return {
        "cond": jnp.asarray(cond, jnp.float32),
        "intensity": jnp.asarray(intensity, jnp.int32),
        "target": _encode(jnp.asarray(target, jnp.float32)),
    }


def loss_fn(method: str, graphdef, data, config: TrainConfig = TrainConfig()):
    """``loss(params, idx (B,), key) -> scalar``: the generator's loss on the examples ``idx`` of ``data``."""
    generator = spec(method).generator

    def loss(params, idx, key):
        batch = {k: v[idx] for k, v in data.items()}
        return generator.loss(nnx.merge(graphdef, params), batch, key, config)

    return loss


def init(method: str, seeds, num_controls: int = 4, num_tendons: int = 4, model: ModelConfig = ModelConfig()):
    """(graphdef, params stacked over seeds)."""
    keys = jnp.stack([jax.random.key(int(s)) for s in seeds])
    graphdef, _ = nnx.split(build_model(method, num_controls, keys[0], num_tendons, model))
    params = jax.vmap(lambda k: nnx.split(build_model(method, num_controls, k, num_tendons, model))[1])(keys)
    return graphdef, params


def abstract(method: str, seeds, num_controls: int = 4, num_tendons: int = 4, model: ModelConfig = ModelConfig()):
    """(graphdef, params as ``jax.ShapeDtypeStruct`` stacked over seeds): :func:`init`'s structure and
    shapes, traced but never computed (a checkpoint restore needs nothing more; no start-up compiles)."""
    net = nnx.eval_shape(lambda: build_model(method, num_controls, jax.random.key(0), num_tendons, model))
    graphdef, state = nnx.split(net)
    return graphdef, jax.tree.map(lambda x: jax.ShapeDtypeStruct((len(seeds), *x.shape), x.dtype), state)


def train(
    method: str,
    library,
    seeds=(0, 1, 2, 3, 4),
    config: TrainConfig = TrainConfig(),
    *,
    intent_emb=None,
    text_emb=None,
    num_controls: int = 4,
    progress: bool = True,
    initial_states=None,
    on_chunk=None,
    mesh=None,
    model: ModelConfig = ModelConfig(),
) -> Trained:
    """Train ``method`` on ``library.train`` for every seed at once (vmap); returns :class:`Trained`.

    ``mesh``: split the seeds over the devices of a :func:`jgrounding.training.distributed.make_mesh` mesh.
    """
    from jgrounding import semantics

    check_options(method, config)
    intent_emb = semantics.intent_embeddings() if intent_emb is None else intent_emb
    data = training_data(method, library.train, intent_emb, text_emb, num_controls)
    num_tendons = int(library.train.u.shape[-1])  # N_u from the data
    graphdef, params = init(method, seeds, num_controls, num_tendons, model)
    step = training.make_step(loss_fn(method, graphdef, data, config), int(data["target"].shape[0]), config)
    if initial_states is None:
        keys = jnp.stack([jax.random.fold_in(jax.random.key(int(s)), 1) for s in seeds])
        initial_states = jax.vmap(lambda p, k: training.init_state(p, k, config))(params, keys)
    states, losses = training.train(
        initial_states, step, config, desc=DISPLAY[method], progress=progress, on_chunk=on_chunk, mesh=mesh
    )
    return Trained(
        method,
        graphdef,
        training.eval_params(states),
        tuple(int(s) for s in seeds),
        num_controls,
        losses,
        num_tendons,
        model,
    )


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


def reflow(
    teacher: Trained,
    library,
    config: TrainConfig = TrainConfig(),
    *,
    intent_emb=None,
    pairs_per_example: int = 64,
    teacher_steps: int = 50,
    teacher_guidance: float = 0.0,
    progress: bool = True,
) -> Trained:
    """2-rectified flow (Liu et al., "Flow straight and fast"): retrain each seed of an RF ``teacher`` on
    coupled pairs (eps, x1 = ODE_teacher(eps | condition)) so that its paths straighten and few Euler
    steps reach what many did.

    Args:
      teacher: a trained ``tuple_spline_rf`` (any seeds); every seed is reflowed from its own pairs and
        initialized from its own parameters.
      library: its ``train`` split gives the conditions (each repeated ``pairs_per_example`` times).
      config: training of the reflowed model (``condition_dropout`` / ``time_sampler`` apply as usual).
      teacher_steps: Euler steps S of the teacher's ODE.
      teacher_guidance: the teacher's guidance w; the reflowed model learns the guided field, so it is
        sampled with w = 0 (one network evaluation per step instead of two).
    Returns: a :class:`Trained` of the same method, seeds and P.
    """
    from jgrounding import semantics

    generator = spec(teacher.method).generator
    if not isinstance(generator, RectifiedFlow):
        raise ValueError(f"reflow needs a rectified-flow teacher; {teacher.method} is not RF")
    check_options(teacher.method, config)
    intent_emb = semantics.intent_embeddings() if intent_emb is None else intent_emb
    base = training_data(teacher.method, library.train, intent_emb, None, teacher.num_controls)
    cond = jnp.repeat(base["cond"], pairs_per_example, axis=0)
    inten = jnp.repeat(base["intensity"], pairs_per_example, axis=0)
    dim = base["target"].shape[-1]
    ode = SampleConfig("euler", teacher_steps, teacher_guidance)

    @jax.jit
    def teacher_pairs(params, key):
        x1 = generator.sample(nnx.merge(teacher.graphdef, params), cond, inten, key, dim, ode)
        return jax.random.normal(key, (cond.shape[0], dim)), x1  # the eps the sampler drew from key

    out, losses = [], []
    for i, seed in enumerate(teacher.seeds):
        k_pairs, k_train = jax.random.split(jax.random.fold_in(jax.random.key(seed), 2))
        params = jax.tree.map(lambda x: x[i], teacher.params)
        eps, x1 = teacher_pairs(params, k_pairs)
        data = {"cond": cond, "intensity": inten, "target": x1, "noise": eps}
        step = training.make_step(loss_fn(teacher.method, teacher.graphdef, data, config), int(x1.shape[0]), config)
        state = jax.tree.map(lambda x: x[None], training.init_state(params, k_train, config))
        state, loss = training.train(state, step, config, desc=f"reflow seed {seed}", progress=progress)
        out.append(training.eval_params(state))
        losses.append(loss)
    params = jax.tree.map(lambda *x: jnp.concatenate(x), *out)
    return dataclasses.replace(teacher, params=params, losses=jnp.concatenate(losses))


def checkpoint_meta(trained: Trained) -> dict:
    """What every checkpoint of a :class:`Trained` records so that :func:`restore` rebuilds its network."""
    return {
        "method": trained.method,
        "seeds": list(trained.seeds),
        "num_controls": trained.num_controls,
        "num_tendons": trained.num_tendons,
        "model": dataclasses.asdict(trained.model),
    }


# = jgrounding.library.DEFAULT_PATH, named here so that loading a checkpoint does not import the library
# package (and the physics it screens with): jg.sample's first call stays short.
DEFAULT_LIBRARY = Path(__file__).resolve().parents[2] / "assets" / "library.npz"


def library_mismatch(path, meta: dict) -> str | None:
    """Why checkpoint ``path`` (its ``meta``) does not belong to the library it would be used with, or ``None``.

    The library is the one it recorded (``library_path``, when that file exists) or else the shipped
    ``assets/library.npz``; a checkpoint that recorded no library sha256 is not judged."""
    digest = meta.get("library_sha256")
    lib_path = Path(meta.get("library_path") or DEFAULT_LIBRARY)
    if not digest or not lib_path.is_file() or io.sha256_file(lib_path) == digest:
        return None
    try:
        current = json.loads(lib_path.with_suffix(".json").read_text()).get("library_version", "1 (unversioned)")
    except (OSError, ValueError):
        current = "unknown"
    return (
        f"checkpoint {path} was trained on library version {meta.get('library_version', '1 (unversioned)')} "
        f"(sha256 {digest[:12]}...), but {lib_path} is library version {current} (sha256 "
        f"{io.sha256_file(lib_path)[:12]}...); retrain it (python -m experiments.train --out {path}) or pass "
        "allow_library_mismatch=True (--allow-library-mismatch) to use it anyway"
    )


def restore(path, method: str | None = None, *, allow_library_mismatch: bool = False) -> Trained:
    """A :class:`Trained` (every seed it holds) from a checkpoint directory written by the ablation or
    ``experiments.train``; ``method`` (optional) must match. ``ValueError`` naming the directory for an
    unknown method, P, N_u or model sizes, a checkpoint trained on another library version
    (:func:`library_mismatch`; unless ``allow_library_mismatch``), and whatever :func:`checkpoints.restore`
    refuses (vocabulary, shapes, NaN, digest). Checkpoints written before model sizes were recorded load
    with Table I's sizes (what they were trained with); one whose arrays do not fit them is refused by its
    shapes."""
    from jgrounding.config import model_config

    meta = checkpoints.read_meta(path)
    why = None if allow_library_mismatch else library_mismatch(path, meta)
    if why:
        raise ValueError(why)
    name, num_controls, seeds = meta.get("method"), meta.get("num_controls", 4), meta.get("seeds", [0])
    num_tendons = meta.get("num_tendons", 4)
    if name not in REGISTRY:
        raise ValueError(f"checkpoint {path} names unknown method {name!r}; valid: {', '.join(ALL_METHODS)}")
    if method is not None and name != method:
        raise ValueError(f"checkpoint {path}: method is {name!r}, expected {method!r}")
    if isinstance(num_controls, bool) or not isinstance(num_controls, int) or not 2 <= num_controls <= 64:
        raise ValueError(f"checkpoint {path} has num_controls {num_controls!r}, expected an integer in 2..64")
    if isinstance(num_tendons, bool) or not isinstance(num_tendons, int) or not 1 <= num_tendons <= 64:
        raise ValueError(f"checkpoint {path} has num_tendons {num_tendons!r}, expected an integer in 1..64")
    try:
        model = model_config(meta)
    except (TypeError, ValueError) as e:
        raise ValueError(f"checkpoint {path}: {e}") from None
    graphdef, params = abstract(name, tuple(seeds), num_controls, num_tendons, model)
    params, _ = checkpoints.restore(path, params)
    return Trained(
        name, graphdef, params, tuple(int(x) for x in seeds), num_controls, num_tendons=num_tendons, model=model
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


def actuation(
    method: str,
    graphdef,
    params,
    cond,
    intensity,
    key,
    *,
    sampler: str = "euler",
    steps: int = 50,
    num_controls: int = 4,
    num_tendons: int = 4,
    guidance: float = 0.0,
    start=None,
    noise_scale: float = 1.0,
):
    """Ungated actuation for a batch of conditions: the generator's sample (normalized controls or
    trajectory), decoded to [0, 1], and the spline reconstruction u = R(c) for spline methods.

    Args:
      cond: condition embeddings ``(B, 384)``; intensity: ``(B,)`` int32; key: one key for the batch.
      noise_scale: temperature of the initial noise (:class:`SampleConfig`; 1 = as trained).
      start: ``(B, N_u)`` commands in [0, 1] or None. Given, the first Catmull-Rom control column is fixed
        to it by inpainting during the flow integration (:func:`flows.rf_sample`), so ``u[:, 0] == start``
        and the rest of the motion is generated from that state (:func:`check_start_conditioning`).
    Returns:
      u ``(B, 150, N_u)``, not yet through the safety gate (:func:`sample_one` and the public sampler gate it).
    """
    s = spec(method)
    model = nnx.merge(graphdef, params)
    dim = num_tendons * s.representation.length(num_controls)
    config = SampleConfig(sampler, steps, guidance, noise_scale)
    cond = bound_condition(cond)
    if start is None:
        y = s.generator.sample(model, cond, intensity, key, dim, config)
    else:
        check_start_conditioning(method)
        # Flat layout of the targets: (N_u, P) row-major, so tendon j's first control is coordinate j * P.
        mask = (jnp.arange(dim) % num_controls) == 0
        first = jnp.repeat(_encode(jnp.asarray(start, jnp.float32)), num_controls, axis=-1)  # (B, D)
        y = s.generator.sample(model, cond, intensity, key, dim, config, known=(mask, first))
    return s.representation.actuation(_decode(y), s.generator.sequence, num_tendons, num_controls)


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


def sample_one(
    method: str,
    graphdef,
    params,
    cond,
    intensity,
    key,
    *,
    sampler: str = "euler",
    steps: int = 50,
    num_controls: int = 4,
    num_tendons: int = 4,
    guidance: float = 0.0,
):
    """Samples for a batch of conditions ``cond (B, 384)``, ``intensity (B,)`` -> gated u ``(B, 150, N_u)``."""
    return safety.make_safe(
        actuation(
            method,
            graphdef,
            params,
            cond,
            intensity,
            key,
            sampler=sampler,
            steps=steps,
            num_controls=num_controls,
            num_tendons=num_tendons,
            guidance=guidance,
        )
    )


def generate(
    trained: Trained,
    cond: np.ndarray,
    intensity: np.ndarray,
    key,
    num_samples: int = 30,
    *,
    sampler: str = "euler",
    steps: int = 50,
    batch: int = 640,
    mesh=None,
    guidance: float = 0.0,
) -> np.ndarray:
    """u ``(num_seeds, N, K, 150, 4)`` for conditions ``cond (N, 384)``, ``intensity (N,)``.

    ``mesh``: a :func:`jgrounding.training.distributed.make_mesh` mesh; the flattened (condition x sample)
    batch is then split over its devices. ``batch`` is rounded up to a multiple of the device count;
    the noise depends on the batch layout, so the result equals the single-device run with that batch.
    """
    n = cond.shape[0]
    cond_k = jnp.repeat(jnp.asarray(cond, jnp.float32), num_samples, axis=0)
    inten_k = jnp.repeat(jnp.asarray(intensity, jnp.int32), num_samples, axis=0)
    fn = generate_fn(
        trained.method, trained.graphdef, sampler, steps, trained.num_controls, mesh, trained.num_tendons, guidance
    )
    keys = jax.random.split(key, len(trained.seeds))
    params = trained.params
    if mesh is not None:
        batch = -(-batch // mesh.size) * mesh.size
        params = distributed.replicate(params, mesh)
    outs = []
    for i in range(0, n * num_samples, batch):
        sub = jax.vmap(lambda k: jax.random.fold_in(k, i))(keys)
        c, z = cond_k[i : i + batch], inten_k[i : i + batch]
        pad = batch - c.shape[0]
        c, z = jnp.pad(c, ((0, pad), (0, 0))), jnp.pad(z, (0, pad))
        if mesh is not None:
            (c, z), sub = distributed.shard((c, z), mesh), distributed.replicate(sub, mesh)
        outs.append(distributed.gather(fn(params, c, z, sub))[:, : batch - pad])
    u = np.concatenate(outs, axis=1)
    return u.reshape(len(trained.seeds), n, num_samples, T, trained.num_tendons)


_GEN_CACHE: dict = {}


def generate_fn(method, graphdef, sampler, steps, num_controls, mesh=None, num_tendons: int = 4, guidance=0.0):
    """``jit(vmap over seeds(sample_one))``; with a mesh the batch axis is split over its devices."""
    key = (method, id(graphdef), sampler, steps, num_controls, mesh, num_tendons, float(guidance))
    if key not in _GEN_CACHE:

        def one(params, cond, inten, k):
            return sample_one(
                method,
                graphdef,
                params,
                cond,
                inten,
                k,
                sampler=sampler,
                steps=steps,
                num_controls=num_controls,
                num_tendons=num_tendons,
                guidance=guidance,
            )

        fn = jax.vmap(one, in_axes=(0, None, None, 0))
        if mesh is None:
            _GEN_CACHE[key] = jax.jit(fn)
        else:
            rep, split = distributed.sharding(mesh), distributed.sharding(mesh, distributed.AXIS)
            _GEN_CACHE[key] = jax.jit(
                fn,
                in_shardings=(rep, split, split, rep),
                out_shardings=distributed.sharding(mesh, None, distributed.AXIS),
            )
    return _GEN_CACHE[key]
