"""The public sampler: ``jg.sample(key, intent, intensity, num_samples=1)``.

One tuple gives ``(150, 4)`` (``num_samples == 1``) or ``(K, 150, 4)``; sequences of N tuples give
``(N, K, 150, 4)``. Loads the shipped pretrained Tuple + Spline + RF checkpoint
(``assets/checkpoints/tuple_spline_rf``), or the few-step model ``assets/checkpoints/shipped.json`` names for
the step count (e.g. MeanFlow), once per process. The parameters of one seed and the intent
embeddings live on the device as constants of the compiled program (no seed axis: a size-1 seed vmap
turns every matmul into a batched dot that XLA's CPU backend runs ~10x slower); one program is
compiled per (sampler, steps, batch bucket) and never traced again. Outputs pass the one safety gate
(:func:`jgrounding.safety.gated`): inside [0, 1], slew-limited, never NaN. Trajectory ``r`` of a call
(tuple-major, ``r = n * K + k``) draws its noise from ``fold_in(key, r)``, so results are deterministic
per key and do not depend on the batch bucket.
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import json
import logging
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding import safety
from jgrounding.config import NUM_STEPS, SampleConfig
from jgrounding.generators import methods
from jgrounding.generators.trained import Trained
from jgrounding.training import checkpoints
from jgrounding.vocabulary import INTENSITIES, INTENTS, NUM_INTENSITIES, intensity_index, intent_index

DEFAULT_CHECKPOINT = Path(__file__).resolve().parents[2] / "assets" / "checkpoints" / "tuple_spline_rf"
# Which shipped checkpoint serves which step count (python -m experiments.ship, from the training sweep):
# {"default": <dir>, "few_step": [{"max_steps": S, "checkpoint": <dir>}, ...]} under assets/checkpoints.
SHIPPED = DEFAULT_CHECKPOINT.parent / "shipped.json"
MAX_SAMPLES = 4096  # samples per tuple
MAX_TRAJECTORIES = 1 << 18  # N x K per call (~630 MB of float32 output)
BUCKETS = (1, 2, 4, 8, 16, 32, 64, 128, 256, 640)  # compiled batch sizes; larger calls run chunks of 640
CLASSIC_RUNTIME = {"xla_cpu_use_thunk_runtime": False}  # XLA's classic CPU runtime, per executable
CLASSIC_MAX_BUCKET = 1  # single trajectories (the latency path) are compiled for it


def compiler_options(bucket: int) -> dict | None:
    """XLA options of the program for ``bucket`` trajectories per call: the classic CPU runtime for a single
    trajectory on the CPU, else the defaults (benchmarks compile what they compare against with the same)."""
    return CLASSIC_RUNTIME if bucket <= CLASSIC_MAX_BUCKET and jax.default_backend() == "cpu" else None


def compile_for(lowered, bucket: int):
    """``lowered`` (a ``jax.stages.Lowered``) compiled as jg.sample compiles its program for ``bucket``
    trajectories per call (:func:`compiler_options`); on an XLA without those options, with the defaults (the
    same results)."""
    try:
        return lowered.compile(compiler_options(bucket))
    except Exception:  # an XLA without the option
        return lowered.compile()


# (checkpoint, sampler, steps, bucket) -> times traced; a test checks repeated calls trace once.
TRACES: collections.Counter = collections.Counter()


class Model:
    """A restored generator ready to sample: one seed's parameters and the intent embeddings on the device.

    ``sample`` is what :func:`sample` runs for a checkpoint; programs are compiled once per
    (sampler, steps, batch bucket).
    """

    def __init__(self, trained: Trained, intent_emb, name: str = "model"):
        trained = trained.first_seed()  # an ablation checkpoint: sample with its first seed
        self.trained = trained
        covered = trained.library.get("tuples")  # tuples of an imported library (None: all 64)
        self.covered = None if covered is None else frozenset(covered)
        self.intent_emb = np.asarray(intent_emb, np.float32)
        self.name = name
        self.generator = trained.spec.generator
        self.guidance = float(trained.sample_config.guidance)  # classifier-free guidance w it samples with
        self._params = jax.device_put(trained.seed_params(0))
        self._emb = jax.device_put(self.intent_emb)
        # every tuple's first-layer context, computed once (no per-call condition layer); None: not this method
        contexts = trained.contexts(self.intent_emb)
        self._contexts = None if contexts is None else jax.device_put(np.asarray(contexts))
        self._programs: dict = {}
        self._single: dict = {}  # (intent, intensity) -> device index arrays of a single-tuple call
        self._configs: dict = {}  # (sampler, steps) of a call -> its SampleConfig (config())
        self._zero = jax.device_put(np.int32(0))
        self._rest = jax.device_put(np.zeros(trained.num_tendons, np.float32))

    def program(self, config: SampleConfig, bucket: int, continuity: bool = True, start: bool = False):
        """Gated ``(current (N_u,), intent (B,), intensity (B,), first (), key) -> u (B, 150, N_u)`` float32
        numpy, B = bucket, blended in from the robot's ``current`` command (without ``continuity``: no
        ``current`` argument, first step as the model made it); row ``i`` draws its noise from
        ``fold_in(key, first + i)``. With ``start`` (start-conditioned): ``(current, current, intent, ...)``,
        the second ``current`` fixing the first spline control (:meth:`Trained.actuation`). ``config``: from
        :meth:`config`."""
        cache_key = (config.sampler, config.steps, bucket)
        cache_key = cache_key if continuity else (*cache_key, "no-current")
        cache_key = (*cache_key, "start") if start else cache_key
        if cache_key not in self._programs:
            tr, params, emb, contexts = self.trained, self._params, self._emb, self._contexts

            def row(intent, intensity, key, u0=None):  # one trajectory; params, embeddings, contexts are constants
                start = None if u0 is None else u0[None]
                if contexts is None:
                    cond, context = emb[intent][None], None
                else:
                    cond, context = None, contexts[intent * NUM_INTENSITIES + intensity][None]
                return tr.actuation(key, cond, intensity[None], config, params=params, start=start, context=context)[0]

            def run(intent, intensity, first, key, u0=None):
                TRACES[(self.name, *cache_key)] += 1  # Python side effect: counts traces, not calls
                keys = jax.vmap(lambda i: jax.random.fold_in(key, i))(first + jnp.arange(bucket, dtype=jnp.int32))
                return jax.vmap(lambda m, z, k: row(m, z, k, u0))(intent, intensity, keys)

            fn = (lambda u0, *args: run(*args, u0=u0)) if start else run
            gated = safety.gated(fn, continuity=continuity)
            index = np.zeros(bucket, np.int32)
            example = (*(self._rest,) * (int(continuity) + int(start)), index, index, np.int32(0), jax.random.key(0))
            # A single trajectory (the latency path) runs on XLA's classic CPU runtime: on 2 cores 2-3x faster
            # than the thunk runtime (0.031 vs 0.110 ms at S = 2); batches, as fast or faster on the thunk
            # runtime and compiled faster there, keep the default (docs/how_it_works.md, "Latency").
            self._programs[cache_key] = gated.specialize(*example, compile=lambda lowered: compile_for(lowered, bucket))
        return self._programs[cache_key]

    def temperature(self, steps: int) -> float:
        """The initial-noise scale this model samples ``steps`` steps with (:meth:`Trained.noise_scale_for`)."""
        return self.trained.noise_scale_for(steps)

    def _current(self, current):
        """``(program prefix args, continuity)`` for the robot's current command (validated by the gate)."""
        start = safety.current_command(current, self.trained.num_tendons)
        if start is None:
            return (), False
        return ((self._rest if not start.any() else jax.device_put(start)),), True

    def config(self, sampler: str | None = None, steps: int = SampleConfig.steps) -> SampleConfig:
        """The :class:`SampleConfig` this model samples with for a user's ``sampler`` (None: the generator's
        default) and ``steps``, its recorded guidance kept; ``ValueError`` naming the valid choices. Built once
        per (sampler, steps) of the call's types (a bool is not taken for the integer it equals)."""
        key = (type(sampler), sampler, type(steps), steps)
        try:
            return self._configs[key]
        except (KeyError, TypeError):  # TypeError: unhashable, refused below
            pass
        valid = self.generator.samplers  # the first is the generator's default
        sampler = valid[0] if sampler is None else sampler
        if not isinstance(sampler, str) or sampler not in valid:
            raise ValueError(f"unknown sampler {sampler!r}; valid: {', '.join(valid)}")
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 1 <= steps <= 1000:
            raise ValueError(f"steps must be an integer in 1..1000, got {steps!r}")
        steps = int(steps) if self.generator.iterative else 1
        config = dataclasses.replace(
            self.trained.sample_config, sampler=sampler, steps=steps, noise_scale=self.temperature(steps)
        )
        self._configs[key] = config
        return config

    def sample(
        self, key, intent, intensity, num_samples=1, config=None, *, current=safety.REST, start_conditioned=False
    ) -> np.ndarray:
        """:func:`sample` for this model with ``config`` (a :class:`SampleConfig` from :meth:`config`; default:
        the model's own), from the robot's ``current`` command (same shapes and errors as :func:`sample`)."""
        if (
            isinstance(num_samples, bool)
            or not isinstance(num_samples, (int, np.integer))
            or not 1 <= num_samples <= MAX_SAMPLES
        ):
            raise ValueError(f"num_samples must be an integer in 1..{MAX_SAMPLES}, got {num_samples!r}")
        config = self.config() if config is None else config
        key = as_key(key)
        prefix, continuity = self._current(current)
        if start_conditioned is not False:
            if start_conditioned is not True:
                raise ValueError(f"start_conditioned must be True or False, got {start_conditioned!r}")
            if not continuity:
                raise ValueError("start_conditioned=True needs the robot's current command (current='rest' or (N_u,))")
            methods.check_start_conditioning(self.trained.method)
            prefix = prefix * 2  # the gate's current, then the inpainted first control
        start = bool(start_conditioned)
        ms, zs = _sequence(intent), _sequence(intensity)
        if ms is None and zs is None:
            m, z = _intent(intent), _intensity(intensity)
            if num_samples == 1:  # the latency path: cached device inputs, one dispatch
                args = self._single.get((m, z))
                if args is None:
                    self._check_covered([m], [z])
                    args = self._single[(m, z)] = jax.device_put((np.array([m], np.int32), np.array([z], np.int32)))
                return self.program(config, 1, continuity, start)(*prefix, *args, self._zero, key)[0]
            one = np.array([m], np.int32), np.array([z], np.int32)
            return self._run(key, *one, num_samples, config, prefix, continuity, start)[0]
        m, z = _indices(ms, zs, intent, intensity)
        return self._run(key, m, z, num_samples, config, prefix, continuity, start)

    def _check_covered(self, ms, zs) -> None:
        if self.covered is None:
            return
        for m, z in zip(ms, zs):
            if (int(m), int(z)) not in self.covered:
                names = ", ".join(f"{INTENTS[a]}/{INTENSITIES[b]}" for a, b in sorted(self.covered))
                raise ValueError(
                    f"checkpoint {self.name} was trained on a library without ({INTENTS[m]}, "
                    f"{INTENSITIES[z]}); its tuples: {names}"
                )

    def _run(self, key, m, z, k, config, prefix=(), continuity=False, start_conditioned=False) -> np.ndarray:
        """``(N, K, 150, N_u)`` for index arrays ``m, z (N,)``, in chunks of at most the largest bucket."""
        self._check_covered(m, z)
        total = len(m) * k
        if total > MAX_TRAJECTORIES:
            raise ValueError(
                f"{len(m)} tuples x {k} samples = {total} trajectories; at most {MAX_TRAJECTORIES} per call"
            )
        rows_m, rows_z = np.repeat(m, k), np.repeat(z, k)
        n_u = self.trained.num_tendons
        out = np.empty((total, NUM_STEPS, n_u), np.float32)
        chunk = BUCKETS[-1]
        for start in range(0, total, chunk):
            n = min(chunk, total - start)
            bucket = next(b for b in BUCKETS if b >= n)
            pad = bucket - n
            cm, cz = np.pad(rows_m[start : start + n], (0, pad)), np.pad(rows_z[start : start + n], (0, pad))
            out[start : start + n] = self.program(config, bucket, continuity, start_conditioned)(
                *prefix, cm, cz, np.int32(start), key
            )[:n]
        return out.reshape(len(m), k, NUM_STEPS, n_u)


