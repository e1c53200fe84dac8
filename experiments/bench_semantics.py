"""Grounding accuracy and latency of the embedded reducer on the held-apart paraphrase set."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from jgrounding import semantics
from jgrounding.io import write_atomic
from jgrounding.vocabulary import INTENSITIES, INTENTS

DATA = Path(__file__).resolve().parent / "data" / "paraphrases.json"


def main(argv=None) -> int:
    items = json.loads(DATA.read_text())["items"]
    t0 = time.perf_counter()
    semantics.ground(items[0]["text"])
    first = time.perf_counter() - t0
    intent_ok, z_exact, z_near, times = [], [], [], []
    confusions = {}
    for it in items:
        t0 = time.perf_counter()
        g = semantics.ground(it["text"])
        times.append(time.perf_counter() - t0)
        intent_ok.append(g.intent == it["intent"])
        dz = abs(INTENSITIES.index(g.intensity) - INTENSITIES.index(it["intensity"]))
        z_exact.append(dz == 0)
        z_near.append(dz <= 1)
        if g.intent != it["intent"]:
            confusions[f"{it['intent']} -> {g.intent}"] = confusions.get(f"{it['intent']} -> {g.intent}", 0) + 1
    n = len(items)
    lines = [f"Semantic reduction (embedded backend) on {n} held-apart paraphrases "
             f"({len(INTENTS)} intents x {len(INTENSITIES)} intensities, experiments/data/paraphrases.json):", "",
             "| metric | measured | goal |", "|---|---|---|",
             f"| intent top-1 | {np.mean(intent_ok):.3f} | >= 0.90 |",
             f"| intensity exact | {np.mean(z_exact):.3f} | – |",
             f"| intensity within one level | {np.mean(z_near):.3f} | >= 0.90 |",
             f"| latency per response, warm | {1e3 * np.median(times):.2f} ms median, {1e3 * np.mean(times):.2f} ms mean "
             f"| <= 15 ms |",
             f"| first call (weights + compile) | {first:.2f} s | – |"]
    if confusions:
        lines += ["", "Intent confusions: " + ", ".join(
            f"{k} x{v}" for k, v in sorted(confusions.items(), key=lambda kv: -kv[1])) + "."]
    print("\n".join(lines))
    write_atomic(DATA.parent.parent.parent / "results" / "bench_semantics.md", "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
