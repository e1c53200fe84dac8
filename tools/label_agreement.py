"""How well a second reader agrees with the writer on the situation hold-out: the reference the situation goals of
the semantic bench are read against.

    python -m tools.label_agreement           # the two readers
    python -m tools.label_agreement --head    # and the shipped head (jg.ground_many) against each reader

The hold-out (``assets/semantics/dev/situations_blind/situations.jsonl``, the ship rule's situation term) was labelled by its
writer. A second reader, a helper given only ``docs/semantics_second_reader_brief.md`` (the vocabulary of the
writers' brief) and the 256 texts shuffled under new ids, labelled each text again
(``assets/semantics/dev/situations_blind/second_reader.jsonl``). Situation-only texts imply their intensity, so how often
two readers give the same one says how much of the intensity goal (exact >= 0.80) the labels themselves allow.
The head's rows are optimistic: the hold-out is a dev set, read by the ship score and the threshold's fit.
"""

from __future__ import annotations

import argparse

from jgrounding.vocabulary import INTENSITIES
from tools import semantic_sets
from tools.semantics_data import SITUATION_DEV, read_jsonl

WRITER = SITUATION_DEV  # the hold-out as its writer labelled it
SECOND = semantic_sets.path("dev/situations_blind", "second_reader.jsonl")


def read_labels(path) -> dict[str, tuple[str, str]]:
    """``{id: (intent, intensity)}`` of a JSON Lines file."""
    return {r["id"]: (r["intent"], r["intensity"]) for r in read_jsonl(path)}


def agreement(a: dict, b: dict) -> dict:
    """Intent agreement, intensity exact and within one level, and both, of two labellings with the same ids."""
    if set(a) != set(b):
        raise ValueError(f"the labellings cover different ids: {sorted(set(a) ^ set(b))[:5]}")
    n = len(a)
    intent = sum(a[k][0] == b[k][0] for k in a)
    level = {k: abs(INTENSITIES.index(a[k][1]) - INTENSITIES.index(b[k][1])) for k in a}
    exact = sum(d == 0 for d in level.values())
    within = sum(d <= 1 for d in level.values())
    both = sum(a[k][0] == b[k][0] and level[k] == 0 for k in a)
    return {"n": n, "intent": intent / n, "intensity_exact": exact / n, "within_one": within / n, "both": both / n}


def head_labels() -> dict[str, tuple[str, str]]:
    """The shipped head's tuple for every hold-out text (``jg.ground_many``, acted on or not)."""
    import jgrounding as jg

    rows = read_jsonl(WRITER)
    out = jg.ground_many([r["text"] for r in rows])
    return {r["id"]: (g.intent, g.intensity) for r, g in zip(rows, out)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--head", action="store_true", help="also the shipped head against each reader")
    args = p.parse_args(argv)
    writer, second = read_labels(WRITER), read_labels(SECOND)
    pairs = [("second reader vs writer", second, writer)]
    if args.head:
        head = head_labels()
        pairs += [("shipped head vs writer", head, writer), ("shipped head vs second reader", head, second)]
    print("| situation hold-out (256 texts) | intent | intensity exact | within one | both |")
    print("|---|---|---|---|---|")
    for name, a, b in pairs:
        r = agreement(a, b)
        print(f"| {name} | {r['intent']:.3f} | {r['intensity_exact']:.3f} | {r['within_one']:.3f} | {r['both']:.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
