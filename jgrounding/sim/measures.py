"""What the simulator measures: the :class:`Rollout` record, the trunk's conventions and safety
bounds, whole-body shape features and the feasibility check (shared by every engine).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jgrounding import config
from jgrounding.sim import mjcf as tm

NUM_SEGMENTS = tm.NUM_SEGMENTS
NUM_STEPS = config.NUM_STEPS  # T of Table I
NUM_CHANNELS = config.NUM_TENDONS  # N_u of the built-in trunk
TIMESTEP = tm.TIMESTEP
SUBSTEPS = 4
CONTROL_DT = TIMESTEP * SUBSTEPS  # 1/30 s
USER_POSITION = np.array([tm.USER_TORSO_X, 0.0, 0.7])
BASE_POSITION = np.array([0.0, 0.0, tm.BASE_HEIGHT])
# Safety bounds used by :func:`feasible` (and by library screening).
MAX_CONTACT_FORCE = 15.0  # N, normal force on the user
NEAR_USER_DISTANCE = 0.10  # m: closer than this counts as "near the user"
MAX_TIP_SPEED_NEAR_USER = 1.0  # m/s
MAX_TIP_SPEED = 10.0  # m/s anywhere: beyond this the simulation has blown up

NUM_POINTS = NUM_SEGMENTS + 1


@dataclasses.dataclass(frozen=True)
class Rollout:
    """Simulated motion, batch first; arrays are numpy. Positions in metres, world frame."""

    backbone: np.ndarray  # (B, T, n_seg + 1, 3): segment origins (root first) and the tip
    tip: np.ndarray  # (B, T, 3)
    tip_speed: np.ndarray  # (B, T) m/s
    tendon_length: np.ndarray  # (B, T, 4) m
    user_distance: np.ndarray  # (B, T) m, closest backbone point to the user's surface (< 0: inside)
    contact_force: np.ndarray  # (B, T) N, normal force on the user
    stable: np.ndarray  # (B,) bool: finite, bounded, no blow-up


def segment_distance(p, a, b):
    ab = b - a
    t = np.clip(((p - a) @ ab) / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def user_distance(points: np.ndarray) -> np.ndarray:
    """Distance of points ``(..., P, 3)`` to the user's surface, minimised over P -> ``(...)``."""
    a = np.array([tm.USER_TORSO_X, 0.0, tm.USER_TORSO_Z[0]])
    b = np.array([tm.USER_TORSO_X, 0.0, tm.USER_TORSO_Z[1]])
    torso = segment_distance(points, a, b) - tm.USER_TORSO_RADIUS
    head = np.linalg.norm(points - np.array(tm.USER_HEAD[:3]), axis=-1) - tm.USER_HEAD[3]
    return np.minimum(torso, head).min(axis=-1)


def finish_rollout(backbone, tendon, touch, rest_tip=None) -> Rollout:
    """The :class:`Rollout` of simulated points; ``rest_tip``: the tip at rest before the first step (default: the
    shipped trunk's, hanging straight down from the base)."""
    tip = backbone[:, :, -1]
    if rest_tip is None:
        rest_tip = BASE_POSITION - np.array([0, 0, tm.TRUNK_LENGTH])
    start = np.broadcast_to(np.asarray(rest_tip, np.float64), tip[:, :1].shape)
    tip_speed = np.linalg.norm(np.diff(np.concatenate([start, tip], 1), axis=1), axis=-1) / CONTROL_DT
    stable = (
        np.all(np.isfinite(backbone), axis=(1, 2, 3))
        & (np.abs(backbone).max(axis=(1, 2, 3)) < 3.0)
        & (np.nan_to_num(tip_speed, nan=np.inf).max(axis=1) < MAX_TIP_SPEED)
    )
    return Rollout(
        backbone=backbone,
        tip=tip,
        tip_speed=tip_speed,
        tendon_length=tendon,
        user_distance=user_distance(backbone),
        contact_force=touch,
        stable=stable,
    )


def turning_angle(backbone: np.ndarray) -> np.ndarray:
    """Total turning angle (rad) of the backbone polyline ``(..., P, 3)``, root axis included."""
    seg = np.diff(backbone, axis=-2)
    down = np.broadcast_to(np.array([0.0, 0.0, -1.0]), seg[..., :1, :].shape)
    seg = np.concatenate([down, seg], axis=-2)
    seg = seg / np.maximum(np.linalg.norm(seg, axis=-1, keepdims=True), 1e-9)
    cos = np.clip(np.sum(seg[..., 1:, :] * seg[..., :-1, :], axis=-1), -1.0, 1.0)
    return np.arccos(cos).sum(axis=-1)


