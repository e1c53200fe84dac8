"""Compact actuation-space reduction (Sec. III-B): uniform Catmull-Rom splines over tendon pulls.

Controls ``c`` have shape ``(..., N_u, P)``; actuation ``u`` has shape ``(..., T, N_u)``. Control k
sits at execution time tau_k = k / (P - 1), and the reconstruction interpolates it:
``R(c; tau_k) = c[..., k]``. Each of the P - 1 segments is the standard uniform Catmull-Rom cubic
(tension 1/2), which is C^1 at every joint.

End condition (documented choice): the missing neighbours of the first and last segment are
*phantom points by linear extrapolation*, c_{-1} = 2 c_0 - c_1 and c_P = 2 c_{P-1} - c_{P-2}. With
it the end tangents equal the one-sided chord slopes (c_1 - c_0 and c_{P-1} - c_{P-2} per segment),
so a linear trajectory is reproduced exactly and the curve does not overshoot at its ends.

Because R is linear in c, reconstruction is one matrix product with a ``(T, P)`` basis, and the
least-squares fit of Eq. (ci) has the closed form ``c = (B^T B)^{-1} B^T u`` on the T-point
execution grid tau_t = t / (T - 1) (the trajectory is only known there). ``fit(reconstruct(c)) == c``
up to float error whenever T >= P.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jgrounding.config import NUM_CONTROLS, NUM_STEPS  # noqa: E402  (T and P of Table I, defined once)


def _check_sizes(num_steps: int, num_controls: int) -> None:
    if isinstance(num_controls, bool) or not isinstance(num_controls, (int, np.integer)) or num_controls < 2:
        raise ValueError(f"num_controls (P) must be an integer >= 2, got {num_controls!r}")
    if isinstance(num_steps, bool) or not isinstance(num_steps, (int, np.integer)) or num_steps < num_controls:
        raise ValueError(f"num_steps (T) must be an integer >= num_controls (P={num_controls}), got {num_steps!r}")


@functools.lru_cache(maxsize=64)
def basis_np(num_steps: int, num_controls: int) -> np.ndarray:
    tau = np.linspace(0.0, 1.0, num_steps)
    seg_count = num_controls - 1
    x = tau * seg_count
    seg = np.minimum(np.floor(x).astype(int), seg_count - 1)
    s = x - seg
    # Catmull-Rom weights on (p_{i-1}, p_i, p_{i+1}, p_{i+2}) at local parameter s.
    w = 0.5 * np.stack(
        [
            -s + 2 * s**2 - s**3,
            2 - 5 * s**2 + 3 * s**3,
            s + 4 * s**2 - 3 * s**3,
            -(s**2) + s**3,
        ],
        axis=-1,
    )  # (T, 4)
    # Extended control vector e = [phantom_left, c_0..c_{P-1}, phantom_right] = E @ c.
    ext = np.zeros((num_controls + 2, num_controls))
    ext[1:-1] = np.eye(num_controls)
    ext[0, 0], ext[0, 1] = 2.0, -1.0
    ext[-1, -1], ext[-1, -2] = 2.0, -1.0
    basis = np.zeros((num_steps, num_controls))
    for k in range(4):  # e index of the k-th neighbour is seg + k.
        basis += w[:, k : k + 1] * ext[seg + k]
    return basis


def basis(num_steps: int = NUM_STEPS, num_controls: int = NUM_CONTROLS) -> jax.Array:
    """Reconstruction matrix ``B`` of shape ``(T, P)``: ``u[:, j] = B @ c[j, :]``."""
    _check_sizes(num_steps, num_controls)
    return jnp.asarray(basis_np(int(num_steps), int(num_controls)), dtype=jnp.float32)


@functools.lru_cache(maxsize=64)
def pinv_np(num_steps: int, num_controls: int) -> np.ndarray:
    b = basis_np(num_steps, num_controls)
    return np.linalg.solve(b.T @ b, b.T)  # (P, T), computed in float64


def _check_finite(x, name: str) -> None:
    if isinstance(x, jax.core.Tracer):
        return  # Values are unknown while tracing; the public API checks concrete inputs.
    if not np.all(np.isfinite(np.asarray(x))):
        raise ValueError(f"{name} contains NaN or Inf")


def _as_real_array(x, name: str, shape: str) -> jax.Array:
    """``jnp.asarray`` for a real numeric (float, integer or bool) array; a clear error otherwise."""
    try:
        arr = jnp.asarray(x)
    except (TypeError, ValueError) as e:
        raise type(e)(f"{name} must be a real numeric array of shape {shape}, got {type(x).__name__} ({e})") from None
    if not (jnp.issubdtype(arr.dtype, jnp.floating) or jnp.issubdtype(arr.dtype, jnp.integer) or arr.dtype == bool):
        raise TypeError(
            f"{name} must be a real numeric array (float, integer or bool) of shape {shape}, got dtype {arr.dtype}"
        )
    return arr


def reconstruct(c, num_steps: int = NUM_STEPS) -> jax.Array:
    """Eq. (reconstruction): controls ``(..., N_u, P)`` -> actuation ``(..., T, N_u)``.

    Not gated: Catmull-Rom interpolates its controls and can overshoot between them, so controls in [0, 1]
    can give actuation slightly outside [0, 1] (e.g. 1.02). Pass the result through
    :func:`jgrounding.safety.make_safe` (or :func:`jgrounding.safety.emit`) before it drives a trunk or
    serves as ``current=``; :func:`jgrounding.sample` already returns gated actuation.
    """
    c = _as_real_array(c, "controls", "(..., N_u, P)")
    if c.ndim < 2:
        raise ValueError(f"controls must have shape (..., N_u, P), got {c.shape}")
    _check_sizes(num_steps, c.shape[-1])
    _check_finite(c, "controls")
    b = basis(num_steps, c.shape[-1]).astype(c.dtype if jnp.issubdtype(c.dtype, jnp.floating) else jnp.float32)
    return jnp.einsum("tp,...jp->...tj", b, c)


def fit(u, num_controls: int = NUM_CONTROLS) -> jax.Array:
    """Eq. (ci) in closed form: actuation ``(..., T, N_u)`` -> least-squares controls ``(..., N_u, P)``."""
    u = _as_real_array(u, "actuation", "(..., T, N_u)")
    if u.ndim < 2:
        raise ValueError(f"actuation must have shape (..., T, N_u), got {u.shape}")
    _check_sizes(u.shape[-2], num_controls)
    _check_finite(u, "actuation")
    dtype = u.dtype if jnp.issubdtype(u.dtype, jnp.floating) else jnp.float32
    pinv = jnp.asarray(pinv_np(int(u.shape[-2]), int(num_controls)), dtype=dtype)
    return jnp.einsum("pt,...tj->...jp", pinv, u.astype(dtype))
