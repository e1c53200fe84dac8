"""The ablation's result, typed: what :func:`experiments.ablation.run` returns and
:mod:`experiments.ablation_report` formats, and its one file format.

A result is written by :func:`save` (``<out>/ablation.json`` and the per-sample RMS in ``<out>/ablation_rms.npz``)
and read back by :func:`load`; every reader of results/ablation.json (the report, the sweeps, ``bench trunk``,
the tests) goes through :func:`load`. The file records :data:`SCHEMA`; a file of another schema is refused with
the command that regenerates it. Means and stds are :data:`MeanStd` pairs; "over seeds" is ddof = 1.
"""

from __future__ import annotations

import dataclasses
import io
import json
import types
import typing
from pathlib import Path

import numpy as np

from jgrounding import config as configs
from jgrounding.config import Config
from jgrounding.evaluation.physics import ShapeTolerance
from jgrounding.io import write_atomic

SCHEMA = 2  # results/ablation.json's version; 1 (no "schema" field) was a dict of string keys
REGENERATE = "make ablation (python -m experiments.ablation [--out DIR])"
MeanStd = tuple[float, float]  # (mean, std) over training seeds, sampling keys or replay draws
_NAN = (float("nan"), float("nan"))
_ARRAYS = {"json": False}  # field metadata: an array field, not in ablation.json (the RMS goes to the .npz)


@dataclasses.dataclass(frozen=True)
class Scores:
    """Benchmark v3 metrics of one row against the evaluation set (:mod:`jgrounding.evaluation.distribution`);
    metric names: ``distribution.HEADLINE``, ``"frechet"`` and ``"prec_r_split"``."""

    mean_std: dict[str, MeanStd]  # metric -> (mean, std) over seeds (methods), keys (jg.sample) or one draw
    per_seed: dict[str, tuple[float, ...]]  # metric -> its value per seed / key (for tests between rows)
    std_error: dict[str, float]  # metric -> std / sqrt(n) over the same


@dataclasses.dataclass(frozen=True)
class Physics:
    """The physics columns of one row: the simulated samples (``EvalConfig.physics_samples`` of each tuple's K_div)
    rolled out on the trunk against the held-out references."""

    shape_rms_m: MeanStd  # backbone RMS (over time and the 11 backbone points) to the reference's motion, m
    shape_success: MeanStd  # fraction of all samples within ShapeTolerance.tau_m
    shape_diversity_m: MeanStd  # mean pairwise shape RMS of a tuple's K_div samples, m
    feasible: MeanStd  # fraction of samples stable, with contact force and tip speed within bounds
    simulated: int  # distinct trajectories rolled out (a regressor's identical samples are simulated once)
    samples: int  # samples scored: seeds x 64 x K_div
    seconds: float  # wall time of the rollouts, s
    engine: str  # the engine used: "native", "mjx", or "skipped" (a library whose N_u is not the trunk's 4)


NO_PHYSICS = Physics(_NAN, _NAN, _NAN, _NAN, simulated=0, samples=0, seconds=0.0, engine="skipped")


@dataclasses.dataclass(frozen=True)
class Row:
    """One row of Table II: a registry entry trained over the seeds, evaluated on the 64 held-out tuples."""

    success: MeanStd  # fraction of tuples whose first sample is within tau of the reference (paper protocol)
    success_all_samples: MeanStd  # fraction of all K_div samples within tau
    rms: MeanStd  # normalized actuation RMS to the held-out reference, mean over tuples and samples
    diversity: MeanStd  # mean pairwise RMS of a tuple's K_div samples (normalized actuation)
    coverage: MeanStd  # mean over a tuple's realizations of the RMS to its nearest sample (lower: more reached)
    time_ms: float  # warm single trajectory, ms: median over the interleaved rounds of per-round medians
    time_measures: str  # what time_ms timed (jg.sample's public path, or the compiled core for raw text)
    throughput_per_s: float  # samples per second of the batched evaluation (all seeds)
    train_s: float  # wall time of training all seeds, s
    first_sample_success_per_seed: tuple[float, ...]  # ``success`` per seed (Welch tests between rows)
    distribution: Scores | None  # None: the library has no evaluation set
    physics: Physics
    # Per-round medians of the interleaved timing (latency.interleaved_ms: every method timed in each round,
    # in a fresh order) and the distribution-free 95% interval of their median; () in runs recorded before that.
    time_rounds_ms: tuple[float, ...] = ()
    time_interval_ms: tuple[float, ...] = ()


