"""Split the third blind writer's texts of issue #34 once, deterministically: ``python assets/semantics/bench/w3/split.py``.

The same conversion and rule as ``assets/semantics/bench/v3/split.py``, which it runs on this folder (strata: the
class for no-motion texts, the chosen intent for contrast texts; ids sorted and shuffled with one seeded
``random.Random``; the first 40 % of each stratum to ``bench.jsonl``, the rest to ``train.jsonl``), with this
folder's own seed. ``bench.jsonl`` is frozen: only ``python -m experiments.bench_semantics`` reads it.
"""

import importlib.util
from pathlib import Path

HERE = Path(__file__).resolve().parent
SEED = 20261204

if __name__ == "__main__":
    spec = importlib.util.spec_from_file_location("v3_split", HERE.parent / "v3" / "split.py")
    v3 = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(v3)
    v3.main(HERE, SEED)
