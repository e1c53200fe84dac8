"""Physics-aware training: rejection-sampling fine-tuning of a rectified flow on screened samples.

The simulator shapes the generator. Starting from a trained Tuple + Spline + RF (every seed), each
round

1. draws ``candidates`` samples for each of the 64 (intent, intensity) tuples from the current model;
2. rolls them all out in one batch (:func:`jgrounding.sim.margins`, ``engine="auto"``) and keeps the
   ones whose feasibility margin (:func:`jgrounding.sim.feasibility_margin`) is at least
   ``margin``: a buffer inside the bound, so the model learns to stay away from it, not to graze it;
3. fine-tunes the model with the rectified-flow loss (Eq. rf_loss) on the kept samples' controls
   (Eq. ci) together with the demonstration library's training pairs (which anchor success).

The kept samples are the model's own distribution minus its infeasible tail, so diversity is
preserved; the library keeps it on the demonstrations. This is reward-weighted flow matching with a
0/1 weight ``margin_i >= margin`` (rejection sampling fine-tuning, RAFT / ReST style).
"""

from __future__ import annotations

import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np
from flax import nnx

from jgrounding import sim, training
from jgrounding.actuation import splines
from jgrounding.config import NUM_STEPS, PhysicsConfig, SampleConfig
from jgrounding.generators import encoding, flows
from jgrounding.generators.trained import Trained
from jgrounding.vocabulary import NUM_INTENSITIES, NUM_INTENTS

METHOD = "tuple_spline_rf"


def _candidate_sampler(trained: Trained, cond, inten, c: int, sample: SampleConfig):
    """``(params[S], key) -> u (S, 64, c, T, N_u)``: ``c`` gated samples of every tuple from every seed, compiled
    once for all rounds (vmap over seeds of :meth:`Trained.sample`)."""
    cond_k = jnp.repeat(jnp.asarray(cond, jnp.float32), c, axis=0)
    inten_k = jnp.repeat(jnp.asarray(inten, jnp.int32), c)

    @jax.jit
    def draw(params, key):
        keys = jax.random.split(key, len(trained.seeds))
        u = jax.vmap(lambda p, k: trained.sample(k, cond_k, inten_k, sample, params=p))(params, keys)
        return u.reshape(len(trained.seeds), len(cond), c, NUM_STEPS, trained.num_tendons)

    return draw


