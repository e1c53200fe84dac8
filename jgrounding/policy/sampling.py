"""The public sampler: ``jg.sample(key, intent, intensity, num_samples=1, ..., config=None)``.

One tuple gives ``(150, 4)`` (``num_samples == 1``) or ``(K, 150, 4)``; sequences of N tuples give
``(N, K, 150, 4)``. Loads the shipped pretrained Tuple + Spline + RF checkpoint
(``jgrounding/assets/checkpoints/tuple_spline_rf``), or the few-step model ``jgrounding/assets/checkpoints/shipped.json`` names for
the step count (e.g. MeanFlow), once per process, and runs its compiled sampler
(:class:`jgrounding.policy.program.Model`: one program per (config, batch bucket, start mode), never traced
again; outputs through the one safety gate; deterministic per key, whatever the bucket).

Settings travel as a value: ``config=SampleConfig(...)`` (sampler, steps, guidance, noise scale) is used as
given, so a sweep over settings passes configs instead of rewriting a checkpoint's ``meta.json``; the
``sampler=`` / ``steps=`` keywords take the checkpoint's recorded guidance and noise scale instead
(:func:`default_config` is that config, to start a sweep from). Both are checked once, here
(:func:`request`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import time
import warnings
from pathlib import Path

import jax
import numpy as np

from jgrounding import safety
from jgrounding.config import NUM_STEPS, SampleConfig
from jgrounding.generators import methods
from jgrounding.io import asset
from jgrounding.policy.program import (
    BUCKETS,
    CLASSIC_RUNTIME,
    MAX_SAMPLES,
    MAX_TRAJECTORIES,
    TRACES,
    Model,
    as_key,
    as_sequence,
    check_num_samples,
    compile_for,
    compiler_options,
)
from jgrounding.training import checkpoints
from jgrounding.vocabulary import INTENSITIES, INTENTS

# the compiled sampler's names, reached through the public sampler's module as before
__all__ = [
    "BUCKETS",
    "CLASSIC_RUNTIME",
    "DEFAULT_CHECKPOINT",
    "MAX_SAMPLES",
    "MAX_TRAJECTORIES",
    "SCREEN_BUDGET",
    "SHIPPED",
    "TRACES",
    "Model",
    "Screened",
    "ScreeningError",
    "as_key",
    "compile_for",
    "compiler_options",
    "default_config",
    "load",
    "model",
    "request",
    "sample",
    "screened",
    "shipped_checkpoint",
]

DEFAULT_CHECKPOINT = asset("checkpoints", "tuple_spline_rf")
# Which shipped checkpoint serves which step count (python -m experiments.ship, from the training sweep):
# {"default": <dir>, "few_step": [{"max_steps": S, "checkpoint": <dir>}, ...]} under jgrounding/assets/checkpoints.
SHIPPED = DEFAULT_CHECKPOINT.parent / "shipped.json"


class _Unset:
    """The default of ``steps=``: told apart from every value a caller passes (None included, which is refused)."""

    def __repr__(self) -> str:
        return "50"  # SampleConfig.steps, unless config= gives them


UNSET = _Unset()


@functools.lru_cache(maxsize=4)
def model(checkpoint: str | Path | None = None, allow_library_mismatch: bool = False) -> Model:
    """The :class:`Model` of a checkpoint directory (default: the shipped RF), restored once per process.

    Refuses (``ValueError`` naming the directory) a checkpoint of an unknown method, another
    vocabulary, wrong array shapes or non-finite weights (:func:`jgrounding.training.checkpoints.restore_trained`),
    and one whose model fails a self-test: one sample of the first tuple must be a finite ``(150, 4)`` trajectory.
    An ablation checkpoint (several seeds) samples with its first seed. A checkpoint trained on another
    library is refused unless ``allow_library_mismatch`` (the one rule: :func:`checkpoints.library_mismatch`).
    """
    from jgrounding import semantics

    if checkpoint is not None and not isinstance(checkpoint, (str, Path)):
        raise TypeError(f"checkpoint must be a directory path (str or pathlib.Path), got {type(checkpoint).__name__}")
    path = Path(checkpoint) if checkpoint else DEFAULT_CHECKPOINT
    trained = checkpoints.restore_trained(path, allow_library_mismatch=allow_library_mismatch)
    loaded = Model(trained, semantics.intent_embeddings(), name=str(path))
    m, z = min(loaded.covered) if loaded.covered else (0, 0)
    try:  # the self-test compiles the executable the first default ``sample`` call reuses
        u = loaded.sample(jax.random.key(0), m, z)
    except safety.UnsafeActuationError as err:
        u = err
    if not isinstance(u, np.ndarray) or u.shape != (NUM_STEPS, trained.num_tendons):
        bad = f"shape {u.shape}" if isinstance(u, np.ndarray) else f"non-finite values ({u})"
        raise ValueError(
            f"checkpoint {path} failed its load self-test: a sample of "
            f"({INTENTS[m]}, {INTENSITIES[z]}) has {bad}; refusing to use it"
        )
    return loaded


@functools.lru_cache(maxsize=4)
def _shipped_manifest(path: Path) -> dict | None:
    """The parsed shipped-model manifest, read once per process (not on every ``jg.sample`` call)."""
    return json.loads(path.read_text()) if path.exists() else None


def shipped_checkpoint(steps: int) -> Path:
    """The shipped checkpoint that serves ``steps`` best (:data:`SHIPPED`, chosen by
    ``python -m experiments.sweep training``): the few-step model of the smallest listed
    ``max_steps >= steps`` (e.g. a 2-rectified flow), else the default."""
    manifest = _shipped_manifest(SHIPPED)
    if manifest is None:
        return DEFAULT_CHECKPOINT
    fits = [e for e in manifest.get("few_step", []) if steps <= e["max_steps"]]
    name = min(fits, key=lambda e: e["max_steps"])["checkpoint"] if fits else manifest.get("default")
    return DEFAULT_CHECKPOINT.parent / name if name else DEFAULT_CHECKPOINT


@functools.lru_cache(maxsize=256)
def _route(manifest: Path, steps: int, sampler: str | None) -> Path | None:
    """The checkpoint ``jg.sample`` uses for ``steps`` and ``sampler`` (None: the default): the shipped one for
    ``steps`` (:func:`shipped_checkpoint`), unless its generator has no such sampler (e.g. ``midpoint`` for a
    MeanFlow or shortcut model), which the default then serves. ``manifest``: :data:`SHIPPED` (a cache key)."""
    del manifest  # shipped_checkpoint reads it
    path = shipped_checkpoint(steps)
    if path == DEFAULT_CHECKPOINT:
        return None
    method = checkpoints.read_meta(path).get("method")
    if sampler is not None and method in methods.REGISTRY and sampler not in methods.spec(method).generator.samplers:
        return None
    return path


def load(checkpoint: str | Path | None = None, allow_library_mismatch: bool = False):
    """(Trained, intent embeddings ``(16, 384)``) of :func:`model` (cached; same refusals)."""
    loaded = model(checkpoint, allow_library_mismatch)
    return loaded.trained, loaded.intent_emb


load.cache_clear = model.cache_clear  # forgets the loaded models (a test's "new process")


def request(
    sampler=None,
    steps=UNSET,
    config: SampleConfig | None = None,
    checkpoint: str | Path | None = None,
    allow_library_mismatch: bool = False,
) -> tuple[Model, SampleConfig]:
    """The boundary of :func:`sample` and :func:`screened`: the :class:`Model` that serves the call and its
    resolved :class:`SampleConfig`, every setting checked once (``ValueError`` naming the valid choices).

    ``config`` given, ``sampler`` and ``steps`` must be left out (``ValueError``: they would conflict; put them
    in the config with ``dataclasses.replace``); without it they take the checkpoint's recorded guidance and
    noise scale (:meth:`Model.config`). With no ``checkpoint``, the config's or keywords' steps and sampler
    choose the shipped one (:func:`shipped_checkpoint`)."""
    if config is not None:
        if sampler is not None or steps is not UNSET:
            given = ", ".join(
                f"{n}={v!r}" for n, v in (("sampler", sampler), ("steps", steps)) if v not in (None, UNSET)
            )
            raise ValueError(
                f"pass sampler and steps either as keywords or in config, not both: got config={config!r} and "
                f"{given}; use config=dataclasses.replace(config, {given})"
            )
        if not isinstance(config, SampleConfig):
            raise TypeError(f"config must be a jgrounding.config.SampleConfig, got {type(config).__name__}")
        sampler, steps = config.sampler, config.steps
    elif steps is UNSET:
        steps = SampleConfig.steps
    if checkpoint is None and isinstance(steps, (int, np.integer)) and not isinstance(steps, bool):
        if sampler is None or isinstance(sampler, str):
            checkpoint = _route(SHIPPED, int(steps), sampler)
    loaded = model(checkpoint, allow_library_mismatch)
    return loaded, (loaded.config(sampler, steps) if config is None else loaded.resolve(config))


def default_config(
    sampler: str | None = None,
    steps: int = SampleConfig.steps,
    checkpoint: str | Path | None = None,
    allow_library_mismatch: bool = False,
) -> SampleConfig:
    """The config ``jg.sample(..., sampler=sampler, steps=steps, checkpoint=checkpoint)`` samples with: the
    serving checkpoint's recorded guidance and noise scale for ``steps``. Start a sweep from it:
    ``dataclasses.replace(default_config(steps=8), guidance=0.5)``."""
    return request(sampler, steps, None, checkpoint, allow_library_mismatch)[1]


def sample(
    key,
    intent,
    intensity,
    num_samples: int = 1,
    *,
    sampler: str | None = None,
    steps: int = UNSET,
    checkpoint: str | Path | None = None,
    current=safety.REST,
    start_conditioned: bool = False,
    screen: bool = False,
    allow_library_mismatch: bool = False,
    config: SampleConfig | None = None,
    trunk: str | None = None,
) -> np.ndarray:
    """Sample tendon actuation for (intent, intensity) tuples (names or indices).

    Args:
      key: ``jax.random.key(seed)`` or a raw ``jax.random.PRNGKey(seed)``; results are deterministic per key.
      intent, intensity: one name or index each, or sequences of N of them (a single value is repeated).
      num_samples: K samples per tuple, 1..4096.
      sampler: ``euler`` (default) | ``midpoint`` | ``rk4`` for a rectified flow; ``ancestral`` | ``ddim``
        for a DDPM checkpoint. steps: S sampler steps, 1..1000 (default 50). Both sample with the
        checkpoint's recorded guidance weight and noise scale; leave them out when ``config`` is given.
      checkpoint: a checkpoint directory (default: the shipped model that serves ``steps`` best,
        :func:`shipped_checkpoint`, e.g. MeanFlow for a few steps, or the default RF when that model has no
        such ``sampler``).
      current: the command the robot holds now: ``"rest"`` (default, every tendon slack), a ``(N_u,)``
        command in [0, 1] (e.g. the last step of the previous response), or None. The trajectories blend
        in from it within the slew bound (:mod:`jgrounding.safety`, guarantee 4), so consecutive
        responses never jump; None returns the model's own first step (what evaluation compares).
      start_conditioned: instead of blending in from ``current``, generate the motion from it: the first
        Catmull-Rom control is fixed to ``current`` by inpainting during the flow integration (known
        coordinates set to ``lambda * current + (1 - lambda) * eps`` at every flow time lambda), so the
        trajectory starts exactly at ``current`` (``u[0] == current``) and the model shapes the rest from
        there; still gated (bounds, slew limit from ``current``). Needs ``current`` (not None) and a
        generator that inpaints over spline controls (the shipped models); ``ValueError`` otherwise.
      screen: simulate candidates on the trunk and return only feasible ones (:func:`screened`, which also
        reports how many were rejected); raises :class:`ScreeningError` if too few pass within its budget.
      trunk: the trunk MJCF screening simulates (a fitted one, ``python -m jgrounding.sim calibrate``; None: the
        shipped trunk); a trunk other than the one the checkpoint's library was screened on is warned about.
      allow_library_mismatch: use a checkpoint trained on another library version (refused otherwise).
      config: a :class:`~jgrounding.config.SampleConfig` (sampler, steps, guidance w, noise scale T), used
        as given instead of the checkpoint's recorded settings (:func:`default_config` gives those);
        ``ValueError`` together with ``sampler`` or ``steps``. Calls with equal configs share one compiled
        program.
    Returns:
      float32 actuation inside [0, 1]: ``(150, N_u)`` for one tuple and ``num_samples == 1``,
      ``(K, 150, N_u)`` for one tuple, ``(N, K, 150, N_u)`` for sequences; N_u = 4 for the shipped
      checkpoint, else the number of tendons of the checkpoint's library. A ``checkpoint`` trained on a
      library without a requested tuple (an imported library covers only the tuples recorded) is refused
      with a ``ValueError`` listing its tuples.

    The first call of a (config, batch size) setting compiles it; with JAX's persistent cache
    (``JAX_COMPILATION_CACHE_DIR=...`` and ``JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS=0``) a new
    process reuses it. Calls with 2..640 trajectories share 9 compiled sizes; more run in chunks of 640.
    """
    if screen is not False:
        if screen is not True:
            raise ValueError(f"screen must be True or False, got {screen!r}")
        return screened(
            key,
            intent,
            intensity,
            num_samples,
            sampler=sampler,
            steps=steps,
            checkpoint=checkpoint,
            current=current,
            start_conditioned=start_conditioned,
            allow_library_mismatch=allow_library_mismatch,
            config=config,
            trunk=trunk,
        ).u
    loaded, config = request(sampler, steps, config, checkpoint, allow_library_mismatch)
    return loaded.sample(
        key, intent, intensity, num_samples, config, current=current, start_conditioned=start_conditioned
    )


class ScreeningError(ValueError):
    """Raised when too few candidates pass the simulated trunk's feasibility check within the budget."""


