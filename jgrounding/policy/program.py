"""The compiled sampler of one restored generator: :class:`Model`, what ``jg.sample`` runs after its checkpoint
lookup (:mod:`jgrounding.policy.sampling`).

The parameters of one seed and the intent embeddings live on the device as constants of the compiled program
(no seed axis: a size-1 seed vmap turns every matmul into a batched dot that XLA's CPU backend runs ~10x
slower). One program is compiled per (:class:`~jgrounding.config.SampleConfig`, batch bucket, start mode) and
never traced again (:data:`TRACES` counts). Outputs pass the one safety gate (:func:`jgrounding.safety.gated`).
Trajectory ``r`` of a call (tuple-major, ``r = n * K + k``) draws its noise from ``fold_in(key, r)``, so
results are deterministic per key and do not depend on the batch bucket.

Settings are checked once, where they enter (:meth:`Model.config` for keywords, :meth:`Model.resolve` for a
config; both :meth:`jgrounding.generators.trained.Trained.resolve`'s one check); :meth:`Model.sample` and the
programs take the resolved config as it is.
"""

from __future__ import annotations

import collections
import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding import safety
from jgrounding.config import NUM_STEPS, SampleConfig
from jgrounding.generators import methods
from jgrounding.generators.trained import Trained
from jgrounding.vocabulary import INTENSITIES, INTENTS, NUM_INTENSITIES, intensity_index, intent_index

MAX_SAMPLES = 4096  # samples per tuple
MAX_TRAJECTORIES = 1 << 18  # N x K per call (~630 MB of float32 output)
BUCKETS = (1, 2, 4, 8, 16, 32, 64, 128, 256, 640)  # compiled batch sizes; larger calls run chunks of 640
CLASSIC_RUNTIME = {"xla_cpu_use_thunk_runtime": False}  # XLA's classic CPU runtime, per executable
CLASSIC_MAX_BUCKET = 1  # single trajectories (the latency path) are compiled for it
MAX_PROGRAMS = 64  # compiled programs a model keeps (oldest dropped first: a sweep over many configs)
# How a trajectory begins: "blend" in from the robot's current command within the slew bound; "model": the
# model's own first step (current=None); "inpaint": generated from the current command (start-conditioned).
START_MODES = ("blend", "model", "inpaint")


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


# (checkpoint name, SampleConfig, bucket, start mode) -> times traced; a test checks repeated calls trace once.
TRACES: collections.Counter = collections.Counter()


