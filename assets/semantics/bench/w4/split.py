"""Split the w4 blind writer's texts of issue #34 once, deterministically: ``python assets/semantics/bench/w4/split.py``.

v3's conversion and rule (``assets/semantics/bench/v3/split.py``, run here on this folder with this folder's seed):
strata are the class for no-motion texts and the chosen intent for contrast texts, 40 % of each to the frozen
``bench.jsonl`` (read only by ``python -m experiments.bench_semantics``), the rest to ``train.jsonl``.
"""

import runpy
from pathlib import Path

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":
    runpy.run_path(str(HERE.parent / "v3" / "split.py"), run_name="v3_split")["main"](HERE, 20261206)