@dataclasses.dataclass(frozen=True)
class Reference:
    """A reference of the paper-protocol metric: a replay (mean, std over draws) or a bracket (expected, std 0)."""

    success: dict[float, MeanStd]  # tau (metrics.TAUS) -> fraction of held-out tuples within tau
    rms: MeanStd  # normalized actuation RMS to the held-out reference


@dataclasses.dataclass(frozen=True)
class Timing:
    """Wall time of the run's parts, s; ``physics_s`` overlaps the others (every rollout of the run)."""

    library_simulation_s: float  # the library simulated once: held-out references and the shape tolerance
    train_s: float  # every row's training, fine-tuning included
    evaluate_s: float  # generation, actuation metrics and latency
    distribution_s: float  # the rows' benchmark v3 metrics
    public_s: float | None  # the shipped model through jg.sample; None: not the shipped library
    distribution_references_s: float | None  # benchmark v3 reference rows; None: no evaluation set
    physics_s: float  # every rollout: library, fine-tuning screens, rows and references
    run_s: float  # the whole run
    latency_s: float | None = None  # Table II's Time, measured interleaved (None: a run recorded before it was)

    def parts(self) -> dict[str, float]:
        """The recorded parts, in order."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if getattr(self, f.name) is not None}


@dataclasses.dataclass(frozen=True)
class Environment:
    """What can make a re-run differ on another machine."""

    cpu_isa: str  # avx512f, avx2+fma, sse (bench_sample.cpu_isa) or the machine: XLA emits code for it (bit-for-bit only on the same one)
    cpu_count: int
    xla_flags: str  # $XLA_FLAGS ("" when unset)
    omp_num_threads: str  # $OMP_NUM_THREADS ("" when unset)
    jax: str  # version
    backend: str  # jax.default_backend()
    devices: int  # jax.device_count()
    numpy: str  # version
    python: str  # version


@dataclasses.dataclass(frozen=True)
class AblationResult:
    """One run of ``python -m experiments.ablation``: Table II, its references, benchmark v3 and provenance."""

    config: Config  # the whole composed configuration of the run (named entry and overrides)
    rows: dict[str, Row]  # registry name -> its row, in the order reported
    references: dict[str, Reference]  # oracle, tuple_mean, replays, brackets (those the library can make)
    reference_physics: dict[str, Physics]  # oracle, wrong_intent_any_intensity, tuple_mean replayed on the trunk
    distribution_references: dict[str, Scores]  # distribution.REFERENCES name -> one draw; empty: no evaluation set
    public: dict[str, Scores]  # "default" / "none" (current=None): jg.sample of the shipped model; else empty
    radius: float | None  # r of benchmark v3 (normalized RMS); None: no evaluation set
    shape_tolerance: ShapeTolerance | None  # shape success's tolerance; None: physics skipped (N_u != 4)
    physics_engine: str  # the engine "auto" (or eval.engine) resolved to
    library_version: str | None  # the library's meta "library_version"
    timing: Timing
    environment: Environment | None  # None: not recorded (an older run, migrated to this schema)
    date: str  # when the run finished, ISO seconds
    machine: str  # host · processor · cores · jax version (backend)
    public_rescored: str | None = None  # when --rescore-public last replaced ``public``, ISO seconds
    per_sample_rms: dict[str, np.ndarray] = dataclasses.field(default_factory=dict, compare=False, metadata=_ARRAYS)
    # ^ method -> (seeds, 64, K_div) normalized RMS of every sample; written to ablation_rms.npz, read by the sweeps
    samples: dict[str, np.ndarray] = dataclasses.field(default_factory=dict, compare=False, metadata=_ARRAYS)
    # ^ method -> (64, K_div, T, N_u) of seed 0, for the figures; in memory only (empty once loaded)


def _plain(x):
    """JSON-ready data of a result's value (dataclasses by field, tuples as lists, numpy scalars as numbers)."""
    if isinstance(x, Config):
        return configs.to_dict(x)
    if dataclasses.is_dataclass(x):
        return {f.name: _plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}  # float keys (tau) become "0.35"
    if isinstance(x, (tuple, list)):
        return [_plain(v) for v in x]
    return x.item() if isinstance(x, np.generic) else x


