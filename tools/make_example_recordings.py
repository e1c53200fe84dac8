"""Example recordings for docs/own_data.md: ``python -m tools.make_example_recordings``.

Writes ``assets/examples/trunk_recordings/``: twelve demonstrations as a lab would record them on our
trunk model, with a ``manifest.json``. Each is a record of the shipped library (commands of the trunk
simulator, 150 steps) played over its own duration (4.6-5.4 s), read by a 100 Hz clock with +-0.5 ms
jitter, in millimetres of cable pull (each tendon with its own slack offset and full-pull travel), with
sensor-like Gaussian noise (0.03 mm). Deterministic in ``--seed``.
"""

from __future__ import annotations

import argparse
import io
import json
from pathlib import Path

import numpy as np

from jgrounding import load_library
from jgrounding.io import write_atomic
from jgrounding.vocabulary import INTENSITIES, INTENTS

OUT = Path(__file__).resolve().parent.parent / "assets" / "examples" / "trunk_recordings"
TUPLES = (("nodding", "moderate"), ("nodding", "emphatic"), ("greeting", "moderate"), ("greeting", "emphatic"))
REALIZATIONS = 3
LIMITS_MM = ((1.5, 13.5), (2.0, 14.0), (1.0, 13.0), (2.5, 14.5))  # (slack, full pull) per tendon
RATE_HZ = 100.0
NOISE_MM = 0.03


def recording(u: np.ndarray, duration: float, rng: np.random.Generator) -> str:
    """CSV text ``time,pull_0_mm..pull_3_mm`` of ``u (150, 4)`` in [0, 1] played over ``duration`` s."""
    n = int(round(duration * RATE_HZ)) + 1
    t = np.arange(n) / RATE_HZ + rng.uniform(-5e-4, 5e-4, n)
    t[0], t[-1] = 0.0, duration
    grid = np.linspace(0.0, duration, len(u))
    lim = np.asarray(LIMITS_MM)
    mm = np.stack([np.interp(t, grid, u[:, j]) for j in range(u.shape[1])], -1) * (lim[:, 1] - lim[:, 0]) + lim[:, 0]
    mm = np.clip(mm + rng.normal(0.0, NOISE_MM, mm.shape), lim[:, 0], lim[:, 1])  # the sensor's own range
    buf = io.StringIO()
    buf.write("time," + ",".join(f"pull_{j}_mm" for j in range(u.shape[1])) + "\n")
    for ti, row in zip(t, mm):
        buf.write(f"{ti:.4f}," + ",".join(f"{v:.3f}" for v in row) + "\n")
    return buf.getvalue()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", default=str(OUT))
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    lib = load_library()
    rng = np.random.default_rng(args.seed)
    entries = []
    for name, level in TUPLES:
        m, z = INTENTS.index(name), INTENSITIES.index(level)
        split = lib.train
        idx = np.flatnonzero((split.intent == m) & (split.intensity == z))[:REALIZATIONS]
        for r, i in enumerate(idx):
            file = f"{name}_{level}_{r + 1:02d}.csv"
            write_atomic(Path(args.out) / file, recording(split.u[i], float(rng.uniform(4.6, 5.4)), rng))
            entries.append(
                {"file": file, "intent": name, "intensity": level, "realization": r, "texts": list(split.texts[i][:2])}
            )
    manifest = {"limits": [list(p) for p in LIMITS_MM], "time_column": "time", "demonstrations": entries}
    write_atomic(Path(args.out) / "manifest.json", json.dumps(manifest, indent=1) + "\n")
    print(f"wrote {len(entries)} recordings and manifest.json to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
