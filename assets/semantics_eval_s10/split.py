"""Write the s10 blind writer's situation-only texts of issue #34 as the frozen bench, once:
``python assets/semantics_eval_s10/split.py``.

The same rule as ``assets/semantics_eval_s4/split.py``, which it runs on this folder: every text of
``situation_raw.jsonl``, in file order, to ``bench.jsonl`` (no training split). Only
``python -m experiments.bench_semantics`` reads ``bench.jsonl``.
"""

import importlib.util
from pathlib import Path

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":
    spec = importlib.util.spec_from_file_location("s4_split", HERE.parent / "semantics_eval_s4" / "split.py")
    s4 = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(s4)
    s4.main(HERE)
