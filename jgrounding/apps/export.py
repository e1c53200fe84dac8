"""Command streams for hardware: the (150, N_u) tendon actuation (N_u = 4 for the built-in trunk) as CSV and JSON at the control rate.

Both formats carry a header with units, bounds and timing, so a lab's motor controller can check what
it receives. Trajectories pass through :func:`jgrounding.safety.emit` before they are written, so a
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


def _header(u: np.ndarray, control_dt: float, meta: dict | None) -> dict:
    return {
        "format_version": FORMAT_VERSION,
        "units": "normalized tendon pull (0 = slack, 1 = largest safe pull)",
        "bounds": [safety.ACTUATION_MIN, safety.ACTUATION_MAX],
        "max_slew_per_step": safety.MAX_SLEW,
        "control_dt_s": control_dt,
        "control_rate_hz": 1.0 / control_dt,
        "num_steps": int(u.shape[0]),
        **(
            _layout()
            if u.shape[-1] == len(TENDON_ANGLES_DEG)
            else {
                "channels": [f"tendon_{j}" for j in range(u.shape[-1])],
                "tendon_layout": "as in the imported library",
            }
        ),
        **(meta or {}),
    }


def command_stream_csv(u, *, control_dt: float, meta: dict | None = None) -> str:
    """CSV text: ``#``-prefixed JSON header lines, then ``step,time_s,tendon_0..3`` rows."""
    u = safety.emit(u, num_channels=np.shape(u)[-1] if np.ndim(u) else 4)
    if u.ndim != 2:
        raise ValueError(f"one trajectory of shape (T, N_u) expected, got {u.shape}")
    buf = io.StringIO()
    for key, value in _header(u, control_dt, meta).items():
        buf.write(f"# {key}: {json.dumps(value)}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["step", "time_s"] + [f"tendon_{j}" for j in range(u.shape[1])])
    for t, row in enumerate(u):
        w.writerow([t, f"{t * control_dt:.6f}"] + [f"{v:.6f}" for v in row])
    return buf.getvalue()


def command_stream_json(u, *, control_dt: float, meta: dict | None = None) -> str:
    """JSON text: ``{"header": {...}, "commands": [[u0..u3] per step]}``."""
    u = safety.emit(u, num_channels=np.shape(u)[-1] if np.ndim(u) else 4)
    if u.ndim != 2:
        raise ValueError(f"one trajectory of shape (T, N_u) expected, got {u.shape}")
    doc = {"header": _header(u, control_dt, meta), "commands": np.round(u.astype(float), 6).tolist()}
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
