"""Split the blind writer's situation-only and mixed texts of issue #34 once, deterministically:
``python assets/semantics/bench/s3/split.py``.

Reads ``situation_raw.jsonl`` and ``mixed_raw.jsonl`` (already in the evaluation format
``{"id", "text", "intent", "intensity", "style"}``), writes them as ``all.jsonl`` and splits it as v3 and w3 are
split: strata are (style, intent), ids sorted and shuffled with one ``random.Random(20261205)``; the first 40 % of
each stratum (rounded) go to ``bench.jsonl``, the frozen part that only ``python -m experiments.bench_semantics``
reads, the rest to ``train.jsonl``, which training may read. Files keep the order of ``all.jsonl``.
"""

import json
import random
from pathlib import Path

HERE = Path(__file__).resolve().parent
BENCH_SHARE = 0.4
SEED = 20261205


def rows(here=HERE):
    out = []
    for name in ("situation_raw.jsonl", "mixed_raw.jsonl"):
        for line in (here / name).read_text().splitlines():
            r = json.loads(line)
            out.append({k: r[k] for k in ("id", "text", "intent", "intensity", "style")})
    return out


def main(here=HERE, seed=SEED):
    items = rows(here)
    strata = {}
    for r in items:
        strata.setdefault((r["style"], r["intent"]), []).append(r["id"])
    rng = random.Random(seed)
    bench = set()
    for key in sorted(strata):
        ids = sorted(strata[key])
        rng.shuffle(ids)
        bench.update(ids[: round(BENCH_SHARE * len(ids))])
    for name, keep in (
        ("all", lambda r: True),
        ("bench", lambda r: r["id"] in bench),
        ("train", lambda r: r["id"] not in bench),
    ):
        text = "".join(json.dumps(r, ensure_ascii=False) + "\n" for r in items if keep(r))
        # the training split goes to the training role's folder of the same name (assets/semantics/train/<set>/)
        out = here.parents[1] / "train" / here.name if name == "train" else here
        out.mkdir(exist_ok=True)
        (out / f"{name}.jsonl").write_text(text)
    print(f"{len(items)} texts: {len(bench)} bench (frozen), {len(items) - len(bench)} train")


if __name__ == "__main__":
    main()
