"""The native engine: multi-threaded ``mujoco.rollout`` over the batch, reading the backbone,
tendon lengths and user contact force from sensors (the CPU default of :func:`jgrounding.sim.rollout`).
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import mujoco
import numpy as np

from jgrounding.sim import mjcf as tm
from jgrounding.sim.measures import NUM_CHANNELS, NUM_POINTS, SUBSTEPS, Rollout, finish_rollout

_SENSOR_TENDON = slice(3 * NUM_POINTS, 3 * NUM_POINTS + 4)
_SENSOR_TOUCH = 3 * NUM_POINTS + 4


def from_sensordata(sensordata: np.ndarray) -> Rollout:
    """The trunk model's sensors ``(B, T, nsensordata)`` read at the end of each control step -> :class:`Rollout`:
    the backbone's frame positions, the four tendon lengths and the touch sensor over the user, in that order (what
    ``jgrounding/sim/model.py`` declares). The native engine and MJX's Warp engine both read this way."""
    batch, steps = sensordata.shape[:2]
    backbone = sensordata[..., : 3 * NUM_POINTS].reshape(batch, steps, NUM_POINTS, 3)
    return finish_rollout(backbone, sensordata[..., _SENSOR_TENDON], sensordata[..., _SENSOR_TOUCH])


@functools.lru_cache(maxsize=4)
def load_model(path: str | None = None, contact: bool = True) -> mujoco.MjModel:
    """The trunk MjModel: ``jgrounding/assets/trunk.xml`` by default; ``contact=False`` drops user contact."""
    if path is None and not contact:
        return mujoco.MjModel.from_xml_string(tm.build_xml(contact=False))
    path = Path(path or tm.DEFAULT_PATH)
    if not path.exists():
        raise FileNotFoundError(f"trunk model {path} not found; regenerate it with `python -m jgrounding.sim.model`")
    return mujoco.MjModel.from_xml_path(str(path))


def validate_actuation(u) -> np.ndarray:
    """``(T, 4)`` or ``(B, T, 4)`` finite commands in [0, 1] -> float64 ``(B, T, 4)``."""
    arr = np.asarray(u)
    if arr.dtype.kind not in "biuf":  # strings, objects, complex: not a command
        raise TypeError(f"actuation must be a real-valued array (T, 4) or (B, T, 4), got dtype {arr.dtype}")
    u = arr.astype(np.float64)
    if u.ndim == 2:
        u = u[None]
    if u.ndim != 3 or u.shape[-1] != NUM_CHANNELS or u.shape[1] < 1:
        raise ValueError(f"actuation must have shape (T, 4) or (B, T, 4), got {u.shape}")
    if not np.all(np.isfinite(u)):
        raise ValueError("actuation contains NaN or Inf")
    if u.min() < -1e-6 or u.max() > 1 + 1e-6:
        raise ValueError(
            f"actuation must lie in [0, 1] (got range [{u.min():.3g}, {u.max():.3g}]); "
            "pass it through jgrounding.safety.emit first"
        )
    return np.clip(u, 0.0, 1.0)


@functools.lru_cache(maxsize=2)
def _native_workers(contact: bool):
    model = load_model(None, contact)
    nthread = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)  # every core
    data = [mujoco.MjData(model) for _ in range(nthread)]
    init = mujoco.MjData(model)
    mujoco.mj_forward(model, init)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, init, state0, spec)
    return model, data, state0


def rollout_native(u: np.ndarray, contact: bool) -> Rollout:
    from mujoco import rollout as mj_rollout

    model, data, state0 = _native_workers(contact)
    batch = u.shape[0]
    control = np.repeat(u, SUBSTEPS, axis=1)  # control held over the physics substeps
    _, sensordata = mj_rollout.rollout(model, data if batch > 1 else data[0], np.tile(state0, (batch, 1)), control)
    return from_sensordata(sensordata[:, SUBSTEPS - 1 :: SUBSTEPS])  # end of each control step
