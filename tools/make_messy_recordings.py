"""Messy recordings, as a lab exports them on day one: ``python -m tools.make_messy_recordings --out DIR``.

Sixteen demonstrations of four (intent, intensity) tuples (4 each), made from records of the shipped library
and written the way a real lab's logger writes them: a 200 Hz clock, motor angles in degrees
(:data:`LIMITS_DEG`, motor C reading backwards: slack 540 deg, full pull 0 deg), the lab's own column names
(``Elapsed_s, Motor_A_deg, ...``), and sensor noise of sigma 0.6 deg (0.1% of the travel) that is *not*
clipped, so readings at slack or full pull fall a hair outside the limits. A ``manifest.csv`` lists them.
On top of that, one file each (see :data:`PROBLEMS`):

- accepted, with a note: another column order, a UTF-8 BOM, ``;`` between cells with decimal commas;
- refused: a stuck sensor, a 2 s gap in the time stamps, time in milliseconds (the header still says
  ``Elapsed_s``), a flat recording (the robot was off), and a manifest text with an unquoted comma.

Used by ``tests/library/test_messy_import.py`` and the walk-through in ``docs/own_data.md``. Deterministic
in ``--seed``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from jgrounding.io import write_atomic
from jgrounding.vocabulary import INTENSITIES, INTENTS

TUPLES = (("nodding", "moderate"), ("nodding", "emphatic"), ("greeting", "moderate"), ("greeting", "emphatic"))
REALIZATIONS = 4
RATE_HZ = 200.0
NOISE_DEG = 0.6
LIMITS_DEG = ((0.0, 540.0), (0.0, 540.0), (540.0, 0.0), (0.0, 540.0))  # (slack, full pull); motor C reversed
LIMITS_FLAG = ",".join(f"{a:g}:{b:g}" for a, b in LIMITS_DEG)  # --limits of the import
TIME = "Elapsed_s"
MOTORS = ("Motor_A_deg", "Motor_B_deg", "Motor_C_deg", "Motor_D_deg")
PROBLEMS = {  # file -> what is wrong with it (the rest are clean but noisy)
    "nodding_moderate_2.csv": "columns in another order",
    "nodding_moderate_3.csv": "UTF-8 byte-order mark",
    "nodding_moderate_4.csv": "stuck sensor: Motor_B_deg holds one reading from 1.0 s to 4.0 s",
    "nodding_emphatic_1.csv": "';' between cells and decimal commas",
    "nodding_emphatic_3.csv": "2 s gap in the time stamps (2.0 s to 4.0 s lost)",
    "greeting_moderate_1.csv": "time in milliseconds, header still Elapsed_s",
    "greeting_moderate_4.csv": "flat: the robot was off",
    "greeting_emphatic_1.csv": "its manifest text has an unquoted comma",
}
REFUSED = (
    "nodding_moderate_4.csv",
    "nodding_emphatic_3.csv",
    "greeting_moderate_1.csv",
    "greeting_moderate_4.csv",
    "greeting_emphatic_1.csv",
)


def degrees(u: np.ndarray, duration: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(time (n,), motor angles (n, 4)) of ``u (150, 4)`` in [0, 1] played over ``duration`` s at 200 Hz."""
    n = int(round(duration * RATE_HZ)) + 1
    t = np.arange(n) / RATE_HZ + rng.uniform(-2e-4, 2e-4, n)
    t[0], t[-1] = 0.0, duration
    grid = np.linspace(0.0, duration, len(u))
    lim = np.asarray(LIMITS_DEG)
    x = np.stack([np.interp(t, grid, u[:, j]) for j in range(u.shape[1])], -1)
    return t, lim[:, 0] + x * (lim[:, 1] - lim[:, 0]) + rng.normal(0.0, NOISE_DEG, x.shape)


def to_csv(t, x, columns=(TIME, *MOTORS), delimiter=",", decimal=".", bom=False) -> str:
    lines = [delimiter.join(columns)]
    for ti, row in zip(t, x):
        cells = [f"{ti:.4f}"] + [f"{v:.2f}" for v in row]
        lines.append(delimiter.join(c.replace(".", decimal) for c in cells))
    return ("\ufeff" if bom else "") + "\n".join(lines) + "\n"


def recording(file: str, u: np.ndarray, rng: np.random.Generator) -> str:
    t, x = degrees(u, float(rng.uniform(4.6, 5.4)), rng)
    if file == "nodding_moderate_2.csv":  # another column order
        order = [0, 3, 1, 4, 2]
        cols = np.array((TIME, *MOTORS))[order]
        full = np.column_stack([t, x])[:, order]
        return to_csv(full[:, 0], full[:, 1:], columns=tuple(cols))
    if file == "nodding_moderate_3.csv":
        return to_csv(t, x, bom=True)
    if file == "nodding_moderate_4.csv":  # stuck sensor
        stuck = (t >= 1.0) & (t <= 4.0)
        x[stuck, 1] = round(float(x[np.argmax(stuck), 1]) + 100.0, 2)
        return to_csv(t, x)
    if file == "nodding_emphatic_1.csv":
        return to_csv(t, x, delimiter=";", decimal=",")
    if file == "nodding_emphatic_3.csv":  # 2 s of frames lost
        keep = (t < 2.0) | (t > 4.0)
        return to_csv(t[keep], x[keep])
    if file == "greeting_moderate_1.csv":  # milliseconds under a seconds header
        return to_csv(t * 1000.0, x)
    if file == "greeting_moderate_4.csv":  # the robot was off: slack plus noise
        lim = np.asarray(LIMITS_DEG)
        return to_csv(t, lim[:, 0] + rng.normal(0.0, NOISE_DEG, x.shape))
    return to_csv(t, x)


def write(out, seed: int = 0) -> Path:
    from jgrounding import load_library

    out = Path(out)
    lib = load_library()
    rng = np.random.default_rng(seed)
    rows = ["file,intent,intensity,texts,realization"]
    for name, level in TUPLES:
        m, z = INTENTS.index(name), INTENSITIES.index(level)
        records = [
            (split.u[i], split.texts[i])
            for split in (lib.train, lib.heldout)
            for i in np.flatnonzero((split.intent == m) & (split.intensity == z))
        ][:REALIZATIONS]
        for r, (u, texts) in enumerate(records):
            file = f"{name}_{level}_{r + 1}.csv"
            write_atomic(out / file, recording(file, np.asarray(u), rng))
            said = "|".join(str(s) for s in texts[:2])
            if file == "greeting_emphatic_1.csv":  # a text with a comma, not quoted
                said = "Hello there, so good to see you!|" + str(texts[0])
            elif "," in said:
                said = '"' + said.replace('"', '""') + '"'
            rows.append(f"{file},{name},{level},{said},{r}")
    write_atomic(out / "manifest.csv", "\n".join(rows) + "\n")
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", default="runs/messy_recordings")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    out = write(args.out, args.seed)
    print(f"wrote {len(TUPLES) * REALIZATIONS} recordings and manifest.csv to {out}")
    for file, problem in PROBLEMS.items():
        print(f"  {file}: {problem}")
    print(f"import: python -m jgrounding.library import {out} --out my_library.npz --limits {LIMITS_FLAG} --controls 4")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
