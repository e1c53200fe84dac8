"""What a calibration fits and how: the fittable parameters and their default bounds, :class:`Settings`, and
their reading from the command line (``--bound NAME=LOW,HIGH``) or a TOML file (``--settings``)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from jgrounding.io import read_toml
from jgrounding.sim import mjcf as tm

FIT_PARAMETERS = (
    "stiffness_root",
    "stiffness_tip",
    "damping_root",
    "damping_tip",
    "tendon_force",
    "slide_stiffness",
    "density",
    "delay",
)
# Box bounds of every fittable parameter: wide (a factor of about 5-10 around the hand-tuned trunk), physical
# (positive), and inside the range where the chain stays stable at dt = 1/120 s.
DEFAULT_BOUNDS = {
    "stiffness_root": (1.0, 30.0),
    "stiffness_tip": (0.05, 5.0),
    "damping_root": (0.03, 3.0),
    "damping_tip": (0.003, 0.3),
    "tendon_force": (3.0, 60.0),
    "slide_stiffness": (500.0, 20000.0),
    "slide_damping": (1.0, 40.0),
    "density": (100.0, 1500.0),
    "hinge_armature": (0.0001, 0.005),
    "slide_armature": (0.002, 0.05),
    "delay": (0.0, 0.1),
}


class CalibrationError(ValueError):
    """Calibration cannot proceed or did not succeed; the message says why and what to change."""


@dataclasses.dataclass(frozen=True)
class Settings:
    """What to fit and how: parameter names, their bounds, the split and the optimizer's budget."""

    parameters: tuple[str, ...] = FIT_PARAMETERS
    bounds: tuple[tuple[str, float, float], ...] = ()  # overrides of DEFAULT_BOUNDS: (name, low, high)
    validation: float = 0.25  # fraction of the recordings held out (at least one when there are >= 2)
    seed: int = 0  # of the split
    max_iters: int = 40  # per round
    restarts: int = 2  # more rounds from the point reached while a round still gains > 10 %

    def __post_init__(self):
        unknown = [p for p in self.parameters if p not in DEFAULT_BOUNDS]
        if unknown or not self.parameters or len(set(self.parameters)) != len(self.parameters):
            raise CalibrationError(
                f"parameters to fit {list(self.parameters)} must be distinct names of: {', '.join(DEFAULT_BOUNDS)}"
            )
        for name, low, high in self.bounds:
            if name not in DEFAULT_BOUNDS:
                raise CalibrationError(f"bounds for unknown parameter {name!r}; valid: {', '.join(DEFAULT_BOUNDS)}")
            if not (math.isfinite(low) and math.isfinite(high) and 0 <= low < high):
                raise CalibrationError(f"bounds of {name} must be finite with 0 <= low < high, got [{low}, {high}]")
            if name != "delay" and name not in tm.NON_NEGATIVE and low <= 0:
                raise CalibrationError(f"bounds of {name} must be positive (> 0), got [{low}, {high}]")
        if not 0 <= self.validation < 1:
            raise CalibrationError(f"validation fraction must be in [0, 1), got {self.validation}")
        if self.max_iters < 1:
            raise CalibrationError(f"max_iters must be >= 1, got {self.max_iters}")

    def bound(self, name: str) -> tuple[float, float]:
        found = [(lo, hi) for n, lo, hi in self.bounds if n == name]
        return found[-1] if found else DEFAULT_BOUNDS[name]


def parse_bound(text: str) -> tuple[str, float, float]:
    """``"name=low,high"`` (the command line's ``--bound``) -> ``(name, low, high)``."""
    name, sep, rest = text.partition("=")
    parts = rest.split(",")
    try:
        if not sep or len(parts) != 2:
            raise ValueError
        return name.strip(), float(parts[0]), float(parts[1])
    except ValueError:
        raise CalibrationError(f"a bound is NAME=LOW,HIGH (e.g. tendon_force=5,40), got {text!r}") from None


def load_settings(path: str | Path, **overrides) -> Settings:
    """:class:`Settings` from a TOML file: ``parameters = [...]``, ``validation``, ``seed``, ``max_iters`` and a
    ``[bounds]`` table of ``name = [low, high]``; ``overrides`` (not None) replace its values."""
    path = Path(path)
    try:
        data = read_toml(path, "calibration settings")
    except (FileNotFoundError, ValueError) as e:
        raise CalibrationError(str(e)) from None
    valid = ("parameters", "bounds", "validation", "seed", "max_iters", "restarts")
    unknown = sorted(set(data) - set(valid))
    if unknown:
        raise CalibrationError(f"{path}: unknown settings {unknown}; valid: {', '.join(valid)}")
    bounds = []
    for name, pair in data.get("bounds", {}).items():
        if not isinstance(pair, list) or len(pair) != 2:
            raise CalibrationError(f"{path}: bounds.{name} must be [low, high], got {pair!r}")
        bounds.append((name, float(pair[0]), float(pair[1])))
    kwargs = {k: data[k] for k in ("validation", "seed", "max_iters", "restarts") if k in data}
    if "parameters" in data:
        kwargs["parameters"] = tuple(data["parameters"])
    kwargs["bounds"] = tuple(bounds)
    for k, v in overrides.items():
        if v is not None:
            kwargs[k] = kwargs.get("bounds", ()) + tuple(v) if k == "bounds" else v
    return Settings(**kwargs)
