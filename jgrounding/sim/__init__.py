"""The trunk in simulation: batched rollouts of actuation ``(B, 150, 4)`` on MuJoCo (native) or MJX.

Two engines behind one function, :func:`rollout`, and one choice between them, ``engine="auto"``
(the default):

- ``"native"``: ``mujoco.rollout`` over the batch, multi-threaded, reading the backbone, tendon
  lengths and user contact force from sensors. On CPU it is the fast path: about 10x MJX's physics
  steps/s on this 2-core CPU (``python -m experiments.bench trunk`` prints both, for the ablation's
  batch), and it needs no compilation.
- ``"mjx"``: ``jit(vmap(lax.scan))`` over control steps with the physics substeps inside, compiled
  once per chunk size (padded power-of-two chunks, at most :data:`MJX_CHUNK`). It is the engine that scales on
  accelerators; on CPU it serves as a check (the two agree to float precision).
- ``"mjx-warp"``: the same program on MJX's Warp implementation (MuJoCo Warp's kernels; an NVIDIA GPU, or the
  CPU through Warp's LLVM backend, where it serves as a check: it agrees with native to float precision).
- ``"auto"``: ``"native"`` on the CPU; on an accelerator, the faster of ``"mjx"`` and ``"mjx-warp"``, measured
  once per device and stack on the shape the ablation runs and cached (:func:`resolve_engine`). Every caller in
  the project (ablation, screened sampling, physics-aware training) goes through it, so one flag decides the
  engine everywhere.

Conventions (fixed; the library, the ablation and the CLI rely on them): the trunk hangs from its
base at ``BASE_HEIGHT``; the user stands in front at +x; tendon 0 faces the user (+x), 1 the robot's
left (+y), 2 away (-x), 3 right (-y); pulling tendon j bends the trunk toward side j, all four
together shorten it. One control step lasts ``CONTROL_DT`` = 1/30 s (``SUBSTEPS`` physics steps), so
150 steps are 5 s of motion. Commands must be finite and inside [0, 1] (``ValueError`` otherwise):
this function simulates what it is given; clamping belongs to :mod:`jgrounding.safety` alone.
"""

from __future__ import annotations

import numpy as np

from jgrounding.sim.measures import (  # noqa: F401  (re-exported: the simulator's public surface)
    BASE_POSITION,
    CONTROL_DT,
    MAX_CONTACT_FORCE,
    MAX_TIP_SPEED,
    MAX_TIP_SPEED_NEAR_USER,
    NEAR_USER_DISTANCE,
    NUM_CHANNELS,
    NUM_POINTS,
    NUM_SEGMENTS,
    NUM_STEPS,
    SUBSTEPS,
    TIMESTEP,
    USER_POSITION,
    Rollout,
    feasibility_margin,
    feasible,
    features,
    finish_rollout,
    segment_distance,
    turning_angle,
    user_distance,
)
from jgrounding.sim.native import (  # noqa: F401
    has_delay,
    load_model,
    resolve_trunk,
    rollout_native,
    trunk_identity,
    trunk_mismatch,
    validate_actuation,
)

ENGINES = ("auto", "native", "mjx", "mjx-warp")
MJX_CHUNK = 1024  # the largest padded chunk MJX runs (evaluation.physics rolls out batches of this size)


def resolve_engine(engine: str = "auto", trunk: str | None = None) -> str:
    """``"auto"`` -> ``"native"`` on the CPU, or for a ``trunk`` with a command delay (MJX does not simulate MuJoCo's
    actuator delay; an MJX engine for such a trunk is an error); on an accelerator the engine of higher measured
    throughput among ``"mjx"`` and ``"mjx-warp"`` (:func:`jgrounding.sim.engines.fastest`: measured once per device
    and stack, then read from the cache). Other names pass through after validation."""
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; valid engines: {', '.join(ENGINES)}")
    delayed = trunk is not None and has_delay(resolve_trunk(trunk))
    if engine in ("mjx", "mjx-warp") and delayed:
        raise ValueError(
            f"trunk {trunk} has a command delay, which only the native engine simulates: use engine='native'"
        )
    if engine != "auto":
        return engine
    import jax

    if jax.default_backend() == "cpu" or delayed:
        return "native"
    from jgrounding.sim import engines

    return engines.fastest()


def rollout(u, *, engine: str = "auto", contact: bool = True, trunk: str | None = None) -> Rollout:
    """Simulate actuation ``(T, 4)`` or ``(B, T, 4)`` in [0, 1]; returns a batch-first :class:`Rollout`.

    ``engine``: ``"auto"`` (default: native on CPU, the faster MJX implementation on an accelerator), ``"native"``
    (MuJoCo, multi-threaded ``mujoco.rollout``), ``"mjx"`` or ``"mjx-warp"`` (compiled batched rollouts on MJX's
    JAX or Warp implementation, padded power-of-two chunks of at most :data:`MJX_CHUNK`). ``contact=False`` removes the user's contact geometry
    (distances are still measured). ``trunk``: the MJCF of the trunk to simulate (a fitted one, from
    ``python -m jgrounding.sim calibrate``); None, the shipped hand-tuned trunk.
    """
    trunk = resolve_trunk(trunk)
    engine = resolve_engine(engine, trunk)
    u = validate_actuation(u)
    if engine == "native":
        return rollout_native(u, contact, trunk)
    from jgrounding.sim import mjx

    # Padded chunks of the next power of two (at most MJX_CHUNK): a handful of compiled programs serve
    # every batch size.
    chunk = min(MJX_CHUNK, 1 << (u.shape[0] - 1).bit_length())
    if engine == "mjx-warp":
        return mjx.rollout_warp(u, contact, chunk=chunk, trunk=trunk)
    return mjx.rollout_mjx(u, contact, chunk=chunk, trunk=trunk)


def margins(u, *, engine: str = "auto", trunk: str | None = None) -> np.ndarray:
    """Feasibility margin (:func:`feasibility_margin`) of every trajectory ``u (B, T, 4)``, rolled out in
    chunks of :data:`MJX_CHUNK` -> ``(B,)``; ``>= 0`` exactly when feasible. What screening
    (``jg.sample(..., screen=True)``, the physics-aware fine-tuning) keeps or rejects by; on ``trunk`` (None: the
    shipped one)."""
    trunk = resolve_trunk(trunk)
    engine = resolve_engine(engine, trunk)
    return np.concatenate(
        [
            feasibility_margin(rollout(u[i : i + MJX_CHUNK], engine=engine, trunk=trunk))
            for i in range(0, len(u), MJX_CHUNK)
        ]
    )