def _sequence(values) -> list | None:
    """The elements of a list, tuple or 1-d array of tuples' names/indices; None for anything else (a single
    value, validated by the vocabulary)."""
    if isinstance(values, (list, tuple)):
        return list(values)
    if isinstance(values, (np.ndarray, jax.Array)) and values.ndim == 1:
        return np.asarray(values).tolist()
    return None


def _lookup(index_fn):
    cached = functools.lru_cache(maxsize=4096, typed=True)(index_fn)

    def index(value) -> int:
        try:
            return cached(value)
        except TypeError:  # unhashable: the uncached call raises the vocabulary's own message
            return index_fn(value)

    return index


_intent, _intensity = _lookup(intent_index), _lookup(intensity_index)


def _indices(ms: list | None, zs: list | None, intent, intensity) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays ``(N,)`` for sequences of tuples; a single value is repeated to the other's length."""
    if ms is not None and zs is not None and len(ms) != len(zs):
        raise ValueError(f"intents and intensities must have the same length, got {len(ms)} and {len(zs)}")
    n = len(ms) if ms is not None else len(zs)
    if n == 0:
        raise ValueError(
            f"intents and intensities must name at least one tuple, got empty sequences; "
            f"valid intents: {', '.join(INTENTS)}; valid intensities: {', '.join(INTENSITIES)}"
        )
    m = np.array([_intent(v) for v in ms] if ms is not None else [_intent(intent)] * n, np.int32)
    z = np.array([_intensity(v) for v in zs] if zs is not None else [_intensity(intensity)] * n, np.int32)
    return m, z