def _json_fields(cls) -> list[str]:
    return [f.name for f in dataclasses.fields(cls) if f.metadata.get("json", True)]


def to_json(result: AblationResult) -> str:
    """The text of ablation.json: the result without its arrays, and :data:`SCHEMA`."""
    body = {name: _plain(getattr(result, name)) for name in _json_fields(AblationResult)}
    return json.dumps({"schema": SCHEMA, **body}, indent=1)


def _decode(hint, value, where: str):
    """``value`` read from JSON as the type ``hint`` of its field (``where`` names it in errors)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is Config:
        if isinstance(value, dict) and isinstance(value.get("eval"), dict) and "physics_samples" not in value["eval"]:
            # recorded before EvalConfig.physics_samples existed: those runs simulated every sample
            value = {**value, "eval": {**value["eval"], "physics_samples": value["eval"].get("num_samples", 30)}}
        return configs.from_dict(value)
    if dataclasses.is_dataclass(hint):
        names = _json_fields(hint)
        optional = {f.name for f in dataclasses.fields(hint) if f.default is not dataclasses.MISSING}
        if isinstance(value, dict):  # a field added later with a default may be absent from older files
            names = [n for n in names if n in value or n not in optional]
        if not isinstance(value, dict) or set(value) != set(names):
            got = sorted(value) if isinstance(value, dict) else type(value).__name__
            raise ValueError(f"{where}: expected the fields {names} of {hint.__name__}, got {got}")
        hints = typing.get_type_hints(hint)
        return hint(**{n: _decode(hints[n], value[n], f"{where}.{n}") for n in names})
    if origin in (types.UnionType, typing.Union):  # X | None
        (inner,) = [a for a in args if a is not type(None)]
        return None if value is None else _decode(inner, value, where)
    if origin is dict:
        key, item = args
        return {key(k): _decode(item, v, f"{where}[{k}]") for k, v in value.items()}
    if origin is tuple:
        hints = [args[0]] * len(value) if args[-1] is Ellipsis else args
        if len(hints) != len(value):
            raise ValueError(f"{where}: expected {len(hints)} numbers, got {value!r}")
        return tuple(_decode(h, v, where) for h, v in zip(hints, value))
    if hint is float and isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if not isinstance(value, hint) or isinstance(value, bool) is not (hint is bool):
        raise ValueError(f"{where}: expected {hint.__name__}, got {value!r}")
    return value


def from_json(text: str, where: str = "ablation.json") -> AblationResult:
    """The result :func:`to_json` wrote (without its arrays); another schema is a ValueError saying how to
    regenerate the file."""
    data = json.loads(text)
    found = data.pop("schema", 1) if isinstance(data, dict) else None
    if found != SCHEMA:
        raise ValueError(
            f"{where} is in schema {found} of the ablation's results; this code reads schema {SCHEMA}. "
            f"Regenerate it: {REGENERATE}"
        )
    return _decode(AblationResult, data, where)


def save(result: AblationResult, out: str | Path) -> None:
    """Write ``<out>/ablation.json`` and ``<out>/ablation_rms.npz`` (the per-sample RMS)."""
    out = Path(out)
    write_atomic(out / "ablation.json", to_json(result))
    buf = io.BytesIO()
    np.savez(buf, **result.per_sample_rms)
    write_atomic(out / "ablation_rms.npz", buf.getvalue())


def load(out: str | Path) -> AblationResult:
    """The result :func:`save` wrote to ``out``, with its per-sample RMS (its seed-0 samples are not kept)."""
    paths = [Path(out) / "ablation.json", Path(out) / "ablation_rms.npz"]
    missing = [str(p) for p in paths if not p.exists()]
    if missing:
        raise FileNotFoundError(f"{' and '.join(missing)} not found: run {REGENERATE} first")
    result = from_json(paths[0].read_text(), str(paths[0]))
    with np.load(paths[1]) as f:
        rms = {k: f[k] for k in f.files}
    return dataclasses.replace(result, per_sample_rms=rms)