@dataclasses.dataclass(frozen=True)
class Screened:
    """Result of :func:`screened`: only samples the simulated trunk found feasible, and the bookkeeping."""

    u: np.ndarray  # as sample() returns it: (150, N_u), (K, 150, N_u) or (N, K, 150, N_u); every one feasible
    candidates: int  # trajectories drawn and simulated, all tuples together
    rejected: int  # of them, infeasible
    rounds: int  # draw -> simulate rounds
    seconds: float  # wall time of the simulation
    engine: str  # the trunk engine used


SCREEN_BUDGET = 64  # default: at most this many candidates per tuple (4 x num_samples when larger)


def screened(
    key,
    intent,
    intensity,
    num_samples: int = 1,
    *,
    budget: int | None = None,
    engine: str = "auto",
    sampler: str | None = None,
    steps: int = UNSET,
    checkpoint: str | Path | None = None,
    current=safety.REST,
    start_conditioned: bool = False,
    allow_library_mismatch: bool = False,
    config: SampleConfig | None = None,
    trunk: str | None = None,
) -> Screened:
    """Screened sampling: draw candidates, roll them out on the trunk in one batch per round and keep the
    feasible ones (:func:`jgrounding.sim.feasible`: stable, contact force within bounds, slow tip near
    the user) until every tuple has ``num_samples``.

    Args:
      key, intent, intensity, num_samples, sampler, steps, checkpoint, current, start_conditioned,
        allow_library_mismatch, config: as :func:`sample`. The candidates are the trajectories that would be
        emitted, blended in from ``current``; they are simulated from the trunk at rest (exact for the
        default ``"rest"``).
      budget: candidates per tuple at most (default ``max(SCREEN_BUDGET, 4 * num_samples)``, capped at
        ``MAX_SAMPLES``).
      engine: :func:`jgrounding.sim.rollout` engine (``auto``: native on CPU, MJX on an accelerator).
      trunk: the trunk MJCF simulated (None: the shipped trunk); a trunk other than the one the checkpoint's
        library was screened on is warned about (:func:`jgrounding.sim.trunk_mismatch`), naming both.
    Returns:
      :class:`Screened`: ``u`` shaped as :func:`sample` returns it, the candidates simulated, how many
      were rejected, the rounds and the simulation time. Round r draws with ``fold_in(key, r)``.
    Raises:
      ScreeningError (a ``ValueError``) when, for some tuple, fewer than ``num_samples`` of ``budget``
      candidates pass.
    """
    from jgrounding import sim

    check_num_samples(num_samples)
    if budget is None:  # the default never exceeds the cap, so only a user's own budget= can be refused
        budget = min(MAX_SAMPLES, max(SCREEN_BUDGET, 4 * int(num_samples)))
    elif (
        isinstance(budget, bool)
        or not isinstance(budget, (int, np.integer))
        or not num_samples <= budget <= MAX_SAMPLES
    ):
        raise ValueError(
            f"budget must be an integer in num_samples..{MAX_SAMPLES} (here {num_samples}..{MAX_SAMPLES}: "
            f"candidates per tuple), got {budget!r}"
        )
    trunk = sim.resolve_trunk(trunk)
    engine = sim.resolve_engine(engine, trunk)
    key = as_key(key)
    loaded, config = request(sampler, steps, config, checkpoint, allow_library_mismatch)
    why = sim.trunk_mismatch((loaded.trained.library or {}).get("trunk"), trunk)
    if why:
        warnings.warn(f"checkpoint {loaded.name}: its library was {why}", stacklevel=2)
    draw = functools.partial(loaded.sample, config=config, current=current, start_conditioned=start_conditioned)
    single = as_sequence(intent) is None and as_sequence(intensity) is None
    kept, drawn, passed, seconds, rounds = None, 0, 0, 0.0, 0
    while drawn < budget:
        missing = num_samples - (min(len(k) for k in kept) if kept else 0)
        if missing <= 0:
            break
        c = int(min(budget - drawn, missing + max(2, -(-missing // 4))))  # a few spare for the rejections
        u = np.asarray(draw(jax.random.fold_in(key, rounds), intent, intensity, c))
        u = u.reshape(-1, c, *u.shape[-2:])  # (N, c, 150, N_u)
        if u.shape[-1] != sim.NUM_CHANNELS:
            raise ValueError(
                f"screening simulates the built-in {sim.NUM_CHANNELS}-tendon trunk; this checkpoint "
                f"has {u.shape[-1]} tendons"
            )
        t0 = time.perf_counter()
        ok = (sim.margins(u.reshape(-1, *u.shape[-2:]), engine=engine, trunk=trunk) >= 0).reshape(u.shape[:2])
        seconds += time.perf_counter() - t0
        kept = kept or [[] for _ in range(len(u))]
        for j in range(len(u)):
            kept[j].extend(u[j][ok[j]][: num_samples - len(kept[j])])
        drawn, passed, rounds = drawn + c, passed + int(ok.sum()), rounds + 1
    have = np.array([len(k) for k in kept])
    if (have < num_samples).any():
        short = np.flatnonzero(have < num_samples)
        raise ScreeningError(
            f"screening: {len(short)} of {len(kept)} tuple(s) got fewer than {num_samples} feasible samples within "
            f"the budget of {budget} candidates per tuple (worst: {have.min()} passed; first such tuple: "
            f"position {short[0]}). Feasible = stable, contact force <= {sim.MAX_CONTACT_FORCE} N and tip speed "
            f"<= {sim.MAX_TIP_SPEED_NEAR_USER} m/s within {sim.NEAR_USER_DISTANCE} m of the user; pass a larger "
            "budget= or ask for fewer samples"
        )
    out = np.stack([np.stack(k) for k in kept])  # (N, K, 150, N_u)
    if single:
        out = out[0, 0] if num_samples == 1 else out[0]
    total = drawn * len(kept)
    logging.getLogger(__name__).info("screened %d candidates, %d rejected as infeasible", total, total - passed)
    return Screened(u=out, candidates=total, rejected=total - passed, rounds=rounds, seconds=seconds, engine=engine)