class Model:
    """A restored generator ready to sample: one seed's parameters and the intent embeddings on the device.

    ``sample`` is what :func:`jgrounding.policy.sampling.sample` runs for a checkpoint; programs are compiled
    once per (resolved :class:`SampleConfig`, batch bucket, start mode).
    """

    def __init__(self, trained: Trained, intent_emb, name: str = "model"):
        trained = trained.first_seed()  # an ablation checkpoint: sample with its first seed
        self.trained = trained
        covered = trained.library.get("tuples")  # tuples of an imported library (None: all 64)
        self.covered = None if covered is None else frozenset(covered)
        self.intent_emb = np.asarray(intent_emb, np.float32)
        self.name = name
        self.generator = trained.generator
        self.guidance = float(trained.sample_config.guidance)  # classifier-free guidance w it samples with
        self._params = jax.device_put(trained.seed_params(0))
        self._emb = jax.device_put(self.intent_emb)
        # every tuple's first-layer context, computed once (no per-call condition layer); None: not this method
        contexts = trained.contexts(self.intent_emb)
        self._contexts = None if contexts is None else jax.device_put(np.asarray(contexts))
        self._programs: dict = {}  # (config, bucket, start mode) -> compiled program, oldest first
        self._single: dict = {}  # (intent, intensity) -> device index arrays of a single-tuple call
        self._configs: dict = {}  # (sampler, steps) keywords of a call -> their SampleConfig (config())
        self._resolved: dict = {}  # a caller's SampleConfig -> resolved (resolve())
        self._zero = jax.device_put(np.int32(0))
        self._rest = jax.device_put(np.zeros(trained.num_tendons, np.float32))

    def program(self, config: SampleConfig, bucket: int, start: str = "blend"):
        """Gated ``(current (N_u,), intent (B,), intensity (B,), first (), key) -> u (B, 150, N_u)`` float32
        numpy, B = bucket; row ``i`` draws its noise from ``fold_in(key, first + i)``. ``start``
        (:data:`START_MODES`): ``"blend"`` in from the robot's ``current`` command; ``"model"``: no ``current``
        argument, the first step as the model made it; ``"inpaint"``: ``(current, current, intent, ...)``, the
        second ``current`` fixing the first spline control (:meth:`Trained.actuation`). ``config``: resolved
        (:meth:`config`, :meth:`resolve`); it keys the cache with ``bucket`` and ``start``."""
        cache_key = (config, bucket, start)
        compiled = self._programs.get(cache_key)
        if compiled is not None:
            return compiled
        tr, params, emb, contexts = self.trained, self._params, self._emb, self._contexts
        continuity, inpaint = start != "model", start == "inpaint"

        def row(intent, intensity, key, u0=None):  # one trajectory; params, embeddings, contexts are constants
            first = None if u0 is None else u0[None]
            if contexts is None:
                cond, context = emb[intent][None], None
            else:
                cond, context = None, contexts[intent * NUM_INTENSITIES + intensity][None]
            return tr.actuation(key, cond, intensity[None], config, params=params, start=first, context=context)[0]

        def run(intent, intensity, first, key, u0=None):
            TRACES[(self.name, *cache_key)] += 1  # Python side effect: counts traces, not calls
            keys = jax.vmap(lambda i: jax.random.fold_in(key, i))(first + jnp.arange(bucket, dtype=jnp.int32))
            return jax.vmap(lambda m, z, k: row(m, z, k, u0))(intent, intensity, keys)

        fn = (lambda u0, *args: run(*args, u0=u0)) if inpaint else run
        gated = safety.gated(fn, continuity=continuity)
        index = np.zeros(bucket, np.int32)
        example = (*(self._rest,) * (int(continuity) + int(inpaint)), index, index, np.int32(0), jax.random.key(0))
        # A single trajectory (the latency path) runs on XLA's classic CPU runtime: on 2 cores 2-3x faster
        # than the thunk runtime (0.031 vs 0.110 ms at S = 2); batches, as fast or faster on the thunk
        # runtime and compiled faster there, keep the default (docs/how_it_works.md, "Latency").
        compiled = gated.specialize(*example, compile=lambda lowered: compile_for(lowered, bucket))
        if len(self._programs) >= MAX_PROGRAMS:
            del self._programs[next(iter(self._programs))]
        self._programs[cache_key] = compiled
        return compiled

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
        """The :class:`SampleConfig` of a call's ``sampler`` (None: the generator's default) and ``steps``
        keywords: this checkpoint's recorded guidance and the noise scale recorded for ``steps``
        (:meth:`temperature`), checked once by :meth:`Trained.settings` (``ValueError`` naming the valid
        choices). Built once per (sampler, steps) of the call's types (a bool is not taken for the integer it
        equals)."""
        key = (type(sampler), sampler, type(steps), steps)
        try:
            return self._configs[key]
        except (KeyError, TypeError):  # TypeError: unhashable, refused below
            pass
        sampler, steps = self.trained.settings(sampler, steps)
        config = dataclasses.replace(
            self.trained.sample_config, sampler=sampler, steps=steps, noise_scale=self.temperature(steps)
        )
        self._configs[key] = config
        return config

    def resolve(self, config: SampleConfig) -> SampleConfig:
        """A caller's whole ``config`` (its guidance and noise scale as given) checked and filled in by
        :meth:`Trained.resolve`, once per distinct config."""
        try:
            return self._resolved[config]
        except KeyError:
            pass
        except TypeError:  # unhashable: not a SampleConfig, which resolve refuses by name
            return self.trained.resolve(config)
        resolved = self._resolved[config] = self.trained.resolve(config)
        return resolved

    def sample(
        self, key, intent, intensity, num_samples=1, config=None, *, current=safety.REST, start_conditioned=False
    ) -> np.ndarray:
        """:func:`jgrounding.policy.sampling.sample` for this model with ``config`` (resolved: from
        :meth:`config` or :meth:`resolve`; default: the model's own), from the robot's ``current`` command
        (same shapes and errors)."""
        check_num_samples(num_samples)
        config = self.config() if config is None else config
        key = as_key(key)
        prefix, continuity = self._current(current)
        start = "blend" if continuity else "model"
        if start_conditioned is not False:
            if start_conditioned is not True:
                raise ValueError(f"start_conditioned must be True or False, got {start_conditioned!r}")
            if not continuity:
                raise ValueError("start_conditioned=True needs the robot's current command (current='rest' or (N_u,))")
            methods.check_start_conditioning(self.trained.method)
            prefix, start = prefix * 2, "inpaint"  # the gate's current, then the inpainted first control
        ms, zs = as_sequence(intent), as_sequence(intensity)
        if ms is None and zs is None:
            m, z = _intent(intent), _intensity(intensity)
            if num_samples == 1:  # the latency path: cached device inputs, one dispatch
                args = self._single.get((m, z))
                if args is None:
                    self._check_covered([m], [z])
                    args = self._single[(m, z)] = jax.device_put((np.array([m], np.int32), np.array([z], np.int32)))
                return self.program(config, 1, start)(*prefix, *args, self._zero, key)[0]
            one = np.array([m], np.int32), np.array([z], np.int32)
            return self._run(key, *one, num_samples, config, prefix, start)[0]
        m, z = _indices(ms, zs, intent, intensity)
        return self._run(key, m, z, num_samples, config, prefix, start)

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

    def _run(self, key, m, z, k, config, prefix=(), start="model") -> np.ndarray:
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
        for first in range(0, total, chunk):
            n = min(chunk, total - first)
            bucket = next(b for b in BUCKETS if b >= n)
            pad = bucket - n
            cm, cz = np.pad(rows_m[first : first + n], (0, pad)), np.pad(rows_z[first : first + n], (0, pad))
            out[first : first + n] = self.program(config, bucket, start)(*prefix, cm, cz, np.int32(first), key)[:n]
        return out.reshape(len(m), k, NUM_STEPS, n_u)


def check_num_samples(num_samples) -> None:
    """``ValueError`` naming the range unless ``num_samples`` is an integer in 1..:data:`MAX_SAMPLES` (the one
    check of it, for :meth:`Model.sample` and screening)."""
    if (
        isinstance(num_samples, bool)
        or not isinstance(num_samples, (int, np.integer))
        or not 1 <= num_samples <= MAX_SAMPLES
    ):
        raise ValueError(f"num_samples must be an integer in 1..{MAX_SAMPLES}, got {num_samples!r}")


def as_sequence(values) -> list | None:
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
    """``key`` as one typed key; ``TypeError`` / ``ValueError`` naming what is accepted."""
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
