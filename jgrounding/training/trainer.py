"""Training of a registered method: from scratch (:func:`fit`), 2-rectified flow (:func:`reflow`) and the
registry's recipes (:func:`make`: ``fit`` or the physics-aware fine-tuning of a trained base method).

Every function returns a :class:`~jgrounding.generators.trained.Trained` whose parameters carry one leading
axis per seed, trained at once by the compiled loop of :mod:`jgrounding.training.loop`.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jgrounding.config import NUM_CONTROLS, ModelConfig, PhysicsConfig, SampleConfig, TrainConfig
from jgrounding.generators import methods
from jgrounding.generators.encoding import encode
from jgrounding.generators.trained import Trained
from jgrounding.training import loop


def library_identity(library) -> dict:
    """What a model records of the library it was trained on: its version and file (hashed when checkpointed)."""
    meta = getattr(library, "meta", None) or {}
    out = {"version": meta.get("library_version", "1 (unversioned)")}
    if getattr(library, "path", None):
        out["path"] = str(library.path)
    if meta.get("trunk"):  # screened on a trunk of its own (a fitted one); no key: the shipped trunk
        out["trunk"] = meta["trunk"]
    return out


def training_data(method: str, split, intent_emb: np.ndarray, text_emb: np.ndarray | None, num_controls: int):
    """Arrays the loss reads: condition embedding, intensity, normalized target (flat or sequence); the
    method's condition (tuple or raw text) decides what a training example is."""
    s = methods.spec(method)
    target = s.representation.target(split, num_controls, s.generator.sequence)
    cond, intensity, target = s.condition.examples(split, intent_emb, text_emb, target)
    return {
        "cond": jnp.asarray(cond, jnp.float32),
        "intensity": jnp.asarray(intensity, jnp.int32),
        "target": encode(jnp.asarray(target, jnp.float32)),
    }


def loss_fn(method: str, graphdef, data, config: TrainConfig = TrainConfig()):
    """``loss(params, idx (B,), key) -> scalar``: the generator's loss on the examples ``idx`` of ``data``."""
    generator = methods.spec(method).generator

    def loss(params, idx, key):
        batch = {k: v[idx] for k, v in data.items()}
        return generator.loss(nnx.merge(graphdef, params), batch, key, config)

    return loss


def fit(
    method: str,
    library,
    seeds=(0, 1, 2, 3, 4),
    config: TrainConfig = TrainConfig(),
    *,
    intent_emb=None,
    text_emb=None,
    num_controls: int = NUM_CONTROLS,
    progress: bool = True,
    initial_states=None,
    on_chunk=None,
    mesh=None,
    model: ModelConfig = ModelConfig(),
) -> Trained:
    """Train ``method`` from scratch on ``library.train`` for every seed at once (:func:`loop.make_chunk`); returns
    :class:`Trained`.

    ``mesh``: split the seeds over the devices of a :func:`jgrounding.training.distributed.make_mesh` mesh.
    """
    from jgrounding import semantics

    methods.check_options(method, config)
    intent_emb = semantics.intent_embeddings() if intent_emb is None else intent_emb
    data = training_data(method, library.train, intent_emb, text_emb, num_controls)
    num_tendons = int(library.train.u.shape[-1])  # N_u from the data
    graphdef, params = methods.init(method, seeds, num_controls, num_tendons, model)
    step = loop.make_step(loss_fn(method, graphdef, data, config), int(data["target"].shape[0]), config)
    if initial_states is None:
        keys = jnp.stack([jax.random.fold_in(jax.random.key(int(s)), 1) for s in seeds])
        initial_states = jax.vmap(lambda p, k: loop.init_state(p, k, config))(params, keys)
    states, losses = loop.train(
        initial_states, step, config, desc=methods.DISPLAY[method], progress=progress, on_chunk=on_chunk, mesh=mesh
    )
    return Trained(
        method,
        graphdef,
        loop.eval_params(states),
        tuple(int(s) for s in seeds),
        num_controls,
        losses,
        num_tendons,
        model,
        library=library_identity(library),
    )


