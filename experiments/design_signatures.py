"""Refine the intents' tendon signatures into a code with large pairwise distance.

``python -m experiments.design_signatures`` starts from the semantic anchor table
(``jgrounding.primitives.ANCHORS``: what each behaviour pulls, and when) and runs a deterministic
projected gradient that pushes apart every pair of intents whose Catmull-Rom reconstructions are
closer than the target RMS at the subtle intensity, while keeping each anchor's defining pulls
(high anchors stay >= 0.6, anchors <= 0.2 stay <= 0.35). It prints the refined table, which is
stored as ``jgrounding.primitives.SIGNATURES``; ``--check`` verifies that the stored table is what
this script produces.
"""
from __future__ import annotations

import argparse

import numpy as np

from jgrounding import primitives as pr
from jgrounding import splines
from jgrounding.vocabulary import INTENTS


def refine(anchors: np.ndarray, target_subtle: float = 0.47, iters: int = 6000, lr: float = 0.01,
           lam: float = 0.3) -> np.ndarray:
    basis = splines._basis_np(150, 4)
    gram = basis.T @ basis / 150  # RMS^2 between splines = mean_j d_j^T G d_j / 4
    target = target_subtle / pr.INTENSITY_SCALE[0]
    lo = np.where(anchors >= 0.6, 0.6, 0.02)
    hi = np.where(anchors <= 0.2, 0.35, 0.97)
    s = anchors.copy()
    off = ~np.eye(len(anchors), dtype=bool)
    for _ in range(iters):
        diff = s[:, None] - s[None]  # (16, 16, 4, P)
        d = np.sqrt(np.einsum("abjp,pq,abjq->ab", diff, gram, diff) / 4 + 1e-9)
        viol = np.where(off, np.maximum(target - d, 0.0), 0.0)
        coef = -2.0 * viol / d / 4.0
        grad = 2.0 * np.einsum("ab,pq,abjq->ajp", coef, gram, diff) + lam * (s - anchors)
        s = np.clip(s - lr * grad, lo, hi)
    return np.round(s, 2)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--check", action="store_true", help="exit 1 unless primitives.SIGNATURES matches")
    args = p.parse_args(argv)
    refined = refine(pr.ANCHORS)
    if args.check:
        ok = np.allclose(refined, pr.SIGNATURES, atol=0.011)
        print("SIGNATURES match the refinement" if ok else "SIGNATURES differ from the refinement")
        return 0 if ok else 1
    print("SIGNATURES = {")
    for m, name in enumerate(INTENTS):
        rows = ", ".join("[" + ", ".join(f"{v:.2f}" for v in row) + "]" for row in refined[m])
        print(f'    "{name}": ({rows}),')
    print("}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
