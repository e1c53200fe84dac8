"""Write the fifth blind writer's situation-only texts of issue #34 as the frozen bench, once:
``python assets/semantics/bench/s4/split.py`` (``... split.py <folder>``: the same for another folder's
``situation_raw.jsonl``, as s10's, s11's and s14's).

Reads ``situation_raw.jsonl`` (already in the evaluation format ``{"id", "text", "intent", "intensity", "style"}``)
and writes every text, in file order, to ``bench.jsonl``: this set has no training split. It was written after the
s3 bench had been read, to judge what changed after that read (the confidence threshold's situation budget) on
texts nothing was tuned on. Only ``python -m experiments.bench_semantics`` reads ``bench.jsonl``.
"""

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(here=HERE):
    rows = [json.loads(line) for line in (here / "situation_raw.jsonl").read_text().splitlines() if line.strip()]
    keys = ("id", "text", "intent", "intensity", "style")
    text = "".join(json.dumps({k: r[k] for k in keys}, ensure_ascii=False) + "\n" for r in rows)
    (here / "bench.jsonl").write_text(text)
    print(f"{len(rows)} texts: all to bench.jsonl (frozen)")


if __name__ == "__main__":  # another folder's raw file: python assets/semantics/bench/s4/split.py <folder>
    import sys

    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE)
