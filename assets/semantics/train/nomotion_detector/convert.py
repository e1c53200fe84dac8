"""Convert a detector-only writer's raw files to training rows, once: ``python assets/semantics/train/nomotion_detector/convert.py
assets/semantics/train/nomotion_detector/w7`` (a second argument names the output file instead of ``train.jsonl``: the
no-motion dev set's ``dev.jsonl``, ``assets/semantics/dev/nomotion``).

v3's conversion (``assets/semantics/bench/v3/split.py``'s ``rows``: ``nomotion_raw.jsonl`` and ``contrast_raw.jsonl``
to ``{"id", "text", "intent", "intensity", "style"}`` rows, and ``"rejected"`` for contrast texts), every text to
``train.jsonl``: nothing here is frozen, and nothing here is evaluated on.
"""

import json
import runpy
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":
    folder = Path(sys.argv[1])
    rows = runpy.run_path(str(HERE.parents[1] / "bench" / "v3" / "split.py"), run_name="v3_split")["rows"](folder)
    out = folder / (sys.argv[2] if len(sys.argv) > 2 else "train.jsonl")
    out.write_text("".join(json.dumps(r, ensure_ascii=False) + "\n" for r in rows))
    print(f"{len(rows)} texts to {out}")
