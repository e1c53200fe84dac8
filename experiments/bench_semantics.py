"""Grounding accuracy and latency of the embedded reducer on the held-apart paraphrase set."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from jgrounding import semantics
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
    print(f"semantic reduction on {n} held-apart paraphrases ({len(INTENTS)} intents x {len(INTENSITIES)} intensities):")
    print(f"  intent top-1            {np.mean(intent_ok):.3f}   (goal >= 0.90)")
    print(f"  intensity exact         {np.mean(z_exact):.3f}")
    print(f"  intensity within one    {np.mean(z_near):.3f}   (goal >= 0.90)")
    print(f"  latency warm            {1e3 * np.median(times):.2f} ms median, {1e3 * np.mean(times):.2f} ms mean "
          f"(goal <= 15 ms); first call {first:.2f} s (weights + compile)")
    if confusions:
        print("  intent confusions: " + ", ".join(f"{k} x{v}" for k, v in sorted(confusions.items(), key=lambda kv: -kv[1])))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
