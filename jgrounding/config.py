"""One composed configuration: every setting of a run in one frozen tree, named entries and overrides.

In the spirit of MuJoCo Playground's ``default_config()`` and big_vision's config files:

- :class:`ModelConfig`: network sizes (recorded in every checkpoint, so a checkpoint rebuilds its own network).
- :class:`TrainConfig`: AdamW, batch, steps, and the generator options (EMA, flow-time
  distribution, condition dropout for classifier-free guidance), each off by default.
- :class:`SampleConfig`: sampler, steps S, guidance weight w.
- :class:`PhysicsConfig`: the physics-aware fine-tuning of the ablation's extra row, and the trunk simulated.
- :class:`EvalConfig`: what the ablation evaluates (seeds, K, tau, rows, engine, library, output).
- :class:`Config`: all of them; :data:`CONFIGS` names entries (``paper`` = Table I, ``quick`` = the smoke
  run), each a function whose docstring opens with the command it serves and the result it should give;
  :func:`get` applies generic overrides ``"train.steps=2000"`` (``--set`` on the command lines) and
  :func:`to_dict` is what every result and checkpoint records.

The sizes of Table I that everything shares (T, P, N_u, tau) and the sampler names are defined here once.
This module imports nothing from the package, so every stage can import it without a cycle. What the shipped
checkpoints were trained with is recorded in their own meta.json (``python -m experiments.ship``).
"""

from __future__ import annotations

import dataclasses
import numbers
import types
import typing

NUM_STEPS = 150  # T of Table I: steps of a trajectory (5 s at 30 Hz)
NUM_CONTROLS = 4  # P of Table I: Catmull-Rom controls per tendon
NUM_TENDONS = 4  # N_u of the built-in trunk (an imported library may have another number)
TAU_RMS = 0.35  # tau of Table I: a sample within this normalized RMS of its reference is a success
RF_SAMPLERS = ("euler", "midpoint", "rk4")  # ODE integrators of a rectified flow (Euler is Table I's)
DDPM_SAMPLERS = ("ancestral", "ddim")
SAMPLERS = (*RF_SAMPLERS, *DDPM_SAMPLERS, "none")  # none: the deterministic regressors
TIME_SAMPLERS = ("uniform", "logit_normal", "beta")  # generators.flows.TIME_SAMPLERS implements these
MAX_SAMPLE_STEPS = 1000  # most sampler steps S a sampling call takes (Trained.resolve)


def _integer(owner: str, name: str, value, low: int) -> None:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
        raise ValueError(f"{owner}.{name} must be an integer >= {low}, got {value!r}")


