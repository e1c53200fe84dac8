"""The one safety layer between every model and the outside world (this drives a robot near people).

Every actuation trajectory that leaves the library passes through :func:`emit` (or, inside compiled
code, :func:`make_safe`), and nowhere else clamps. The guarantees:

1. **Bounds.** Each tendon pull is inside ``[ACTUATION_MIN, ACTUATION_MAX] = [0, 1]`` (0 = slack,
   1 = largest safe pull; SPEC §3), whatever the model produced.
2. **Slew.** Between consecutive control steps a channel moves at most ``MAX_SLEW`` (normalized
   pull per step, i.e. ``MAX_SLEW * 150`` per full trajectory duration), so a tendon is never
   jerked. The limiter follows the raw command as closely as the bound allows.
3. **Finite.** A trajectory containing NaN or Inf is refused with :class:`UnsafeActuationError`;
   it is never "repaired" into something that looks valid.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

ACTUATION_MIN = 0.0
ACTUATION_MAX = 1.0
# Largest change of one channel between consecutive control steps (T = 150 per trajectory). The
# demonstration library is screened against the same bound, so valid commands are never altered.
MAX_SLEW = 0.1


class UnsafeActuationError(ValueError):
    """Raised instead of emitting a trajectory that is not finite or has the wrong shape."""


def _rate_limit(u: jax.Array, max_slew: float) -> jax.Array:
    """Slew-limit ``(T, N_u)`` along time with a scan; the first step is taken as is."""

    def step(prev, target):
        nxt = prev + jnp.clip(target - prev, -max_slew, max_slew)
        return nxt, nxt

    _, rest = jax.lax.scan(step, u[0], u[1:])
    return jnp.concatenate([u[:1], rest], axis=0)


def make_safe(u: jax.Array, max_slew: float | None = MAX_SLEW) -> jax.Array:
    """Clamp ``(..., T, N_u)`` to the actuation bounds and slew-limit it; pure and jit/vmap-able.

    NaN passes through unchanged (``clip`` keeps NaN) so that :func:`emit` can refuse it.
    """
    u = jnp.clip(u, ACTUATION_MIN, ACTUATION_MAX)
    if max_slew is None:
        return u
    flat = u.reshape((-1,) + u.shape[-2:])
    flat = jax.vmap(lambda x: _rate_limit(x, max_slew))(flat)
    return flat.reshape(u.shape)


def check_finite(u, what: str = "actuation") -> None:
    """Raise :class:`UnsafeActuationError` if a concrete array holds NaN or Inf."""
    arr = np.asarray(u)
    if not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise UnsafeActuationError(f"refusing to emit {what}: {bad} non-finite value(s) (NaN/Inf)")


def emit(u, *, num_channels: int = 4) -> np.ndarray:
    """The exit gate: validate, clamp and slew-limit ``(..., T, N_u)``; returns float32 numpy.

    Raises :class:`UnsafeActuationError` on NaN/Inf or a shape that is not ``(..., T, num_channels)``.
    """
    arr = np.asarray(u, dtype=np.float32)
    if arr.ndim < 2 or arr.shape[-1] != num_channels or arr.shape[-2] < 1:
        raise UnsafeActuationError(f"actuation must have shape (..., T, {num_channels}), got {arr.shape}")
    check_finite(arr)
    safe = np.asarray(_make_safe_jit(jnp.asarray(arr)))
    return safe.astype(np.float32)


_make_safe_jit = jax.jit(make_safe)


def is_safe(u, max_slew: float = MAX_SLEW, atol: float = 1e-6) -> bool:
    """True when ``(..., T, N_u)`` is finite, inside the bounds and within the slew bound."""
    arr = np.asarray(u, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        return False
    if arr.min() < ACTUATION_MIN - atol or arr.max() > ACTUATION_MAX + atol:
        return False
    return bool(np.all(np.abs(np.diff(arr, axis=-2)) <= max_slew + atol))
