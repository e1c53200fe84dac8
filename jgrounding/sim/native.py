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


def from_sensordata(sensordata: np.ndarray, rest_tip: np.ndarray | None = None) -> Rollout:
    """The trunk model's sensors ``(B, T, nsensordata)`` read at the end of each control step -> :class:`Rollout`:
    the backbone's frame positions, the four tendon lengths and the touch sensor over the user, in that order (what
    ``jgrounding/sim/model.py`` declares). The native engine and MJX's Warp engine both read this way. ``rest_tip``:
    a trunk of its own's tip at rest (None: the shipped trunk's)."""
    batch, steps = sensordata.shape[:2]
    backbone = sensordata[..., : 3 * NUM_POINTS].reshape(batch, steps, NUM_POINTS, 3)
    return finish_rollout(backbone, sensordata[..., _SENSOR_TENDON], sensordata[..., _SENSOR_TOUCH], rest_tip)


def resolve_trunk(trunk: str | os.PathLike | None) -> str | None:
    """The trunk setting as one value: None (the shipped, hand-tuned ``jgrounding/assets/trunk.xml``) or an absolute
    path to an MJCF file (a fitted trunk, or one built from its description); a missing file is an error here, at
    the boundary, not deep in a rollout."""
    if trunk is None or str(trunk) == "":
        return None
    path = Path(trunk).expanduser().resolve()
    if path == Path(tm.DEFAULT_PATH).resolve():
        return None
    if not path.is_file():
        raise FileNotFoundError(
            f"trunk {trunk} not found: pass an MJCF written by `python -m jgrounding.sim calibrate` or "
            "`python -m jgrounding.sim.model`, or leave the trunk unset for the shipped one"
        )
    return str(path)


def trunk_identity(trunk: str | os.PathLike | None) -> dict:
    """What a checkpoint or library records of the trunk it was screened on: ``{"path", "sha256"}`` (path None for the
    shipped trunk)."""
    from jgrounding.io import sha256_file

    path = resolve_trunk(trunk)
    return {"path": path, "sha256": sha256_file(path or tm.DEFAULT_PATH)}


def trunk_mismatch(recorded: dict | None, trunk: str | os.PathLike | None) -> str | None:
    """A sentence naming both trunks when ``recorded`` (a :func:`trunk_identity`) is not the trunk in use, else None.
    Records written before trunks were recorded were all screened on the shipped trunk."""
    recorded = recorded or {"path": None, "sha256": trunk_identity(None)["sha256"]}
    now = trunk_identity(trunk)
    if recorded.get("sha256") == now["sha256"]:
        return None
    name = lambda t: t["path"] or "the shipped trunk"  # noqa: E731
    return (
        f"screened on {name(recorded)} (sha256 {str(recorded.get('sha256'))[:12]}) but simulating on {name(now)} "
        f"(sha256 {now['sha256'][:12]}): its feasibility does not carry over"
    )


@functools.lru_cache(maxsize=8)
def load_model(path: str | None = None, contact: bool = True) -> mujoco.MjModel:
    """The trunk MjModel: ``jgrounding/assets/trunk.xml`` by default, else the MJCF at ``path`` (a fitted trunk);
    ``contact=False`` drops user contact. A trunk must keep the shipped layout (segments, tendons, sensors)."""
    path = resolve_trunk(path)
    if path is None and not contact:
        return mujoco.MjModel.from_xml_string(tm.build_xml(contact=False))
    file = Path(path or tm.DEFAULT_PATH)
    if not file.exists():
        raise FileNotFoundError(f"trunk model {file} not found; regenerate it with `python -m jgrounding.sim.model`")
    if contact:
        model = mujoco.MjModel.from_xml_path(str(file))
    else:
        spec = mujoco.MjSpec.from_file(str(file))
        for pair in list(spec.pairs):
            spec.delete(pair)
        model = spec.compile()
    if model.nu != NUM_CHANNELS or model.nsensordata != _SENSOR_TOUCH + 1 or model.nbody != NUM_POINTS + 1:
        raise ValueError(
            f"trunk {file} has {model.nu} motors, {model.nbody - 2} segments and {model.nsensordata} sensor values; "
            f"the simulator takes trunks of {NUM_CHANNELS} tendons and {NUM_POINTS - 1} segments with the shipped "
            "sensors (build it with python -m jgrounding.sim.model)"
        )
    return model


def has_delay(trunk: str | None) -> bool:
    """Whether the trunk holds its commands back (MuJoCo's actuator delay): only the native engine simulates it."""
    return bool(np.any(load_model(trunk, False).actuator_delay > 0))


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


@functools.lru_cache(maxsize=4)
def _native_workers(trunk: str | None, contact: bool):
    model = load_model(trunk, contact)
    nthread = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)  # every core
    data = [mujoco.MjData(model) for _ in range(nthread)]
    init = mujoco.MjData(model)
    mujoco.mj_forward(model, init)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, init, state0, spec)
    return model, data, state0, init.site_xpos[model.site("tip").id].copy()


def rollout_native(u: np.ndarray, contact: bool, trunk: str | None = None) -> Rollout:
    from mujoco import rollout as mj_rollout

    model, data, state0, rest_tip = _native_workers(resolve_trunk(trunk), contact)
    batch = u.shape[0]
    control = np.repeat(u, SUBSTEPS, axis=1)  # control held over the physics substeps
    _, sensordata = mj_rollout.rollout(model, data if batch > 1 else data[0], np.tile(state0, (batch, 1)), control)
    # the end of each control step; a trunk of its own is measured from its own tip at rest
    return from_sensordata(sensordata[:, SUBSTEPS - 1 :: SUBSTEPS], None if trunk is None else rest_tip)
