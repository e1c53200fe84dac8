"""The one safety layer between every model and the outside world (this drives a robot near people).

Every actuation trajectory that leaves the library passes through :func:`emit`, or through a compiled
function built by :func:`gated` (:func:`make_safe` inside the compiled code, then the host check of
:func:`release`), and nowhere else clamps. The guarantees:

1. **Bounds.** Each tendon pull is inside ``[ACTUATION_MIN, ACTUATION_MAX] = [0, 1]`` (0 = slack,
   1 = largest safe pull; SPEC §3), whatever the model produced.
2. **Slew.** Between consecutive control steps a channel moves at most ``MAX_SLEW`` (normalized
   pull per step, i.e. ``MAX_SLEW * 150`` per full trajectory duration), so a tendon is never
   jerked. The limiter follows the raw command as closely as the bound allows.
3. **Finite.** A trajectory containing NaN or Inf is refused with :class:`UnsafeActuationError`;
   it is never "repaired" into something that looks valid.
4. **Continuity with the robot's state.** Given the command the robot holds now (``current``, shape
   ``(N_u,)``; :data:`REST` = all slack), the new trajectory is blended into from it: the offset
   ``current - u[0]`` fades out along a half-cosine over :data:`BLEND_STEPS` steps, and the slew limiter
   starts from ``current``. So the step from the last command sent to the first new one is bounded too,
   and a stream of consecutive responses never jumps at a boundary. ``current=None`` takes the first
   step as is (evaluation: the model's own trajectory, compared with the library's).
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
# Steps over which a new trajectory is blended in from the robot's current command (1 s at 30 Hz). A
# half-cosine of length L moves at most pi / (2 L) of the offset per step: <= 0.052 for the largest
# offset (1.0), half the slew bound, so the blend itself leaves room for the trajectory's own motion.
BLEND_STEPS = 30
# Steps of the slew-limit scan per loop iteration: the same result, with a fifth of XLA's loop overhead (a batch
# of 1,920 trajectories at S = 4 went from 13.3 to 12.3 ms on 2 CPU cores; one trajectory is unchanged).
SLEW_UNROLL = 5
REST = "rest"  # the robot's command at rest: every tendon slack (0)


class UnsafeActuationError(ValueError):
    """Raised instead of emitting a trajectory that is not finite or has the wrong shape."""


def _rate_limit(u: jax.Array, max_slew: float, start: jax.Array) -> jax.Array:
    """Slew-limit ``(T, N_u)`` along time with a scan, starting from the command ``start (N_u,)``."""

    def step(prev, target):
        nxt = prev + jnp.clip(target - prev, -max_slew, max_slew)
        return nxt, nxt

    _, out = jax.lax.scan(step, start, u, unroll=SLEW_UNROLL)
    return out


def blend_weights(num_steps: int, blend_steps: int = BLEND_STEPS) -> jax.Array:
    """``(num_steps,)`` half-cosine from 1 (t = 0) to 0 (t >= blend_steps): the share of the offset
    ``current - u[0]`` still applied at step t."""
    t = jnp.arange(num_steps, dtype=jnp.float32) / max(blend_steps, 1)
    return jnp.where(t < 1.0, 0.5 * (1.0 + jnp.cos(jnp.pi * t)), 0.0)


def make_safe(u: jax.Array, max_slew: float | None = MAX_SLEW, current: jax.Array | None = None) -> jax.Array:
    """Clamp ``(..., T, N_u)`` to the actuation bounds and slew-limit it; pure and jit/vmap-able.

    Args:
      u: ``(..., T, N_u)`` raw commands.
      max_slew: largest change per step (None: clamp only).
      current: ``(N_u,)`` or ``(..., N_u)`` command the robot holds now, or None. Given, the trajectory
        is blended into from it (guarantee 4 of the module) and no step, the first included, exceeds
        ``max_slew``.
    Returns:
      ``(..., T, N_u)`` safe commands. NaN passes through unchanged (``clip`` keeps NaN) so that
      :func:`emit` can refuse it.
    """
    u = jnp.clip(u, ACTUATION_MIN, ACTUATION_MAX)
    if current is not None:
        current = jnp.clip(
            jnp.broadcast_to(jnp.asarray(current, u.dtype), u.shape[:-2] + u.shape[-1:]), ACTUATION_MIN, ACTUATION_MAX
        )
        w = blend_weights(u.shape[-2])[:, None]  # (T, 1)
        u = jnp.clip(u + w * (current - u[..., 0, :])[..., None, :], ACTUATION_MIN, ACTUATION_MAX)
    if max_slew is None:
        return u
    flat = u.reshape((-1,) + u.shape[-2:])
    start = flat[:, 0] if current is None else current.reshape(flat[:, 0].shape)
    flat = jax.vmap(lambda x, s: _rate_limit(x, max_slew, s))(flat, start)
    return flat.reshape(u.shape)


def current_command(current, num_channels: int = 4) -> np.ndarray | None:
    """Validate the robot's current command: ``"rest"`` (all slack), None (no continuity) or a finite
    ``(num_channels,)`` array inside [0, 1]; returns float32 ``(num_channels,)`` or None."""
    if current is None:
        return None
    if isinstance(current, str):
        if current != REST:
            raise ValueError(
                f"current must be {REST!r}, None or a ({num_channels},) command in [0, 1], got {current!r}"
            )
        return np.zeros(num_channels, np.float32)
    try:
        arr = np.asarray(current, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(
            f"current must be {REST!r}, None or a ({num_channels},) command in [0, 1], got {type(current).__name__}"
        ) from None
    if arr.shape != (num_channels,):
        raise ValueError(f"current must have shape ({num_channels},) (one pull per tendon), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise UnsafeActuationError("current command holds NaN/Inf; refusing to plan from it")
    if arr.min() < ACTUATION_MIN - 1e-6 or arr.max() > ACTUATION_MAX + 1e-6:
        raise ValueError(f"current command must lie in [0, 1], got range [{arr.min():.3g}, {arr.max():.3g}]")
    return np.clip(arr, ACTUATION_MIN, ACTUATION_MAX).astype(np.float32)


def check_finite(u, what: str = "actuation") -> None:
    """Raise :class:`UnsafeActuationError` if a concrete array holds NaN or Inf."""
    arr = np.asarray(u)
    if not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise UnsafeActuationError(f"refusing to emit {what}: {bad} non-finite value(s) (NaN/Inf)")


def emit(u, *, num_channels: int = 4, current=None) -> np.ndarray:
    """The exit gate: validate, clamp and slew-limit ``(..., T, N_u)``; returns float32 numpy.

    ``current``: the robot's current command (``"rest"`` or ``(num_channels,)`` in [0, 1]) to blend in
    from, or None (first step as is). Raises :class:`UnsafeActuationError` on NaN/Inf or a shape that is
    not ``(..., T, num_channels)``; ``ValueError`` for an invalid ``current``.
    """
    arr = np.asarray(u, dtype=np.float32)
    if arr.ndim < 2 or arr.shape[-1] != num_channels or arr.shape[-2] < 1:
        raise UnsafeActuationError(f"actuation must have shape (..., T, {num_channels}), got {arr.shape}")
    check_finite(arr)
    start = current_command(current, num_channels)
    if start is None:
        safe = _make_safe_jit(jnp.asarray(arr))
    else:
        safe = _make_safe_from_jit(jnp.asarray(arr), jnp.asarray(start))
    return np.asarray(safe).astype(np.float32)


_make_safe_jit = jax.jit(make_safe)
_make_safe_from_jit = jax.jit(lambda u, current: make_safe(u, MAX_SLEW, current))


def release(u, *, num_channels: int | None = None) -> np.ndarray:
    """The host half of a :func:`gated` function's gate: a fresh float32 numpy copy of ``(..., T, N_u)``.

    The bounds and the slew limit were applied inside the compiled function; this refuses
    (:class:`UnsafeActuationError`) NaN/Inf and a wrong shape (``num_channels``: expected N_u), as :func:`emit` does.
    """
    arr = np.array(u, dtype=np.float32)
    if arr.ndim < 2 or arr.shape[-2] < 1 or (num_channels is not None and arr.shape[-1] != num_channels):
        raise UnsafeActuationError(f"actuation must have shape (..., T, {num_channels or 'N_u'}), got {arr.shape}")
    if not np.isfinite(arr.sum(dtype=np.float64)):  # one pass: a float64 sum of float32 values cannot overflow,
        check_finite(arr)  # so it is finite exactly when every value is; the count and the error come from here
    return arr


def gated(fn, *, continuity: bool = False):
    """``jit(make_safe(fn(*args)))`` whose results leave only through :func:`release`.

    Args:
      fn: a pure function returning actuation ``(..., T, N_u)``.
      continuity: the compiled function then takes the robot's current command ``(N_u,)`` first and
        blends the result in from it (guarantee 4): ``call(current, *args)``.
    Returns:
      ``call(*args) -> np.ndarray``: the gated float32 result (inside the bounds, slew-limited, finite or
      refused). ``call.compiled`` is the jitted function (for lowering, or timing the compiled core).
    """
    if continuity:
        compiled = jax.jit(lambda current, *args: make_safe(fn(*args), MAX_SLEW, current))
    else:
        compiled = jax.jit(lambda *args: make_safe(fn(*args)))

    def call(*args) -> np.ndarray:
        return release(compiled(*args))

    def specialize(*example, compile=None):
        """``call`` compiled ahead of time for arguments shaped and typed like ``example``: the XLA executable
        is called directly (no tracing, no jit dispatch). Arguments of another type (e.g. a key of another
        PRNG implementation) go through the jitted function; either way the result leaves through
        :func:`release`. ``compile``: how to compile the lowered program (default: ``Lowered.compile()``)."""
        lowered = compiled.lower(*example)
        executable = lowered.compile() if compile is None else compile(lowered)

        def run(*args) -> np.ndarray:
            try:
                out = executable(*args)
            except TypeError:  # "argument types differ from the types for which this computation was compiled"
                out = compiled(*args)
            return release(out)

        run.compiled, run.executable = compiled, executable
        return run

    call.compiled, call.specialize = compiled, specialize
    return call


def is_safe(u, max_slew: float = MAX_SLEW, atol: float = 1e-6, current=None) -> bool:
    """True when ``(..., T, N_u)`` is finite, inside the bounds and within the slew bound (from
    ``current`` ``(N_u,)`` to the first step too, when given)."""
    arr = np.asarray(u, dtype=np.float64)
    if current is not None:
        start = np.broadcast_to(np.asarray(current, np.float64), arr.shape[:-2] + arr.shape[-1:])
        arr = np.concatenate([start[..., None, :], arr], axis=-2)
    if not np.all(np.isfinite(arr)):
        return False
    if arr.min() < ACTUATION_MIN - atol or arr.max() > ACTUATION_MAX + atol:
        return False
    return bool(np.all(np.abs(np.diff(arr, axis=-2)) <= max_slew + atol))
