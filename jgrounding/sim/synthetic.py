"""Recordings made by our own MuJoCo trunk: the identifiability check's data and the docs' example folder.

The same marker model calibration fits (:func:`jgrounding.sim.calibration.marker_spec`), rolled out with
``mujoco.rollout`` at the physics rate, in the recording format of :mod:`jgrounding.sim.recordings`.
"""

from __future__ import annotations

import mujoco
import numpy as np

from jgrounding.sim import calibration
from jgrounding.sim import mjcf as tm
from jgrounding.sim.measures import MAX_TIP_SPEED


def synthesize(
    u, params: tm.TrunkParams, marker_names, marker_s, *, names=None, labels=None, noise: float = 0.0, seed: int = 0
) -> list:
    """Recordings made by our own MuJoCo trunk ``params``: commands ``u (B, T, 4)`` at the control rate (30 Hz) held
    over the physics steps, markers sampled at every physics step (120 Hz) with Gaussian ``noise`` (m). What the
    identifiability check fits, and an example folder for the docs."""
    from mujoco import rollout as mj_rollout

    from jgrounding.sim.measures import SUBSTEPS
    from jgrounding.sim.recordings import Recording

    u = np.asarray(u, np.float64)
    spec = calibration.marker_spec(params, marker_names, marker_s, max_delay=params.delay)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    first = data.sensordata.copy()
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, kind))
    mujoco.mj_getState(model, data, state0, kind)
    control = np.repeat(u, SUBSTEPS, axis=1)
    datas = [mujoco.MjData(model) for _ in range(calibration.n_threads())]
    state, sensordata = mj_rollout.rollout(model, datas, np.tile(state0, (len(u), 1)), control)
    # A diverging simulation (MuJoCo resets it: its clock goes back; or a marker moves faster than MAX_TIP_SPEED,
    # the simulator's blow-up bound) is no recording of this trunk
    speed = np.linalg.norm(np.diff(sensordata.reshape(len(u), control.shape[1], -1, 3), axis=1), axis=-1) / tm.TIMESTEP
    bad = [
        b
        for b in range(len(u))
        if not (np.all(np.diff(state[b, :, 0]) > 0) and np.all(np.isfinite(sensordata[b])))
        or np.nan_to_num(speed[b], nan=np.inf).max() > MAX_TIP_SPEED
    ]
    if bad:
        raise calibration.UnstableError(f"the trunk {params} diverges on command(s) {bad} of {len(u)}")
    rng = np.random.default_rng(seed)
    out = []
    m = len(marker_names)
    for b in range(len(u)):
        pos = np.concatenate([first[None], sensordata[b, :-1]]).reshape(-1, m, 3)
        pos = pos + noise * rng.standard_normal(pos.shape)
        intent, intensity = labels[b] if labels is not None else ("nodding", "moderate")
        out.append(
            Recording(
                name=names[b] if names is not None else f"rec{b:03d}",
                t=np.arange(control.shape[1]) * tm.TIMESTEP,
                u=control[b],
                markers=pos,
                marker_names=tuple(marker_names),
                marker_s=np.asarray(marker_s, float),
                intent=intent,
                intensity=intensity,
            )
        )
    return out
