"""Example motion-capture recordings for docs/trunk.md: ``python -m tools.make_trunk_recordings``.

Writes ``assets/examples/trunk_mocap/``: eight recordings of the library's training commands played on our own
MuJoCo trunk with its parameters perturbed (the "lab's trunk" of the example, stated below), two markers (mid
backbone and tip) at 120 Hz in millimetres with 0.2 mm Gaussian noise, in the recording format of
:mod:`jgrounding.sim.recordings`. Calibrating on it (``python -m jgrounding.sim calibrate``) should find the
perturbed values. Deterministic.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from jgrounding import load_library
from jgrounding.sim import mjcf as tm
from jgrounding.sim.recordings import write_recordings
from jgrounding.sim.synthetic import synthesize
from jgrounding.vocabulary import INTENSITIES, INTENTS

OUT = Path(__file__).resolve().parent.parent / "assets" / "examples" / "trunk_mocap"
# The example lab's trunk: every fitted parameter moved 8-20 % from the shipped, hand-tuned trunk.
LAB_TRUNK = tm.TrunkParams(
    stiffness_root=8.2,
    stiffness_tip=0.42,
    damping_root=0.30,
    damping_tip=0.035,
    tendon_force=16.0,
    slide_stiffness=2200.0,
    density=400.0,
    delay=0.025,
)
MARKERS = (("mid", 0.35), ("tip", tm.TRUNK_LENGTH))
NOISE_M = 0.0002
COUNT = 8


def recordings(count: int = COUNT, seed: int = 0):
    lib = load_library()
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(len(lib.train.u), size=count, replace=False))
    labels = [(INTENTS[lib.train.intent[i]], INTENSITIES[lib.train.intensity[i]]) for i in idx]
    names = [f"{a}_{b}_{k}" for k, (a, b) in enumerate(labels)]
    return synthesize(
        lib.train.u[idx],
        LAB_TRUNK,
        [m for m, _ in MARKERS],
        [s for _, s in MARKERS],
        names=names,
        labels=labels,
        noise=NOISE_M,
        seed=seed,
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", default=str(OUT))
    p.add_argument("--count", type=int, default=COUNT)
    args = p.parse_args(argv)
    folder = write_recordings(
        args.out,
        recordings(args.count),
        marker_units="mm",
        extra={"source": "our MuJoCo trunk with perturbed parameters (tools/make_trunk_recordings.py)"},
    )
    print(f"wrote {folder}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
