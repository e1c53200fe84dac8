"""Reference rows and brackets of the benchmark: ``python -m experiments.references [--write]``.

Benchmark v3 first: the reference rows (fresh replay = a perfect generator, variant midpoint = hedge, one
variant only = collapse, tuple mean, another intent, adjacent intensity) scored by the same code as the
methods (:mod:`jgrounding.evaluation.distribution`) against the library's evaluation set, and the brackets
they must satisfy before any method is ranked (exit 1 if one fails).

Then the brackets of the paper-protocol success metric (Succ@tau of one sample against the held-out
realization), kept for comparison with the paper and earlier library versions:

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
from jgrounding.evaluation import distribution, metrics
from jgrounding.io import write_atomic
from jgrounding.library import designs

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


def distribution_table(scores: dict) -> str:
    cols = distribution.HEADLINE
    lines = [
        "| reference row | " + " | ".join(distribution.LABELS[c] for c in cols) + " | Prec@r (split tuples) |",
        "|" + "---|" * (len(cols) + 2),
    ]
    for name, s in scores.items():
        lines.append(
            f"| {distribution.REFERENCES[name]} | "
            + " | ".join(f"{s.mean(c):.3f}" for c in cols)
            + f" | {s.mean('prec_r', split_only=True):.3f} |"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--library", default=None, help="library .npz (default: the shipped one)")
    p.add_argument("--write", action="store_true", help=f"also write {RESULTS.name} under results/ (for the README)")
    args = p.parse_args(argv)
    samples_per_tuple = 30
    lib = load_library(args.library)
    lines = []
    failures = []
    if lib.evaluation is not None:
        scores = distribution.reference_scores(lib, k=samples_per_tuple)
        r = next(iter(scores.values())).r
        failures = distribution.bracket_failures(scores)
        lines += [
            f"Reference rows of benchmark v3: K = {samples_per_tuple} samples of each of the 64 tuples against the evaluation set "
            f"({len(lib.evaluation)} realizations, 16 per tuple, never trained on); r = {r:.4f}, tau = "
            f"{metrics.TAU_RMS}.",
            "",
            distribution_table(scores),
            "",
            "- Brackets asserted before any method is ranked: "
            + "; ".join(
                f"{name}: " + ", ".join(f"{m} in [{lo}, {hi}]" for m, (lo, hi) in want.items())
                for name, want in distribution.BRACKETS.items()
            )
            + (". All hold." if not failures else ". FAILED: " + "; ".join(failures)),
            "- Prec@τ cannot rank them: the hedge and the adjacent intensity score "
            f"{scores['hedge'].mean('prec_tau'):.3f} and {scores['adjacent_intensity'].mean('prec_tau'):.3f}, like "
            f"the perfect replay ({scores['fresh_replay'].mean('prec_tau'):.3f}).",
            "",
            "Paper protocol (one sample against the held-out realization), expected success over every replay:",
            "",
        ]
    b = library.brackets(lib, metrics.TAUS)
    lines += [table(b), ""]
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
        f"- Paper-protocol brackets at tau = {metrics.TAU_RMS}: "
        + ("all within the SPEC §3 ranges." if not bad else "outside the SPEC §3 ranges: " + "; ".join(bad))
        + (
            (
                ". Library v3 starts every realization from rest and makes subtle motions small, so different intents "
                "and far intensities come within tau of each other; the one-sample metric no longer separates them, "
                "and the distribution metrics above carry the ranking."
                if designs.of_library(lib).version == 3
                else f". At tau = 0.45 wrong intent is {b['wrong_intent'][0.45]:.3f} (SPEC: <= 0.20). In a few split "
                f"tuples of library v{designs.of_library(lib).version} the mean of the training realizations lies "
                "within tau of the held-out one, so the tuple mean's gap to the oracle stays short of 0.10; the "
                "distribution metrics above separate it."
            )
            if bad and lib.evaluation is not None
            else ""
        )
    )
    text = "\n".join(lines)
    print(text)
    if args.write:
        header = (
            f"Reference rows and brackets on `{Path(lib.path).name}` (library {lib.meta.get('library_version', '?')}): "
            "`python -m experiments.references --write`."
        )
        write_atomic(RESULTS, header + "\n\n" + text + "\n")
        print(f"wrote {RESULTS}")
    return 0 if not failures else 1


if __name__ == "__main__":
    raise SystemExit(main())
