"""What ``python -m experiments.trunk_reference`` measures on the reference's motion: the library's kinematic
signatures on the physical rod, and how far the hand-tuned MuJoCo trunk is from the rod on the same commands.

The signatures are those of ``tests/library/test_signatures.py`` (SPEC §2-3), evaluated per realization where
the test asserts a property of every realization, and as one verdict per group where it asserts a mean or a
median. They read :func:`jgrounding.sim.features` of a :class:`jgrounding.sim.Rollout` built from the rod's
backbone at the MuJoCo trunk's points (segment origins and tip, at their undeformed arc lengths) at the end of
each control step. The rod has no user body, so its contact force is zero; the distances to the user are
geometric, as in the MuJoCo trunk's features.
"""

from __future__ import annotations

import mujoco
import numpy as np

from jgrounding import sim
from jgrounding.sim import mjcf as tm
from jgrounding.sim import reference
from jgrounding.sim.measures import NUM_POINTS, SUBSTEPS, finish_rollout
from jgrounding.vocabulary import INTENSITIES, INTENTS

EMPHATIC = INTENSITIES.index("emphatic")
SUBTLE = INTENSITIES.index("subtle")


def chain_s() -> np.ndarray:
    """Undeformed arc lengths of the MuJoCo trunk's backbone points (segment origins, root first, and tip)."""
    return np.concatenate([[0.0], np.cumsum(tm.segment_lengths())])


def rod_rollout(nodes: np.ndarray) -> sim.Rollout:
    """A :class:`jgrounding.sim.Rollout` of rod node positions ``(B, 4 T_c + 1, n + 1, 3)`` at 120 Hz: the points
    at the MuJoCo trunk's arc lengths at the end of each control step."""
    per = int(round(sim.CONTROL_DT * reference.RECORD_HZ))
    n = nodes.shape[-2] - 1
    s_nodes = np.linspace(0.0, reference.PARAMETERS.length, n + 1)
    backbone = reference.at_arc_length(nodes[:, per::per], s_nodes, chain_s())
    batch, steps = backbone.shape[:2]
    return finish_rollout(backbone, np.zeros((batch, steps, 4)), np.zeros((batch, steps)))


def mujoco_markers(u: np.ndarray, marker_s, *, contact: bool = False) -> np.ndarray:
    """Marker positions ``(B, 4 T_c, M, 3)`` of the MuJoCo trunk at 120 Hz (one per physics step, sample k
    before step k) driven by ``u`` ``(B, T_c, 4)``: its backbone points interpolated at arc lengths
    ``marker_s`` of the undeformed chain. ``contact=False``: without the user's body, like the rod."""
    from mujoco import rollout as mj_rollout

    model = sim.load_model(None, contact)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state0, spec)
    first = data.sensordata[: 3 * NUM_POINTS].reshape(NUM_POINTS, 3).copy()
    u = np.asarray(u, np.float64)
    control = np.repeat(u, SUBSTEPS, axis=1)[:, :-1]  # sample k is the state before step k
    batch = len(u)
    _, sensordata = mj_rollout.rollout(model, mujoco.MjData(model), np.tile(state0, (batch, 1)), control)
    points = sensordata[..., : 3 * NUM_POINTS].reshape(batch, -1, NUM_POINTS, 3)
    points = np.concatenate([np.broadcast_to(first, (batch, 1, NUM_POINTS, 3)), points], axis=1)
    return reference.at_arc_length(points, chain_s(), marker_s)