@functools.lru_cache(maxsize=16)
def _is_key_dtype(dtype) -> bool:
    return bool(jnp.issubdtype(dtype, jax.dtypes.prng_key))


def as_key(key):
    accepted = "a typed key from jax.random.key(seed) or a raw uint32[2] key from jax.random.PRNGKey(seed)"
    if isinstance(key, jax.Array) and _is_key_dtype(key.dtype):
        if key.shape != ():
            raise ValueError(f"key must be a single key ({accepted}), got a key array of shape {key.shape}")
        return key
    arr = np.asarray(key) if isinstance(key, (jax.Array, np.ndarray)) else None
    if arr is not None and arr.dtype == np.uint32 and arr.shape == (2,):
        return jax.random.wrap_key_data(jnp.asarray(arr))
    got = f"{arr.dtype}{list(arr.shape)} array" if arr is not None else type(key).__name__
    raise TypeError(f"key must be {accepted}; got {got}")


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


def sample(
    key,
    intent,
    intensity,
    num_samples: int = 1,
    *,
    sampler: str | None = None,
    steps: int = SampleConfig.steps,
    checkpoint: str | Path | None = None,
    current=safety.REST,
    start_conditioned: bool = False,
    screen: bool = False,
    allow_library_mismatch: bool = False,
) -> np.ndarray:
    """Sample tendon actuation for (intent, intensity) tuples (names or indices).

    Args:
      key: ``jax.random.key(seed)`` or a raw ``jax.random.PRNGKey(seed)``; results are deterministic per key.
      intent, intensity: one name or index each, or sequences of N of them (a single value is repeated).
      num_samples: K samples per tuple, 1..4096.
      sampler: ``euler`` (default) | ``midpoint`` | ``rk4`` for a rectified flow; ``ancestral`` | ``ddim``
        for a DDPM checkpoint. steps: S sampler steps, 1..1000.
      checkpoint: a checkpoint directory (default: the shipped model that serves ``steps`` best,
        :func:`shipped_checkpoint`, e.g. MeanFlow for a few steps, or the default RF when that model has no
        such ``sampler``); each checkpoint samples with its recorded guidance weight.
      current: the command the robot holds now: ``"rest"`` (default, every tendon slack), a ``(N_u,)``
        command in [0, 1] (e.g. the last step of the previous response), or None. The trajectories blend
        in from it within the slew bound (:mod:`jgrounding.safety`, guarantee 4), so consecutive
        responses never jump; None returns the model's own first step (what evaluation compares).
      start_conditioned: instead of blending in from ``current``, generate the motion from it: the first
        Catmull-Rom control is fixed to ``current`` by inpainting during the flow integration (known
        coordinates set to ``lambda * current + (1 - lambda) * eps`` at every flow time lambda), so the
        trajectory starts exactly at ``current`` (``u[0] == current``) and the model shapes the rest from
        there; still gated (bounds, slew limit from ``current``). Needs ``current`` (not None) and a
        rectified flow over spline controls (the shipped models); ``ValueError`` otherwise.
      screen: simulate candidates on the trunk and return only feasible ones (:func:`screened`, which also
        reports how many were rejected); raises :class:`ScreeningError` if too few pass within its budget.
      allow_library_mismatch: use a checkpoint trained on another library version (refused otherwise).
    Returns:
      float32 actuation inside [0, 1]: ``(150, N_u)`` for one tuple and ``num_samples == 1``,
      ``(K, 150, N_u)`` for one tuple, ``(N, K, 150, N_u)`` for sequences; N_u = 4 for the shipped
      checkpoint, else the number of tendons of the checkpoint's library. A ``checkpoint`` trained on a
      library without a requested tuple (an imported library covers only the tuples recorded) is refused
      with a ``ValueError`` listing its tuples.

    The first call of a (sampler, steps, batch size) setting compiles it; with JAX's persistent cache
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
        ).u
    if checkpoint is None and isinstance(steps, (int, np.integer)) and not isinstance(steps, bool):
        if sampler is None or isinstance(sampler, str):
            checkpoint = _route(SHIPPED, int(steps), sampler)
    loaded = model(checkpoint, allow_library_mismatch)
    config = loaded.config(sampler, steps)
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
    key, intent, intensity, num_samples: int = 1, *, budget: int | None = None, engine: str = "auto", **sample_kwargs
) -> Screened:
    """Screened sampling: draw candidates, roll them out on the trunk in one batch per round and keep the
    feasible ones (:func:`jgrounding.sim.feasible`: stable, contact force within bounds, slow tip near
    the user) until every tuple has ``num_samples``.

    Args:
      key, intent, intensity, num_samples, **sample_kwargs: as :func:`sample` (``sampler``, ``steps``,
        ``checkpoint``, ``current``). The candidates are the trajectories that would be emitted, blended in
        from ``current``; they are simulated from the trunk at rest (exact for the default ``"rest"``).
      budget: candidates per tuple at most (default ``max(SCREEN_BUDGET, 4 * num_samples)``, capped at
        ``MAX_SAMPLES``).
      engine: :func:`jgrounding.sim.rollout` engine (``auto``: native on CPU, MJX on an accelerator).
    Returns:
      :class:`Screened`: ``u`` shaped as :func:`sample` returns it, the candidates simulated, how many
      were rejected, the rounds and the simulation time. Round r draws with ``fold_in(key, r)``.
    Raises:
      ScreeningError (a ``ValueError``) when, for some tuple, fewer than ``num_samples`` of ``budget``
      candidates pass.
    """
    from jgrounding import sim

    if (
        isinstance(num_samples, bool)
        or not isinstance(num_samples, (int, np.integer))
        or not 1 <= num_samples <= MAX_SAMPLES
    ):
        raise ValueError(f"num_samples must be an integer in 1..{MAX_SAMPLES}, got {num_samples!r}")
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
    engine = sim.resolve_engine(engine)
    key = as_key(key)
    single = _sequence(intent) is None and _sequence(intensity) is None
    kept, drawn, passed, seconds, rounds = None, 0, 0, 0.0, 0
    while drawn < budget:
        missing = num_samples - (min(len(k) for k in kept) if kept else 0)
        if missing <= 0:
            break
        c = int(min(budget - drawn, missing + max(2, -(-missing // 4))))  # a few spare for the rejections
        u = np.asarray(sample(jax.random.fold_in(key, rounds), intent, intensity, num_samples=c, **sample_kwargs))
        u = u.reshape(-1, c, *u.shape[-2:])  # (N, c, 150, N_u)
        if u.shape[-1] != sim.NUM_CHANNELS:
            raise ValueError(
                f"screening simulates the built-in {sim.NUM_CHANNELS}-tendon trunk; this checkpoint "
                f"has {u.shape[-1]} tendons"
            )
        t0 = time.perf_counter()
        ok = (sim.margins(u.reshape(-1, *u.shape[-2:]), engine=engine) >= 0).reshape(u.shape[:2])
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