def _real(owner: str, name: str, value, low: float, high: float, *, high_open: bool = False) -> None:
    ok = (
        isinstance(value, numbers.Real)
        and not isinstance(value, bool)
        and low <= value <= high
        and not (high_open and value == high)
    )
    if not ok:
        raise ValueError(f"{owner}.{name} must be a number in [{low}, {high}{')' if high_open else ']'}, got {value!r}")


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    """Network sizes of Table I. ``num_tendons`` / ``num_controls`` come from the library (N_u, P)."""

    width: int = 256  # hidden width of the velocity / noise MLP
    depth: int = 4  # linear layers of the MLP (input, depth - 2 hidden, output)
    time_dim: int = 128  # sinusoidal flow/diffusion-time embedding
    text_dim: int = 384  # frozen sentence embedding E_m (MiniLM)
    intensity_dim: int = 64  # learnable intensity embedding E_z
    cnn_channels: int = 64  # 1-D CNN regressor over the P spline controls
    dense_cnn_channels: int = 32  # 1-D CNN over the 150 dense steps: the same budget order as the MLPs
    cnn_kernel: int = 5  # hidden convolutions (the output convolution has kernel 3)

    def __post_init__(self):
        for name in (
            "width",
            "time_dim",
            "text_dim",
            "intensity_dim",
            "cnn_channels",
            "dense_cnn_channels",
            "cnn_kernel",
        ):
            _integer("ModelConfig", name, getattr(self, name), 1)
        _integer("ModelConfig", "depth", self.depth, 2)
        if self.time_dim % 2:
            raise ValueError(f"ModelConfig.time_dim must be even (sin and cos halves), got {self.time_dim}")


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """Defaults are the paper's Table I; the generator options are off."""

    steps: int = 10_000
    batch_size: int = 8
    learning_rate: float = 1e-3
    weight_decay: float = 1e-4
    chunk: int = 1_000  # steps per compiled chunk (progress / checkpoint granularity)
    ema_decay: float = 0.0  # 0 = off; else the model is evaluated with an EMA of its parameters (warm-up)
    time_sampler: str = "uniform"  # flow-time distribution of the RF loss (TIME_SAMPLERS)
    condition_dropout: float = 0.0  # probability of training on the null condition (classifier-free guidance)

    def __post_init__(self):
        for name, low in (("steps", 0), ("batch_size", 1), ("chunk", 1)):
            _integer("TrainConfig", name, getattr(self, name), low)
        for name in ("learning_rate", "weight_decay"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not 0 <= value < float("inf"):
                raise ValueError(f"TrainConfig.{name} must be a finite number >= 0, got {value!r}")
        for name in ("ema_decay", "condition_dropout"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not 0 <= value < 1:
                raise ValueError(f"TrainConfig.{name} must be a number in [0, 1), got {value!r}")
        if self.time_sampler not in TIME_SAMPLERS:
            raise ValueError(
                f"TrainConfig.time_sampler must be one of {', '.join(TIME_SAMPLERS)}, got {self.time_sampler!r}"
            )


@dataclasses.dataclass(frozen=True)
class SampleConfig:
    """Sampling of Table I (S = 50 steps of the generator's default sampler: Euler for a rectified flow,
    ancestral for a DDPM); ``guidance`` w: v = v_c + w (v_c - v_null), 0 = off. ``sampler`` None: the
    generator's default; a name it does not have is refused when sampling (never silently replaced).
    ``noise_scale``: temperature of the initial noise, eps ~ N(0, noise_scale^2 I) (1 = the trained prior;
    above 1 spreads the samples of an under-dispersed few-step model).

    Frozen and hashable: ``jg.sample(..., config=SampleConfig(...))`` passes one, and the public sampler
    compiles one program per (config, batch bucket). A model fills in and checks what depends on its
    generator (the default sampler; steps 1..:data:`MAX_SAMPLE_STEPS`) in one place,
    :meth:`jgrounding.generators.trained.Trained.resolve`."""

    sampler: str | None = None  # None: the generator's default (euler for RF, ancestral for DDPM)
    steps: int = 50  # S sampler steps (one forward pass for a regressor, whatever S)
    guidance: float = 0.0  # classifier-free guidance w (needs a model trained with condition dropout)
    noise_scale: float = 1.0  # temperature T of the initial noise

    def __post_init__(self):
        if self.sampler is not None and self.sampler not in SAMPLERS:
            raise ValueError(f"SampleConfig.sampler must be one of {', '.join(SAMPLERS)}, got {self.sampler!r}")
        _integer("SampleConfig", "steps", self.steps, 1)
        _real("SampleConfig", "guidance", self.guidance, 0.0, 20.0)
        _real("SampleConfig", "noise_scale", self.noise_scale, 0.1, 4.0)


@dataclasses.dataclass(frozen=True)
class PhysicsConfig:
    """Physics-aware fine-tuning (the ablation's extra row, :mod:`jgrounding.training.physics`) and the trunk that
    every simulation of a run uses."""

    rounds: int = 2  # generate -> simulate -> fine-tune rounds
    candidates: int = 16  # samples per tuple per round (64 tuples: 1024 rollouts per seed and round)
    steps: int = 1000  # fine-tuning steps per round (Table I optimizer, batch 8)
    margin: float = 0.2  # keep candidates with feasibility margin >= this (0 = just feasible)
    learning_rate: float = 3e-4  # below Table I's 1e-3: fine-tuning, not training (1e-3 drifted: RMS up)
    engine: str = "auto"  # jgrounding.sim.rollout engine
    # The trunk every simulation of a run uses (rollouts, screening, the physics columns, the render): an MJCF path
    # (a fitted trunk from `python -m jgrounding.sim calibrate`), None = the shipped, hand-tuned trunk.
    trunk: str | None = None

    def __post_init__(self):
        if self.trunk is not None and (not isinstance(self.trunk, str) or not self.trunk.strip()):
            raise ValueError(f"PhysicsConfig.trunk must be a path to an MJCF file or None, got {self.trunk!r}")
        for name in ("rounds", "candidates", "steps"):
            _integer("PhysicsConfig", name, getattr(self, name), 1)
        _real("PhysicsConfig", "margin", self.margin, 0.0, 1e3)
        _real("PhysicsConfig", "learning_rate", self.learning_rate, 0.0, 1.0)


@dataclasses.dataclass(frozen=True)
class EvalConfig:
    """What the ablation trains and evaluates (Table I: 5 seeds, K_div = 30, tau = 0.35)."""

    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    num_samples: int = 30  # K_div samples per held-out tuple
    # Of each tuple's K_div samples, the first this many are simulated for the physics columns (>= num_samples:
    # all). Samples are i.i.d., so the first 10 are a random subset: a third of the rollouts, for a third of the time.
    physics_samples: int = 10
    tau: float = TAU_RMS
    rows: tuple[str, ...] = ()  # registry names of the rows; () = Table II's five and the physics-aware RF
    engine: str = "auto"  # sim.rollout engine of the physics columns: native on CPU, MJX on an accelerator
    devices: int = 1  # > 1 or 0 (= all): seeds (training) and samples (evaluation) split over a device mesh
    library: str | None = None  # library .npz (None: the shipped one), e.g. imported from recordings
    out: str = "results"
    runs: str = "runs/ablation"

    def __post_init__(self):
        if not self.seeds or len(set(self.seeds)) != len(self.seeds) or min(self.seeds) < 0:
            raise ValueError(f"EvalConfig.seeds must be distinct non-negative integers, got {self.seeds!r}")
        _integer("EvalConfig", "num_samples", self.num_samples, 1)
        _integer("EvalConfig", "physics_samples", self.physics_samples, 1)
        _real("EvalConfig", "tau", self.tau, 0.0, 10.0)
        _integer("EvalConfig", "devices", self.devices, 0)


@dataclasses.dataclass(frozen=True)
class Config:
    model: ModelConfig = ModelConfig()
    train: TrainConfig = TrainConfig()
    sample: SampleConfig = SampleConfig()
    physics: PhysicsConfig = PhysicsConfig()
    eval: EvalConfig = EvalConfig()


def paper() -> Config:
    """``python -m experiments.ablation`` (``make ablation``): Table II on the shipped library, 5 seeds x
    10,000 steps, K_div = 30, S = 50, tau = 0.35, 10 of each tuple's 30 samples simulated, plus the physics-aware RF
    row.
    Gives results/ablation.{md,json}: every row's success, diversity, time, physics and distribution columns
    (the shipped model through jg.sample meets the benchmark's goals; about 10 min on 2 CPU cores: docs/testing.md)."""
    return Config()


def quick() -> Config:
    """``python -m experiments.ablation --config quick`` (``--quick``; the tests' end-to-end runs): 2 seeds x
    300 steps, K_div = 8, one short physics round. Gives the same files in well under a minute per method;
    its numbers only show that the path runs (300 steps do not train a model)."""
    return Config(
        train=TrainConfig(steps=300, chunk=300),
        physics=PhysicsConfig(rounds=1, candidates=4, steps=100),
        eval=EvalConfig(seeds=(0, 1), num_samples=8),
    )


CONFIGS = {"paper": paper, "quick": quick}


def _parse(owner: str, name: str, hint, text: str):
    """``text`` as a value of the field's type hint (int, float, str, bool, None-able, tuple of int/str)."""
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        if text.lower() in ("none", "null", ""):
            return None
        return _parse(owner, name, next(a for a in args if a is not type(None)), text)
    if typing.get_origin(hint) is tuple:
        return tuple(_parse(owner, name, args[0], t.strip()) for t in text.split(",") if t.strip())
    if hint is bool:
        if text.lower() not in ("true", "false", "1", "0"):
            raise ValueError(f"{owner}.{name} is true or false, got {text!r}")
        return text.lower() in ("true", "1")
    try:
        return hint(text)
    except ValueError:
        kind = {int: "an integer", float: "a number"}.get(hint, hint.__name__)
        raise ValueError(f"{owner}.{name} must be {kind}, got {text!r}") from None


def override(cfg, assignment: str):
    """``cfg`` with one ``"section.field=value"`` (or ``"field=value"`` on a section) applied; ``ValueError``
    naming the valid sections or fields."""
    path, sep, text = assignment.partition("=")
    if not sep or not path.strip():
        raise ValueError(f"an override is section.field=value (e.g. train.steps=2000), got {assignment!r}")
    head, _, rest = path.strip().partition(".")
    hints = typing.get_type_hints(type(cfg))
    names = [f.name for f in dataclasses.fields(cfg)]
    owner = type(cfg).__name__
    if head not in names:
        raise ValueError(f"{owner} has no field {head!r}; valid: {', '.join(names)}")
    value = getattr(cfg, head)
    if rest:
        if not dataclasses.is_dataclass(value):
            raise ValueError(f"{owner}.{head} is a value, not a section; write {head}={text}")
        return dataclasses.replace(cfg, **{head: override(value, f"{rest}={text}")})
    if dataclasses.is_dataclass(value):
        fields = ", ".join(f"{head}.{f.name}" for f in dataclasses.fields(value))
        raise ValueError(f"{owner}.{head} is a section; set one of its fields: {fields}")
    return dataclasses.replace(cfg, **{head: _parse(owner, head, hints[head], text.strip())})


def get(name: str = "paper", overrides=()) -> Config:
    """The named configuration with ``overrides`` (``"section.field=value"`` strings) applied in order;
    ``ValueError`` listing the valid names, sections or fields."""
    if name not in CONFIGS:
        raise ValueError(f"unknown config {name!r}; valid: {', '.join(CONFIGS)}")
    cfg = CONFIGS[name]()
    for assignment in overrides:
        cfg = override(cfg, assignment)
    return cfg


def add_arguments(parser, example: str = "train.steps=2000") -> None:
    """``--config NAME`` and repeatable ``--set SECTION.FIELD=VALUE`` on a command line's ``parser``; the
    script applies them with ``get(args.config, [...shorthands, *args.set])``."""
    parser.add_argument("--config", default="paper", choices=tuple(CONFIGS), help="named configuration")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SECTION.FIELD=VALUE",
        help=f"override one setting, e.g. --set {example} (repeatable; sections: model, train, sample, physics, eval)",
    )


def to_dict(cfg) -> dict:
    """The whole configuration as plain JSON-ready data (what results and checkpoints record)."""
    return dataclasses.asdict(cfg)


def from_dict(data: dict) -> Config:
    """The :class:`Config` that :func:`to_dict` wrote; unknown sections or fields are refused."""
    sections = {f.name: f.type for f in dataclasses.fields(Config)}
    hints = typing.get_type_hints(Config)
    unknown = set(data) - set(sections)
    if unknown:
        raise ValueError(f"unknown config sections {sorted(unknown)}; valid: {', '.join(sections)}")
    out = {}
    for name, value in data.items():
        cls = hints[name]
        valid = {f.name: f for f in dataclasses.fields(cls)}
        if set(value) - set(valid):
            raise ValueError(f"unknown {name} fields {sorted(set(value) - set(valid))}; valid: {', '.join(valid)}")
        out[name] = cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in value.items()})
    return Config(**out)


def model_config(meta: dict) -> ModelConfig:
    """The :class:`ModelConfig` a checkpoint's ``meta.json`` records; checkpoints written before sizes were
    recorded were all trained at Table I's sizes, so they get the defaults. Unknown fields are refused."""
    stored = meta.get("model")
    if stored is None:
        return ModelConfig()
    names = {f.name for f in dataclasses.fields(ModelConfig)}
    if not isinstance(stored, dict) or set(stored) - names:
        raise ValueError(
            f"checkpoint model sizes {stored!r} are not a ModelConfig (fields: {', '.join(sorted(names))})"
        )
    return ModelConfig(**stored)