def rms(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(backbone RMS over markers and time, tip RMS over time) per recording, in metres, of marker paths
    ``(B, T, M, 3)`` (the tip is the last marker)."""
    d2 = ((a - b) ** 2).sum(-1)
    return np.sqrt(d2.mean(axis=(1, 2))), np.sqrt(d2[..., -1].mean(axis=1))


# ---------------------------------------------------------------- signatures


def _per_realization(f: dict, z: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
    """``{intent: {signature: (N,) bool}}`` for the signatures the test asserts of every realization (NaN-free
    features ``f`` of the intent's realizations, intensities ``z``)."""
    return {
        "greeting": {
            "rises (rise > 0)": f["rise"] > 0.0,
            "waves (lateral reversals >= 1)": f["lateral_reversals"] >= 1,
        },
        "withdrawal": {
            "ends farther from the user (final retreat > 0)": f["final_retreat"] > 0.0,
            "no reach toward the user (< 0.05 m)": f["reach_toward_user"] < 0.05,
        },
        "nodding": {
            "sagittal > lateral excursion": f["sagittal_excursion"] > f["lateral_excursion"],
            "vertical reversals >= 1": f["vertical_reversals"] >= 1,
        },
        "refusing": {"lateral > 0.8 x sagittal excursion": f["lateral_excursion"] > 0.8 * f["sagittal_excursion"]},
        "comforting": {
            "emphatic: within 0.15 m of the user": np.where(z == EMPHATIC, f["min_user_distance"] < 0.15, True)
        },
        "embracing": {
            "emphatic: within 0.15 m of the user": np.where(z == EMPHATIC, f["min_user_distance"] < 0.15, True)
        },
        "offering": {
            "emphatic: within 0.15 m of the user": np.where(z == EMPHATIC, f["min_user_distance"] < 0.15, True)
        },
        "coiling": {"no reach toward the user (< 0.08 m)": f["reach_toward_user"] < 0.08},
        "playful_swing": {"lateral reversals >= 1": f["lateral_reversals"] >= 1},
        "celebrating": {"lateral reversals >= 1": f["lateral_reversals"] >= 1},
        "curiosity": {"lateral reversals >= 1": f["lateral_reversals"] >= 1},
    }


def _groups(f: dict, m: np.ndarray, z: np.ndarray) -> list[tuple[str, str, bool]]:
    """(intent, signature, holds) for the signatures the test asserts of a group (a mean or a median)."""
    out = []
    sel = m == INTENTS.index("greeting")
    out.append(("greeting", "mean reach toward the user > 0", bool(f["reach_toward_user"][sel].mean() > 0.0)))
    nod, shake = m == INTENTS.index("nodding"), m == INTENTS.index("refusing")
    ratio = f["lateral_excursion"] / np.maximum(f["sagittal_excursion"], 1e-9)
    out.append(
        (
            "refusing",
            "median lateral/sagittal > 2 x nodding's",
            bool(np.median(ratio[shake]) > 2 * np.median(ratio[nod])),
        )
    )
    cel = m == INTENTS.index("celebrating")
    out.append(
        (
            "celebrating",
            "emphatic rises more than subtle (mean)",
            bool(f["rise"][cel & (z == EMPHATIC)].mean() > f["rise"][cel & (z == SUBTLE)].mean()),
        )
    )
    path = f["lateral_excursion"] + f["sagittal_excursion"] + f["vertical_excursion"]
    for k, name in enumerate(INTENTS):
        if name == "resting":
            continue
        sel = m == k
        hi, lo = sel & (z == EMPHATIC), sel & (z == SUBTLE)
        if not hi.any() or not lo.any():
            continue
        grows = path[hi].mean() > path[lo].mean() and f["peak_tip_speed"][hi].mean() > f["peak_tip_speed"][lo].mean()
        out.append((name, "intensity grows the tip path and peak speed (means)", bool(grows)))
    return out


FEATURES = {  # the features each intent's per-realization signatures read
    "greeting": ("rise", "lateral_reversals"),
    "withdrawal": ("final_retreat", "reach_toward_user"),
    "nodding": ("sagittal_excursion", "lateral_excursion", "vertical_reversals"),
    "refusing": ("lateral_excursion", "sagittal_excursion"),
    "comforting": ("min_user_distance",),
    "embracing": ("min_user_distance",),
    "offering": ("min_user_distance",),
    "coiling": ("reach_toward_user",),
    "playful_swing": ("lateral_reversals", "lateral_excursion"),
    "celebrating": ("lateral_reversals", "lateral_excursion"),
    "curiosity": ("lateral_reversals", "lateral_excursion"),
}


def signatures(features: dict, intent: np.ndarray, intensity: np.ndarray) -> dict:
    """Per intent: realizations, how many hold every per-realization signature, each signature's count, the
    indices (into the batch) of those that do not, and the group verdicts:
    ``{intent: {"n", "hold", "each": {sig: count}, "failing": [index], "groups": [(sig, holds)]}}``."""
    out = {}
    groups = _groups(features, intent, intensity)
    for k, name in enumerate(INTENTS):
        sel = intent == k
        if not sel.any():
            continue
        f = {key: v[sel] for key, v in features.items()}
        sigs = _per_realization(f, intensity[sel]).get(name, {})
        every = np.ones(int(sel.sum()), bool)
        for v in sigs.values():
            every &= v
        out[name] = {
            "n": int(sel.sum()),
            "hold": int(every.sum()) if sigs else None,
            "each": {s: int(v.sum()) for s, v in sigs.items()},
            "failing": np.flatnonzero(sel)[~every].tolist() if sigs else [],
            "groups": [(s, ok) for i, s, ok in groups if i == name],
        }
    return out
