"""Ship the generator the training sweep chose: ``python -m experiments.ship [--dry-run]``.

Reads ``choice`` from results/sweep_training.json (``python -m experiments.sweep training``), trains
the default model (seed 0, the sweep's options and steps) into assets/checkpoints/tuple_spline_rf,
the 2-rectified flow of it into assets/checkpoints/tuple_spline_rf_reflow when the sweep found that it
serves few steps best, and writes assets/checkpoints/shipped.json, which ``jg.sample(..., steps=S)``
reads to pick the checkpoint for S. Prints every command it runs.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from experiments import train
from jgrounding.io import write_atomic

ROOT = Path(__file__).resolve().parent.parent
CKPT = Path("assets/checkpoints")
DEFAULT, REFLOW = "tuple_spline_rf", "tuple_spline_rf_reflow"


def commands(sweep: dict) -> tuple[list[list[str]], dict]:
    """(argv lists of ``experiments.train``, the shipped.json manifest) for the sweep's choice."""
    choice, cfg = sweep["choice"], sweep["choice"]["default"]["config"]
    options = [
        "--steps",
        str(sweep["steps"]),
        "--ema-decay",
        str(cfg["ema_decay"]),
        "--time-sampler",
        cfg["time_sampler"],
    ]
    default = [
        "--method",
        DEFAULT,
        "--seeds",
        "0",
        "--out",
        str(CKPT / DEFAULT),
        *options,
        "--condition-dropout",
        str(cfg["condition_dropout"]),
        "--guidance",
        str(choice["default"]["guidance"]),
    ]
    runs, manifest = [default], {"default": DEFAULT, "few_step": [], "chosen_by": "results/sweep_training.json"}
    reflow_steps = [int(s) for s, v in choice["few_step"].items() if v["run"].startswith("2-rectified")]
    if reflow_steps:
        runs.append(
            [
                "--method",
                DEFAULT,
                "--seeds",
                "0",
                "--out",
                str(CKPT / REFLOW),
                *options,
                "--reflow-from",
                str(CKPT / DEFAULT),
                "--reflow-pairs",
                str(sweep["reflow_pairs"]),
            ]
        )
        # the reflowed model serves every S up to the largest at which it won, unless the default won below it
        won = sorted(int(s) for s in choice["few_step"])
        top = 0
        for s in won:
            if s not in reflow_steps:
                break
            top = s
        if top:
            manifest["few_step"].append({"max_steps": top, "checkpoint": REFLOW})
    return runs, manifest


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--sweep", default="results/sweep_training.json")
    p.add_argument("--dry-run", action="store_true", help="print the commands and the manifest only")
    args = p.parse_args(argv)
    runs, manifest = commands(json.loads(Path(args.sweep).read_text()))
    for argv_ in runs:
        print("python -m experiments.train " + " ".join(argv_), flush=True)
        if not args.dry_run:
            train.main(argv_)
    print(json.dumps(manifest, indent=1))
    if not args.dry_run:
        write_atomic(CKPT / "shipped.json", json.dumps(manifest, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
