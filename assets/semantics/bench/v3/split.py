"""Split the blind-written texts of issue #34 once, deterministically: ``python assets/semantics/bench/v3/split.py``.

Reads ``nomotion_raw.jsonl`` (texts that call for no motion, by class) and ``contrast_raw.jsonl`` (a named
motion rejected, another chosen), writes them as ``all.jsonl`` in the evaluation format
(``{"id", "text", "intent", "intensity", "style"}``; ``intent`` ``"none"`` and ``intensity`` null for no
motion) and splits it: strata are the class for no-motion texts and the chosen intent for contrast texts, ids
sorted and shuffled with one ``random.Random(20261203)``; the first 40 % of each stratum (rounded) go to
``bench.jsonl``, the frozen part that only ``python -m experiments.bench_semantics`` reads, the rest to
``train.jsonl``, which training may read. Files keep the order of ``all.jsonl``.
"""

import json
import random
from pathlib import Path

HERE = Path(__file__).resolve().parent
BENCH_SHARE = 0.4


def rows(here=HERE):
    out = []
    for line in (here / "nomotion_raw.jsonl").read_text().splitlines():
        r = json.loads(line)
        out.append({"id": r["id"], "text": r["text"], "intent": "none", "intensity": None, "style": r["class"]})
    for line in (here / "contrast_raw.jsonl").read_text().splitlines():
        r = json.loads(line)
        out.append(
            {
                "id": r["id"],
                "text": r["text"],
                "intent": r["intent"],
                "intensity": r["intensity"],
                "style": "contrast",
                "rejected": r["rejected"],
            }
        )
    return out


def main(here=HERE, seed=20261203, bench_share=BENCH_SHARE):
    """Split ``here``'s raw files (another folder's too: assets/semantics/bench/w3/split.py) with ``seed``;
    ``bench_share``: the share of each stratum frozen (1.0: all of it, written as ``bench.jsonl`` alone)."""
    items = rows(here)
    strata = {}
    for r in items:
        strata.setdefault(r["style"] if r["intent"] == "none" else r["intent"], []).append(r["id"])
    rng = random.Random(seed)
    bench = set()
    for key in sorted(strata):
        ids = sorted(strata[key])
        rng.shuffle(ids)
        bench.update(ids[: round(bench_share * len(ids))])
    for name, keep in (("all", lambda r: True), ("bench", lambda r: r["id"] in bench), ("train", lambda r: r["id"] not in bench)):
        if name != "bench" and len(bench) == len(items):  # all frozen: bench.jsonl alone
            continue
        text = "".join(json.dumps(r, ensure_ascii=False) + "\n" for r in items if keep(r))
        # the training split goes to the training role's folder of the same name (assets/semantics/train/<set>/)
        out = here.parents[1] / "train" / here.name if name == "train" else here
        out.mkdir(exist_ok=True)
        (out / f"{name}.jsonl").write_text(text)
    print(f"{len(items)} texts: {len(bench)} bench (frozen), {len(items) - len(bench)} train")


if __name__ == "__main__":
    main()
