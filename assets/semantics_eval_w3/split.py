"""Split the third blind writer's texts of issue #34 once, deterministically: ``python assets/semantics_eval_w3/split.py``.

The same conversion and rule as ``assets/semantics_eval_v3/split.py`` (strata: the class for no-motion texts, the
chosen intent for contrast texts; ids sorted and shuffled with one seeded ``random.Random``; the first 40 % of each
stratum to ``bench.jsonl``, the rest to ``train.jsonl``), with this folder's own seed. ``bench.jsonl`` is frozen:
only ``python -m experiments.bench_semantics`` reads it.
"""

import json
import random
from pathlib import Path

HERE = Path(__file__).resolve().parent
BENCH_SHARE = 0.4
SEED = 20261204


def rows():
    out = []
    for line in (HERE / "nomotion_raw.jsonl").read_text().splitlines():
        r = json.loads(line)
        out.append({"id": r["id"], "text": r["text"], "intent": "none", "intensity": None, "style": r["class"]})
    for line in (HERE / "contrast_raw.jsonl").read_text().splitlines():
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


def main():
    items = rows()
    strata = {}
    for r in items:
        strata.setdefault(r["style"] if r["intent"] == "none" else r["intent"], []).append(r["id"])
    rng = random.Random(SEED)
    bench = set()
    for key in sorted(strata):
        ids = sorted(strata[key])
        rng.shuffle(ids)
        bench.update(ids[: round(BENCH_SHARE * len(ids))])
    parts = (("all", lambda r: True), ("bench", lambda r: r["id"] in bench), ("train", lambda r: r["id"] not in bench))
    for name, keep in parts:
        text = "".join(json.dumps(r, ensure_ascii=False) + "\n" for r in items if keep(r))
        (HERE / f"{name}.jsonl").write_text(text)
    print(f"{len(items)} texts: {len(bench)} bench (frozen), {len(items) - len(bench)} train")


if __name__ == "__main__":
    main()
