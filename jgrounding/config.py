"""Configurations as frozen dataclasses whose defaults are the paper's Table I, and a named registry.

- :class:`ModelConfig`: network sizes (recorded in every checkpoint, so a checkpoint rebuilds its own
  network).
- :class:`TrainConfig`: AdamW, batch, steps, and the generator options of issue #16 (EMA, flow-time
  distribution, condition dropout for classifier-free guidance), each off by default.
- :class:`SampleConfig`: sampler, steps S, guidance weight w.
- :data:`CONFIGS`: named (model, train, sample) triples; ``paper`` is Table I. What the shipped
  checkpoints were trained with is recorded in their own meta.json (chosen by
  ``python -m experiments.sweep training``, trained by ``python -m experiments.ship``).

This module imports nothing from the package, so every stage can import it without a cycle.
"""

from __future__ import annotations

import dataclasses
import numbers

SAMPLERS = ("euler", "midpoint", "rk4", "ancestral", "ddim", "none")  # ancestral/ddim: DDPM; none: regressors
TIME_SAMPLERS = ("uniform", "logit_normal", "beta")  # generators.flows.TIME_SAMPLERS implements these


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
    """Sampling of Table I (Euler, S = 50); ``guidance`` w: v = v_c + w (v_c - v_null), 0 = off;
    ``noise_scale``: temperature of the initial noise, eps ~ N(0, noise_scale^2 I) (1 = the trained prior;
    above 1 spreads the samples of an under-dispersed few-step model, issue #25)."""

    sampler: str = "euler"
    steps: int = 50
    guidance: float = 0.0
    noise_scale: float = 1.0

    def __post_init__(self):
        if self.sampler not in SAMPLERS:
            raise ValueError(f"SampleConfig.sampler must be one of {', '.join(SAMPLERS)}, got {self.sampler!r}")
        _integer("SampleConfig", "steps", self.steps, 1)
        _real("SampleConfig", "guidance", self.guidance, 0.0, 20.0)
        _real("SampleConfig", "noise_scale", self.noise_scale, 0.1, 4.0)


@dataclasses.dataclass(frozen=True)
class Config:
    model: ModelConfig = ModelConfig()
    train: TrainConfig = TrainConfig()
    sample: SampleConfig = SampleConfig()


CONFIGS = {
    "paper": Config(),  # Table I
}


def get(name: str) -> Config:
    """The named configuration; ``ValueError`` listing the valid names."""
    if name not in CONFIGS:
        raise ValueError(f"unknown config {name!r}; valid: {', '.join(CONFIGS)}")
    return CONFIGS[name]


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
