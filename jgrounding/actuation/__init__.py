"""Actuation representation, Sec. III-B: uniform Catmull-Rom splines over the tendon commands, and the one
distance between actuation trajectories (:func:`rms`) that the library, the metrics and the evaluation share."""

from __future__ import annotations

import jax
import jax.numpy as jnp


def rms(a, b) -> jax.Array:
    """Normalized RMS distance over the last two axes ``(..., T, N_u)`` -> ``(...)``."""
    return jnp.sqrt(jnp.mean((jnp.asarray(a) - jnp.asarray(b)) ** 2, axis=(-2, -1)))