def reflow(
    teacher: Trained,
    library,
    config: TrainConfig = TrainConfig(),
    *,
    intent_emb=None,
    pairs_per_example: int = 64,
    teacher_steps: int = SampleConfig.steps,
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

    generator = teacher.spec.generator
    if not generator.reflows:  # declared by the generator (jgrounding.generators.base.Generator)
        raise ValueError(f"reflow needs a rectified-flow teacher; {teacher.method} is not RF")
    methods.check_options(teacher.method, config)
    intent_emb = semantics.intent_embeddings() if intent_emb is None else intent_emb
    base = training_data(teacher.method, library.train, intent_emb, None, teacher.num_controls)
    cond = jnp.repeat(base["cond"], pairs_per_example, axis=0)
    inten = jnp.repeat(base["intensity"], pairs_per_example, axis=0)
    dim = base["target"].shape[-1]
    ode = SampleConfig("euler", teacher_steps, teacher_guidance)

    @jax.jit
    def teacher_pairs(params, key):  # the normalized targets x1, not decoded actuation: reflow pairs live there
        x1 = generator.sample(nnx.merge(teacher.graphdef, params), cond, inten, key, dim, ode)
        return jax.random.normal(key, (cond.shape[0], dim)), x1  # the eps the sampler drew from key

    out, losses = [], []
    for i, seed in enumerate(teacher.seeds):
        k_pairs, k_train = jax.random.split(jax.random.fold_in(jax.random.key(seed), 2))
        params = jax.tree.map(lambda x: x[i], teacher.params)
        eps, x1 = teacher_pairs(params, k_pairs)
        data = {"cond": cond, "intensity": inten, "target": x1, "noise": eps}
        step = loop.make_step(loss_fn(teacher.method, teacher.graphdef, data, config), int(x1.shape[0]), config)
        state = jax.tree.map(lambda x: x[None], loop.init_state(params, k_train, config))
        state, loss = loop.train(state, step, config, desc=f"reflow seed {seed}", progress=progress)
        out.append(loop.eval_params(state))
        losses.append(loss)
    params = jax.tree.map(lambda *x: jnp.concatenate(x), *out)
    return dataclasses.replace(teacher, params=params, losses=jnp.concatenate(losses))


def make(
    method: str,
    library,
    seeds=(0, 1, 2, 3, 4),
    config: TrainConfig = TrainConfig(),
    *,
    trained: dict | None = None,
    physics: PhysicsConfig = PhysicsConfig(),
    sample: SampleConfig = SampleConfig(),
    key=None,
    **kwargs,
) -> tuple[Trained, dict]:
    """``method`` made by its registry recipe: ``(Trained, report)``.

    ``fit``: :func:`fit` (``kwargs`` go to it; report ``{}``). ``physics_finetune``: fine-tunes
    ``trained[spec.base]`` (already trained; :func:`jgrounding.training.physics.finetune`), report
    ``{"rounds": [...], "seconds": simulation seconds}``; ``ValueError`` when the base is missing."""
    s = methods.spec(method)
    if s.recipe == "fit":
        return fit(method, library, seeds, config, **kwargs), {}
    if s.recipe == "physics_finetune":
        from jgrounding.training import physics as physics_training

        base = (trained or {}).get(s.base)
        if base is None:
            raise ValueError(f"{method} fine-tunes {s.base}: train {s.base} first (list it before {method})")
        out, rounds = physics_training.finetune(
            base,
            library,
            jax.random.key(17) if key is None else key,
            intent_emb=kwargs.get("intent_emb"),
            physics=physics,
            sample=sample,
            config=config,
        )
        return dataclasses.replace(out, method=method), {
            "rounds": rounds,
            "seconds": sum(r["seconds"] for r in rounds),
        }
    raise ValueError(f"{method}: unknown recipe {s.recipe!r}; valid: {', '.join(methods.RECIPES)}")
