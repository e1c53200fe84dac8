"""Physics-aware training: rejection-sampling fine-tuning of a rectified flow on screened samples.

The simulator shapes the generator. Starting from a trained Tuple + Spline + RF (every seed), each
round

1. draws ``candidates`` samples for each of the 64 (intent, intensity) tuples from the current model;
2. rolls them all out in one batch (:func:`jgrounding.trunk_eval.margins`, ``engine="auto"``) and keeps the
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

from jgrounding import training
from jgrounding.evaluation import physics as trunk_eval

from jgrounding.generators import flows

from jgrounding.generators import methods

from jgrounding.actuation import splines
from jgrounding.vocabulary import NUM_INTENSITIES, NUM_INTENTS

METHOD = "tuple_spline_rf"


@dataclasses.dataclass(frozen=True)
class PhysicsConfig:
    rounds: int = 2  # generate -> simulate -> fine-tune rounds
    candidates: int = 16  # samples per tuple per round (64 tuples: 1024 rollouts per seed and round)
    steps: int = 1000  # fine-tuning steps per round (Table I optimizer, batch 8)
    margin: float = 0.2  # keep candidates with feasibility margin >= this (0 = just feasible)
    learning_rate: float = 3e-4  # below Table I's 1e-3: fine-tuning, not training (1e-3 drifted: RMS up)
    euler_steps: int = 50  # S of the sampler that draws the candidates
    engine: str = "auto"  # trunk.rollout engine


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


def finetune(teacher: methods.Trained, library, key, *, intent_emb, physics: PhysicsConfig = PhysicsConfig(),
             config: training.TrainConfig = training.TrainConfig(), progress: bool = False):
    """Physics-aware fine-tuning of every seed of a trained ``tuple_spline_rf``.

    Args:
      teacher: the trained RF (leading seed axis on its parameters).
      library: its ``train`` split is mixed into every round's data.
      key: randomness of candidate generation and fine-tuning.
      intent_emb: ``(16, 384)`` intent embeddings (the tuple condition).
    Returns:
      ``(trained, report)``: a :class:`jgrounding.generators.methods.Trained` of the same method and seeds, and per
      round the candidates simulated, the fraction kept and the fraction feasible.
    """
    if teacher.method != METHOD:
        raise ValueError(f"physics-aware fine-tuning applies to {METHOD}; got {teacher.method}")
    cond, inten = _tuples(intent_emb)
    lib_cond = np.asarray(intent_emb)[library.train.intent]
    lib_target = np.asarray(library.train.controls).reshape(len(library.train), -1)
    config = dataclasses.replace(config, steps=physics.steps, chunk=min(config.chunk, physics.steps),
                                 learning_rate=physics.learning_rate)
    params, report = teacher.params, []
    for rnd in range(physics.rounds):
        k_gen, k_train = jax.random.split(jax.random.fold_in(key, rnd))
        current = dataclasses.replace(teacher, params=params)
        u = methods.generate(current, cond, inten, k_gen, num_samples=physics.candidates,
                             steps=physics.euler_steps)  # (S, 64, C, 150, 4)
        flat = u.reshape(-1, *u.shape[-2:])
        t0 = time.perf_counter()
        margin = trunk_eval.margins(flat, engine=physics.engine).reshape(u.shape[:3])
        seconds = time.perf_counter() - t0
        keep = margin >= physics.margin
        report.append({"round": rnd, "simulated": int(flat.shape[0]), "kept": float(keep.mean()),
                       "feasible": float((margin >= 0).mean()), "seconds": seconds})
        controls = np.asarray(splines.fit(flat, num_controls=teacher.num_controls)).reshape(
            *u.shape[:3], -1)  # (S, 64, C, 4P)
        new = []
        for i in range(len(teacher.seeds)):
            kept = keep[i]
            c_all = np.concatenate([np.repeat(cond, physics.candidates, 0)[kept.reshape(-1)], lib_cond])
            z_all = np.concatenate([np.repeat(inten, physics.candidates)[kept.reshape(-1)],
                                    library.train.intensity])
            y_all = np.concatenate([controls[i][kept], lib_target])
            data = {"cond": jnp.asarray(c_all, jnp.float32), "intensity": jnp.asarray(z_all, jnp.int32),
                    "target": 2.0 * jnp.asarray(y_all, jnp.float32) - 1.0}  # controls in [-1, 1], as methods
            step = training.make_step(_loss(teacher.graphdef, data), len(y_all), config)
            p_i = jax.tree.map(lambda x: x[i], params)
            state = jax.tree.map(lambda x: x[None], training.init_state(p_i, jax.random.fold_in(k_train, i), config))
            state, _ = training.train(state, step, config, desc=f"physics seed {teacher.seeds[i]}", progress=progress)
            new.append(state.params)
        params = jax.tree.map(lambda *x: jnp.concatenate(x), *new)
    return dataclasses.replace(teacher, params=params, losses=None), report