def _tuples(intent_emb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Conditions of all 64 tuples: ``(64, 384)`` intent embeddings and ``(64,)`` intensities."""
    m, z = np.divmod(np.arange(NUM_INTENTS * NUM_INTENSITIES), NUM_INTENSITIES)
    return np.asarray(intent_emb)[m], z.astype(np.int32)


def _loss(graphdef, data):
    def loss(params, idx, key):
        model = nnx.merge(graphdef, params)
        cond, inten, y = data["cond"][idx], data["intensity"][idx], data["target"][idx]
        return flows.rf_loss(lambda x, t: model(x, t, cond, inten), y, key)

    return loss


def refill(keep: np.ndarray, controls: np.ndarray, lib_controls: dict, rng: np.random.Generator) -> np.ndarray:
    """Fixed-size training targets from the kept candidates: ``keep (64, C)``, ``controls (64, C, D)`` ->
    ``(64, C, D)`` where each rejected slot holds a kept candidate of the same tuple (drawn with ``rng``),
    or one of the tuple's library realizations if none was kept. Tuples stay balanced and every seed's
    data has the same shape, so all seeds fine-tune in one vmapped program."""
    out = controls.copy()
    for j in range(keep.shape[0]):
        bad = np.flatnonzero(~keep[j])
        if len(bad) == 0:
            continue
        kept = np.flatnonzero(keep[j])
        out[j, bad] = (
            controls[j, rng.choice(kept, len(bad))]
            if len(kept)
            else lib_controls[j][rng.integers(0, len(lib_controls[j]), len(bad))]
        )
    return out


def _make_finetune(graphdef, cond, intensity, config: training.TrainConfig):
    """``jit(vmap over seeds)``: ``(states, targets (S, N, D)) -> (states, losses (S, steps))``."""
    n = cond.shape[0]

    def run(state, target):
        data = {"cond": cond, "intensity": intensity, "target": target}
        step = training.make_step(_loss(graphdef, data), n, config)
        return jax.lax.scan(step, state, None, length=config.steps)

    return jax.jit(jax.vmap(run))


def finetune(
    teacher: Trained,
    library,
    key,
    *,
    intent_emb,
    physics: PhysicsConfig = PhysicsConfig(),
    sample: SampleConfig = SampleConfig(),
    config: training.TrainConfig = training.TrainConfig(),
):
    """Physics-aware fine-tuning of every seed of a trained ``tuple_spline_rf`` (all seeds at once).

    Args:
      teacher: the trained RF (leading seed axis on its parameters).
      library: its ``train`` split is mixed into every round's data.
      key: randomness of candidate generation and fine-tuning.
      intent_emb: ``(16, 384)`` intent embeddings (the tuple condition).
      sample: the sampler that draws the candidates (Table I: S = 50 Euler steps).
      config: the optimizer (batch size, weight decay); steps and learning rate come from ``physics``.
    Returns:
      ``(trained, report)``: a :class:`jgrounding.generators.trained.Trained` of the same method and seeds, and per
      round the candidates simulated, the fraction kept, the fraction feasible and the rollout seconds.
    """
    if teacher.method != METHOD:
        raise ValueError(f"physics-aware fine-tuning applies to {METHOD}; got {teacher.method}")
    cond, inten = _tuples(intent_emb)
    n_tuples, c = len(cond), physics.candidates
    tr = library.train
    lib_target = np.asarray(tr.controls, np.float32).reshape(len(tr), -1)
    tuple_of = tr.intent * NUM_INTENSITIES + tr.intensity
    lib_by_tuple = {j: lib_target[tuple_of == j] for j in range(n_tuples)}
    all_cond = jnp.asarray(np.concatenate([np.repeat(cond, c, 0), np.asarray(intent_emb)[tr.intent]]), jnp.float32)
    all_inten = jnp.asarray(np.concatenate([np.repeat(inten, c), tr.intensity]), jnp.int32)
    config = dataclasses.replace(config, steps=physics.steps, learning_rate=physics.learning_rate)
    run = _make_finetune(teacher.graphdef, all_cond, all_inten, config)
    rng = np.random.default_rng(int(jax.random.randint(key, (), 0, 2**31 - 1)))
    params, report = teacher.params, []
    draw = _candidate_sampler(teacher, cond, inten, c, sample)
    for rnd in range(physics.rounds):
        k_gen, k_train = jax.random.split(jax.random.fold_in(key, rnd))
        u = np.asarray(draw(params, k_gen))  # (S, 64, C, T, 4)
        flat = u.reshape(-1, *u.shape[-2:])
        t0 = time.perf_counter()
        margin = sim.margins(flat, engine=physics.engine, trunk=physics.trunk).reshape(u.shape[:3])
        seconds = time.perf_counter() - t0
        keep = margin >= physics.margin
        report.append(
            {
                "round": rnd,
                "simulated": int(flat.shape[0]),
                "kept": float(keep.mean()),
                "feasible": float((margin >= 0).mean()),
                "seconds": seconds,
            }
        )
        controls = np.asarray(splines.fit(flat, num_controls=teacher.num_controls)).reshape(*u.shape[:3], -1)
        targets = np.stack(
            [
                np.concatenate([refill(keep[i], controls[i], lib_by_tuple, rng).reshape(n_tuples * c, -1), lib_target])
                for i in range(len(teacher.seeds))
            ]
        )
        keys = jax.random.split(k_train, len(teacher.seeds))
        states = jax.vmap(lambda p, k: training.init_state(p, k, config))(params, keys)
        states, _ = run(states, encoding.encode(jnp.asarray(targets)))  # controls in [-1, 1], as the methods train
        params = training.eval_params(states)
    library_id = dict(teacher.library or {})
    if sim.resolve_trunk(physics.trunk) is not None:  # its checkpoint records the trunk it was screened on
        library_id["trunk"] = sim.trunk_identity(physics.trunk)
    return dataclasses.replace(teacher, params=params, losses=None, library=library_id), report