def _sign_changes(x: np.ndarray, deadband: float) -> np.ndarray:
    """Number of direction reversals of ``(B, T)`` signals, ignoring moves smaller than deadband."""
    out = np.zeros(x.shape[0], dtype=np.int32)
    for b in range(x.shape[0]):
        anchor, direction, count = x[b, 0], 0, 0
        for v in x[b, 1:]:
            d = v - anchor
            if abs(d) >= deadband:
                s = 1 if d > 0 else -1
                if direction and s != direction:
                    count += 1
                direction, anchor = s, v
            elif direction and (v - anchor) * direction > 0:
                anchor = v
        out[b] = count
    return out


def features(r: Rollout) -> dict[str, np.ndarray]:
    """Whole-body shape features, each ``(B,)``: reach, curl, excursions, proximity, speed, oscillation."""
    tip = r.tip
    rest_tip = BASE_POSITION - np.array([0.0, 0.0, tm.TRUNK_LENGTH])
    turning = turning_angle(r.backbone)  # (B, T)
    return {
        "reach_toward_user": tip[..., 0].max(axis=1) - rest_tip[0],
        "retreat_from_user": rest_tip[0] - tip[..., 0].min(axis=1),
        "mean_tip_x": tip[..., 0].mean(axis=1),
        "final_tip_x": tip[:, -1, 0],
        "curvature_max": turning.max(axis=1),
        "curvature_mean": turning.mean(axis=1),
        "curl_final": turning[:, -1],
        "lateral_excursion": np.ptp(tip[..., 1], axis=1),
        "sagittal_excursion": np.ptp(tip[..., 0], axis=1),
        "rise": tip[..., 2].max(axis=1) - rest_tip[2],
        "final_retreat": tip[:, 0, 0] - tip[:, -1, 0],
        "vertical_excursion": np.ptp(tip[..., 2], axis=1),
        "max_tip_height": tip[..., 2].max(axis=1),
        "final_tip_height": tip[:, -1, 2],
        "min_user_distance": r.user_distance.min(axis=1),
        "final_user_distance": r.user_distance[:, -1],
        "peak_tip_speed": r.tip_speed.max(axis=1),
        "mean_tip_speed": r.tip_speed.mean(axis=1),
        "max_contact_force": r.contact_force.max(axis=1),
        "contact_fraction": (r.contact_force > 1e-3).mean(axis=1),
        "lateral_reversals": _sign_changes(tip[..., 1], 0.03),
        "vertical_reversals": _sign_changes(tip[..., 2], 0.02),
    }


def feasible(r: Rollout) -> np.ndarray:
    """``(B,)`` bool: stable, contact force within ``MAX_CONTACT_FORCE``, slow tip near the user."""
    near = r.user_distance < NEAR_USER_DISTANCE
    fast_near = np.any(near & (r.tip_speed > MAX_TIP_SPEED_NEAR_USER), axis=1)
    return r.stable & (r.contact_force.max(axis=1) <= MAX_CONTACT_FORCE) & ~fast_near


def feasibility_margin(r: Rollout) -> np.ndarray:
    """``(B,)`` float: the smallest relative slack of :func:`feasible`'s bounds, ``min(1 - peak force /
    MAX_CONTACT_FORCE, 1 - peak tip speed near the user / MAX_TIP_SPEED_NEAR_USER)``; -1 when unstable.
    ``margin >= 0`` exactly when the sample is feasible; larger is safer (1 = no contact, tip never fast
    near the user)."""
    near = r.user_distance < NEAR_USER_DISTANCE
    speed_near = np.where(near, np.nan_to_num(r.tip_speed, nan=np.inf), 0.0).max(axis=1)
    force = np.nan_to_num(r.contact_force, nan=np.inf).max(axis=1)
    margin = np.minimum(1.0 - force / MAX_CONTACT_FORCE, 1.0 - speed_near / MAX_TIP_SPEED_NEAR_USER)
    return np.where(r.stable, margin, -1.0)
