"""Reference baselines that bracket the success metric: ``python -m experiments.references``.

Oracle (replay a training realization of the same tuple) is the ceiling; wrong intent is the floor.
"""
from __future__ import annotations

import argparse

import numpy as np

from jgrounding import load_library, metrics


def table(refs: dict, taus=metrics.TAUS) -> str:
    head = "| reference | " + " | ".join(f"succ@{t:.2f}" for t in taus) + " | mean RMS |"
    lines = [head, "|" + "---|" * (len(taus) + 2)]
    for name, r in refs.items():
        cells = " | ".join(f"{r['success'][float(t)][0]:.3f} ± {r['success'][float(t)][1]:.3f}" for t in taus)
        lines.append(f"| {name} | {cells} | {r['rms'][0]:.3f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--draws", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    lib = load_library()
    refs = metrics.reference_baselines(lib, seed=args.seed, draws=args.draws)
    print(table(refs))
    wb = metrics.within_between(lib)
    for k, v in wb.items():
        print(f"{k:36s} mean RMS {v.mean():.3f}  (<= 0.35: {np.mean(v <= 0.35):.3f}, n={len(v)})")
    o = refs["oracle"]["success"][0.35][0]
    w = refs["wrong_intent_any_intensity"]["success"][0.35][0]
    print(f"targets at tau=0.35: oracle {o:.3f} (>= 0.85: {'yes' if o >= 0.85 else 'NO'}), "
          f"wrong intent {w:.3f} (<= 0.10: {'yes' if w <= 0.10 else 'NO'})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
