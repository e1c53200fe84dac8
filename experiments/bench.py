"""Benchmarks, one sub-command per stage: `python -m experiments.bench {trunk,sample,semantics,shard,fuzz,serve,all}`.

Each sub-command lives in its own module (`experiments/bench_<name>.py`) with a `main(argv)`;
every figure is printed beside its reference in the same run, as a ratio.
"""

from __future__ import annotations

import importlib
import sys

COMMANDS = ("trunk", "sample", "semantics", "shard", "fuzz", "serve")


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in COMMANDS + ("all",):
        print(f"usage: python -m experiments.bench {{{','.join(COMMANDS + ('all',))}}} [options]", file=sys.stderr)
        return 2
    names = COMMANDS if argv[0] == "all" else (argv[0],)
    for name in names:
        mod = importlib.import_module(f"experiments.bench_{name}")
        rc = mod.main(argv[1:])
        if rc:
            return rc
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
