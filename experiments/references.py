"""Brackets of the success metric, properties of the benchmark: ``python -m experiments.references``.

Expected values over the library (every replay in each pool, no sampling): oracle (a training
realization of the same tuple: the ceiling), tuple mean (what a deterministic regressor learns),
wrong intent (same intensity), far intensity (same intent, 2+ levels away), adjacent intensity, and
the share of held-out word 4-grams found in same-intent training responses. SPEC §3 ranges at
tau = 0.35 are checked and printed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from jgrounding import library, load_library
from jgrounding.evaluation import metrics
from jgrounding.io import write_atomic

RESULTS = Path(__file__).resolve().parent.parent / "results" / "references.md"

NAMES = {
    "oracle": "oracle (same-tuple replay)",
    "tuple_mean": "tuple mean (regressor ceiling)",
    "wrong_intent": "wrong intent, same intensity",
    "far_intensity": "same intent, 2+ intensity levels away",
    "adjacent_intensity": "same intent, adjacent intensity",
}


def table(b: dict, taus=metrics.TAUS) -> str:
    lines = ["| bracket | " + " | ".join(f"succ@{t:.2f}" for t in taus) + " |", "|" + "---|" * (len(taus) + 1)]
    for key, name in NAMES.items():
        lines.append(f"| {name} | " + " | ".join(f"{b[key][float(t)]:.3f}" for t in taus) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--library", default=None, help="library .npz (default: the shipped one)")
    p.add_argument("--write", action="store_true", help=f"also write {RESULTS.name} under results/ (for the README)")
    args = p.parse_args(argv)
    lib = load_library(args.library)
    b = library.brackets(lib, metrics.TAUS)
    lines = [table(b), ""]
    lines.append(
        f"- Held-out word 4-grams shared with same-intent training responses: {b['heldout_4gram_overlap']:.3f}."
    )
    mid = library.variant_midpoint(lib, metrics.TAUS)
    if mid:
        lines.append(
            f"- Beside the brackets, a hedge on the {mid['tuples']} one-to-many tuples (the midpoint of the two "
            "variants' training means): "
            + ", ".join(f"succ@{t:.2f} {v:.3f}" for t, v in mid["success"].items())
            + ". A generator that averages a gesture's variants can pass the one-sample success metric; diversity "
            "and coverage tell it apart from one that covers them."
        )
    bad = library.bracket_violations(b, metrics.TAU_RMS)
    lines.append(
        f"- Brackets at tau = {metrics.TAU_RMS}: " + ("all within the SPEC §3 ranges." if not bad else "; ".join(bad))
    )
    text = "\n".join(lines)
    print(text)
    if args.write:
        header = (
            f"Brackets of the success metric on `{Path(lib.path).name}` (library {lib.meta.get('library_version', '?')}), "
            "expected values over every replay (no sampling): `python -m experiments.references`."
        )
        write_atomic(RESULTS, header + "\n\n" + text + "\n")
        print(f"wrote {RESULTS}")
    return 0 if not bad else 1


if __name__ == "__main__":
    raise SystemExit(main())
