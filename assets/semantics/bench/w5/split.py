"""Write the w5 blind writer's texts of issue #34 as the frozen bench, once: ``python assets/semantics/bench/w5/split.py``
(``... split.py <folder>``: the same for another folder's raw files, as w6's).

v3's conversion (``assets/semantics/bench/v3/split.py``, run here on this folder) with all of each stratum frozen:
every text to ``bench.jsonl`` (read only by ``python -m experiments.bench_semantics``); there is no training split,
so the seed shuffles nothing that matters.
"""

import runpy
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE
    runpy.run_path(str(HERE.parent / "v3" / "split.py"), run_name="v3_split")["main"](
        folder, 20261207, bench_share=1.0
    )
