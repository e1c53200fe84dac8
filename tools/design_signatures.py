"""Design the library's code: per intent, variant and intensity end, the tendon key poses.

``python -m tools.design_signatures`` starts from the semantic anchors of
:mod:`jgrounding.library.primitives` (what each behaviour pulls and when: ``ANCHORS``; the intensity rule
``subtle_anchor`` / ``emphatic_anchor``; the variants ``VARIANTS``) and runs a deterministic projected
gradient that pushes apart, in RMS of the Catmull-Rom reconstructions,

- every two intents at the same intensity (all variants): ``T_INTENT``;
- the two variants of a one-to-many intent at every intensity: ``T_VARIANT`` (weighted up: the
  2 + 2 split only defeats the tuple mean when the variants are >= ~0.55 apart);
- one intent's intensity levels two or more apart: ``T_FAR``; adjacent: ``T_ADJACENT``,

while keeping what screening and the kinematic signatures check (the intents that go away from the user
keep the toward-user tendon <= 0.15, the ones that lean in without touching <= 0.7). Library v3 pins the
first key pose of every code to the rest command and the last one of the gestures that return
(``primitives.RETURNS``) to rest as well, so every realization starts from rest as a recording does.
Intensity levels are the points 0, 1/3, 2/3, 1 of the segment from a variant's subtle end to its
emphatic end. ``--write`` stores the result in ``jgrounding/assets/designs/code_v3.json`` (:mod:`jgrounding.library.code_words`); ``--check`` verifies
that the stored code is what this script produces (rounded to 0.01).
"""

from __future__ import annotations

import argparse

import numpy as np

from jgrounding.actuation import splines
from jgrounding.io import write_atomic
from jgrounding.library import code_words
from jgrounding.library import primitives as pr

T_INTENT, T_VARIANT, T_FAR, T_ADJACENT = 0.6, 0.8, 0.8, 0.4
VARIANT_WEIGHT = 4.0
TRUST = 0.4  # how far refinement may move a key pose from its anchor
LEVELS = np.arange(4) / 3.0


def _targets(split):
    idx = [(m, v, z) for m in range(len(split)) for v in range(2) for z in range(4) if v == 0 or split[m]]
    n = len(idx)
    target, weight = np.zeros((n, n)), np.ones((n, n))
    for a, (m, v, z) in enumerate(idx):
        for b, (k, w, y) in enumerate(idx):
            if a == b:
                continue
            if m != k:
                target[a, b] = T_INTENT if z == y else 0.0
            elif v == w:
                target[a, b] = T_FAR if abs(z - y) >= 2 else T_ADJACENT
            else:
                target[a, b] = T_VARIANT if z == y else 0.8 * T_VARIANT
                weight[a, b] = VARIANT_WEIGHT
    return idx, target, weight


def refine(
    anchors: np.ndarray, split: np.ndarray, iters: int = 3000, lr: float = 0.02, lam: float = 0.05
) -> np.ndarray:
    """``anchors (16, 2 variants, 2 ends, 4, 4)`` -> the refined code, same shape, rounded to 0.01."""
    basis = splines.basis_np(150, 4)
    gram = basis.T @ basis / 150  # RMS^2 between splines = sum_j d_j^T G d_j / 4
    idx, target, weight = _targets(split)
    mi, vi, zi = (np.array(x) for x in zip(*idx))
    lo = np.clip(anchors - TRUST, 0.0, 0.97)  # a code stays near its anchor: the gesture as written
    hi = np.clip(anchors + TRUST, 0.0, 0.97)
    hi[pr.REACH == 2, :, :, 0] = np.minimum(hi[pr.REACH == 2, :, :, 0], 0.15)  # away intents never lean in
    hi[pr.NO_CONTACT, :, :, 0] = np.minimum(hi[pr.NO_CONTACT, :, :, 0], 0.7)  # lean in, never touch
    lo[..., 0] = hi[..., 0] = pr.REST  # every realization starts from rest
    lo[pr.RETURNS_MASK, ..., -1] = hi[pr.RETURNS_MASK, ..., -1] = pr.REST  # oscillations come back to rest
    code = anchors.copy()
    for _ in range(iters):
        s = LEVELS[zi][:, None, None]
        x = (1 - s) * code[mi, vi, 0] + s * code[mi, vi, 1]  # (n, 4, 4)
        diff = x[:, None] - x[None]
        gdiff = diff @ gram  # (n, n, 4, 4): the Gram matrix is symmetric, so this serves both sums below
        d = np.sqrt((diff * gdiff).sum(axis=(2, 3)) / 4 + 1e-12)
        coef = -weight * np.maximum(target - d, 0.0) / d / 2.0
        gx = 2.0 * (coef[:, None, :] @ gdiff.reshape(len(idx), len(idx), -1)).reshape(x.shape)  # sum over b
        grad = np.zeros_like(code)
        np.add.at(grad, (mi, vi, 0), (1 - s) * gx)
        np.add.at(grad, (mi, vi, 1), s * gx)
        code = np.clip(code - lr * (grad + lam * (code - anchors)), lo, hi)
    return np.round(code, 2)


def design() -> np.ndarray:
    return refine(pr.design_anchors(), pr.SPLIT)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--check", action="store_true", help="exit 1 unless the stored code (code_words.path) matches")
    p.add_argument("--write", action="store_true", help="write jgrounding/assets/designs/code_v3.json")
    args = p.parse_args(argv)
    code = design()
    if args.check:
        ok = np.allclose(code, pr.CODE, atol=0.011)
        print("CODE matches the design" if ok else "CODE differs from the design")
        return 0 if ok else 1
    text = code_words.render(3, code)
    if args.write:
        write_atomic(code_words.path(3), text)
        print(f"wrote {code_words.path(3)}")
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
