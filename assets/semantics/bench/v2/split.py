#!/usr/bin/env python3
"""Deterministic 25% dev / 75% test split of all.jsonl.

Strata: (intent, intensity) for motion items, style for "none" items.
Within each stratum (strata in sorted order, items sorted by id) the items are
shuffled with one shared random.Random(20261201); the first round(0.25 * n)
go to dev (assets/semantics/dev/v2/), the rest to test. Output files keep the order of all.jsonl.
"""
import json
import random
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
SEED = 20261201
DEV_FRACTION = 0.25


def stratum(item):
    if item["intent"] == "none":
        return ("none", item["style"])
    return (item["intent"], item["intensity"])


def main():
    items = [json.loads(l) for l in (HERE / "all.jsonl").read_text(encoding="utf-8").splitlines() if l.strip()]
    groups = defaultdict(list)
    for it in items:
        groups[stratum(it)].append(it["id"])
    rng = random.Random(SEED)
    dev_ids = set()
    for key in sorted(groups):
        ids = sorted(groups[key])
        rng.shuffle(ids)
        dev_ids.update(ids[: round(DEV_FRACTION * len(ids))])
    with open(HERE.parents[1] / "dev" / HERE.name / "dev.jsonl", "w", encoding="utf-8") as fd, open(HERE / "test.jsonl", "w", encoding="utf-8") as ft:
        for it in items:
            (fd if it["id"] in dev_ids else ft).write(json.dumps(it, ensure_ascii=False) + "\n")
    print(f"dev={len(dev_ids)} test={len(items) - len(dev_ids)}")


if __name__ == "__main__":
    main()
