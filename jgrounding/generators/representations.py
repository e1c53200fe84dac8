"""Actuation representations (Sec. III-B): what a generator's network reads and writes.

:class:`Spline`: the N_u x P Catmull-Rom controls, u = R(c) (Eq. ci); :class:`Dense`: the T x N_u trajectory
itself. Both implement :class:`jgrounding.generators.base.Representation`.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from jgrounding.actuation import splines
from jgrounding.config import NUM_STEPS, ModelConfig


@dataclasses.dataclass(frozen=True)
class Spline:
    """Actuation as N_u x P Catmull-Rom controls, u = R(c) (Eq. ci)."""

    name: str = "spline"

    def length(self, num_controls: int) -> int:
        return num_controls

    def cnn_channels(self, config: ModelConfig) -> int:
        return config.cnn_channels

    def target(self, split, num_controls: int, sequence: bool) -> np.ndarray:
        c = (
            split.controls
            if num_controls == split.controls.shape[-1]
            else np.asarray(splines.fit(split.u, num_controls=num_controls))
        )  # (N, N_u, P)
        return np.swapaxes(c, -1, -2) if sequence else c.reshape(len(split), -1)

    def actuation(self, y, sequence: bool, num_tendons: int, num_controls: int):
        c = jnp.swapaxes(y, -1, -2) if sequence else y.reshape(y.shape[0], num_tendons, num_controls)
        return splines.reconstruct(c)


@dataclasses.dataclass(frozen=True)
class Dense:
    """Actuation as the T x N_u trajectory itself."""

    name: str = "dense"

    def length(self, num_controls: int) -> int:
        del num_controls
        return NUM_STEPS

    def cnn_channels(self, config: ModelConfig) -> int:
        return config.dense_cnn_channels

    def target(self, split, num_controls: int, sequence: bool) -> np.ndarray:
        del num_controls
        return split.u if sequence else split.u.reshape(len(split), -1)

    def actuation(self, y, sequence: bool, num_tendons: int, num_controls: int):
        del num_controls
        return y if sequence else y.reshape(y.shape[0], NUM_STEPS, num_tendons)
