"""Command streams for hardware: the (150, N_u) tendon actuation (N_u = 4 for the built-in trunk) as CSV and JSON at the control rate.

Both formats carry a header with units, bounds and timing, so a lab's motor controller can check what
it receives. The default is normalized pull (0 = slack, 1 = full pull); with ``limits`` (the per-tendon
``(slack, full_pull)`` of an import, :func:`jgrounding.apps.own.import_info`) the values are written in the
lab's own units, and ``channels`` names the columns (an imported library's own tendon names). Trajectories pass through :func:`jgrounding.safety.emit` before they are written, so a
file on disk is always inside the actuation bounds and slew limit. Files are written atomically.
"""

from __future__ import annotations

import csv
import io
import json
import os

import numpy as np

from jgrounding import safety
from jgrounding.vocabulary import INTENSITIES, INTENTS

FORMAT_VERSION = 1
TENDON_ANGLES_DEG = (0, 90, 180, 270)


def _layout() -> dict:
    return {
        "channels": [f"tendon_{j}_{a}deg" for j, a in enumerate(TENDON_ANGLES_DEG)],
        "tendon_layout": "tendon 0 faces the user (+x), 1 robot's left (+y), 2 away (-x), 3 right (-y)",
    }


def _check_own(u: np.ndarray, channels, limits) -> None:
    n = u.shape[-1]
    if channels is not None and len(channels) != n:
        raise ValueError(f"channels has {len(channels)} names ({list(channels)}), but the trajectory has {n} tendons")
    if limits is not None and (len(limits) != n or any(len(p) != 2 or p[0] == p[1] for p in limits)):
        raise ValueError(f"limits must be {n} (slack, full_pull) pairs of different numbers, got {list(limits)}")


def to_lab_units(u, limits) -> np.ndarray:
    """Normalized pull ``(..., N_u)`` -> the lab's units: slack + u * (full_pull - slack) per tendon."""
    lim = np.asarray(limits, np.float64)
    return lim[:, 0] + np.asarray(u, np.float64) * (lim[:, 1] - lim[:, 0])


def _header(u: np.ndarray, control_dt: float, meta: dict | None, channels=None, limits=None) -> dict:
    if limits is None:
        units = {
            "units": "normalized tendon pull (0 = slack, 1 = largest safe pull)",
            "bounds": [safety.ACTUATION_MIN, safety.ACTUATION_MAX],
            "max_slew_per_step": safety.MAX_SLEW,
        }
    else:
        units = {
            "units": "the lab's own units, as imported: slack + u * (full_pull - slack) per tendon",
            "limits": [[float(a), float(b)] for a, b in limits],
            "bounds": [sorted([float(a), float(b)]) for a, b in limits],
            "max_slew_per_step": [round(safety.MAX_SLEW * abs(b - a), 9) for a, b in limits],
        }
    if channels is not None:
        layout = {"channels": list(channels), "tendon_layout": "as in the imported library (its column names)"}
    elif u.shape[-1] == len(TENDON_ANGLES_DEG) and limits is None:
        layout = _layout()
    else:
        layout = {
            "channels": [f"tendon_{j}" for j in range(u.shape[-1])],
            "tendon_layout": "as in the imported library",
        }
    return {
        "format_version": FORMAT_VERSION,
        **units,
        "control_dt_s": control_dt,
        "control_rate_hz": 1.0 / control_dt,
        "num_steps": int(u.shape[0]),
        **layout,
        **(meta or {}),
    }


def command_stream_csv(u, *, control_dt: float, meta: dict | None = None, channels=None, limits=None) -> str:
    """CSV text: ``#``-prefixed JSON header lines, then ``step,time_s,<channel>...`` rows.

    ``channels``: column names (default ``tendon_0..``); ``limits``: per-tendon ``(slack, full_pull)`` to
    write the lab's units instead of normalized pull (the gate runs on the normalized values first).
    """
    u = safety.emit(u, num_channels=np.shape(u)[-1] if np.ndim(u) else 4)
    if u.ndim != 2:
        raise ValueError(f"one trajectory of shape (T, N_u) expected, got {u.shape}")
    _check_own(u, channels, limits)
    buf = io.StringIO()
    for key, value in _header(u, control_dt, meta, channels, limits).items():
        buf.write(f"# {key}: {json.dumps(value)}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        ["step", "time_s"] + (list(channels) if channels is not None else [f"tendon_{j}" for j in range(u.shape[1])])
    )
    values = u if limits is None else to_lab_units(u, limits)
    for t, row in enumerate(values):
        w.writerow([t, f"{t * control_dt:.6f}"] + [f"{v:.6f}" for v in row])
    return buf.getvalue()


def command_stream_json(u, *, control_dt: float, meta: dict | None = None, channels=None, limits=None) -> str:
    """JSON text: ``{"header": {...}, "commands": [[u0..u3] per step]}`` (``channels``, ``limits``: as the CSV)."""
    u = safety.emit(u, num_channels=np.shape(u)[-1] if np.ndim(u) else 4)
    if u.ndim != 2:
        raise ValueError(f"one trajectory of shape (T, N_u) expected, got {u.shape}")
    _check_own(u, channels, limits)
    values = u.astype(float) if limits is None else to_lab_units(u, limits)
    doc = {"header": _header(u, control_dt, meta, channels, limits), "commands": np.round(values, 6).tolist()}
    return json.dumps(doc, indent=1)


def read_command_stream_csv(path: str | os.PathLike) -> tuple[dict, np.ndarray]:
    """Parse a file written by :func:`command_stream_csv` back into (header, (T, N_u) array)."""
    header, rows = {}, []
    with open(path) as f:
        for line in f:
            if line.startswith("# "):
                key, _, value = line[2:].partition(": ")
                header[key] = json.loads(value)
            elif line.strip() and not line.startswith("step"):
                rows.append([float(x) for x in line.strip().split(",")[2:]])
    return header, np.asarray(rows, np.float32)


def tuple_meta(intent: int, intensity: int, **extra) -> dict:
    return {"intent": INTENTS[intent], "intensity": INTENSITIES[intensity], **extra}
