"""Write the w5 blind writer's texts of issue #34 as the frozen bench, once: ``python assets/semantics_eval_w5/split.py``.

v3's conversion (``assets/semantics_eval_v3/split.py``, run here on this folder) with all of each stratum frozen:
every text to ``all.jsonl`` and ``bench.jsonl`` (read only by ``python -m experiments.bench_semantics``); there is
no training split.
"""

import runpy
from pathlib import Path

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":
    runpy.run_path(str(HERE.parent / "semantics_eval_v3" / "split.py"), run_name="v3_split")["main"](
        HERE, 20261207, bench_share=1.0
    )
