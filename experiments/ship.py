"""Train and ship the public model, chosen on the benchmark's distribution metrics: ``python -m experiments.ship``.

1. Trains the default model into assets/checkpoints/tuple_spline_rf: Tuple + Spline + RF (Table I sizes)
   with the options the training sweep chose (condition dropout for guidance, EMA), on every library pair
   (train and held out: the user's model; Table II keeps the paper's 192/64 protocol; the evaluation set
   is never trained on), for ``--steps``.
2. Trains its 2-rectified flow into assets/checkpoints/tuple_spline_rf_reflow, and MeanFlow and the shortcut
   model (issue #25; same options and data) into assets/checkpoints/tuple_spline_{meanflow,shortcut}: the
   few-step candidates.
3. For each step count S in ``--step-counts``, scores every (checkpoint, guidance w) candidate through
   ``jg.sample`` itself (default ``current``, K = 30 samples of each of the 64 tuples) on the evaluation
   set with :mod:`jgrounding.evaluation.distribution`, and picks the one with the best score (the mean of
   Prec@r, ModeCov, intent and intensity retrieval, among candidates whose multimodality ratio is in
   0.5-1.5), one guidance per checkpoint (:func:`assign`). The chosen guidance is recorded in each
   checkpoint; assets/checkpoints/shipped.json says which checkpoint serves which S, with the scores it was
   chosen on.

``--no-train`` re-runs only the choice on the checkpoints already there; ``--only NAME,...`` trains only those
checkpoints (e.g. the few-step ones) and then chooses among all. Prints every command it runs.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from experiments import train
from jgrounding.io import write_atomic

CKPT = Path("assets/checkpoints")
DEFAULT, REFLOW = "tuple_spline_rf", "tuple_spline_rf_reflow"
MEANFLOW, SHORTCUT = "tuple_spline_meanflow", "tuple_spline_shortcut"  # checkpoint = method name
CANDIDATES = (DEFAULT, REFLOW, MEANFLOW, SHORTCUT)
STEPS = 120_000
OPTIONS = ["--ema-decay", "0.9995", "--condition-dropout", "0.1", "--data", "all"]
GUIDANCE = (0.0, 0.25, 0.5, 1.0)
STEP_COUNTS = (1, 2, 4, 8, 50)
SCORE = ("prec_r", "mode_cov", "intent_ret", "intensity_ret")


def commands(steps: int, few_step_steps: int | None = None) -> dict[str, list[str]]:
    """``experiments.train`` argv of each shipped checkpoint, by checkpoint name (training order)."""
    common = ["--seeds", "0", "--steps", str(steps), *OPTIONS]
    few = ["--seeds", "0", "--steps", str(few_step_steps or steps), *OPTIONS]
    return {
        DEFAULT: ["--method", DEFAULT, *common, "--out", str(CKPT / DEFAULT)],
        REFLOW: [
            *["--method", DEFAULT, *common, "--out", str(CKPT / REFLOW)],
            *["--reflow-from", str(CKPT / DEFAULT), "--reflow-pairs", "64"],
        ],
        # logit-normal flow times, as the MeanFlow paper: 2 seeds x 8k steps gave Prec@r 0.64 / 0.88 / 0.91 at
        # S = 1 / 2 / 4 against 0.60 / 0.80 / 0.82 with uniform times
        MEANFLOW: ["--method", MEANFLOW, *few, "--time-sampler", "logit_normal", "--out", str(CKPT / MEANFLOW)],
        SHORTCUT: ["--method", SHORTCUT, *few, "--out", str(CKPT / SHORTCUT)],
    }


def _set_guidance(path: Path, w: float) -> None:
    meta_path = path / "meta.json"
    meta = json.loads(meta_path.read_text())
    meta.setdefault("sample", {})["guidance"] = float(w)
    write_atomic(meta_path, json.dumps(meta, indent=1) + "\n")


def evaluate(path: Path, w: float, steps: int, k: int = 30) -> dict:
    """Distribution metrics of ``path`` sampled with guidance ``w`` and ``steps`` through jg.sample."""
    import jax

    import jgrounding as jg
    from jgrounding.evaluation import distribution
    from jgrounding.policy import sampling

    _set_guidance(path, w)
    sampling.load.cache_clear()  # re-read the recorded guidance
    lib = jg.load_library()
    ho = lib.heldout
    u = jg.sample(jax.random.key(7), list(ho.intent), list(ho.intensity), num_samples=k, steps=steps, checkpoint=path)
    return distribution.score(u, ho.intent, ho.intensity, lib.evaluation, with_frechet=False).summary()


def assign(table: list[tuple], step_counts=STEP_COUNTS) -> tuple[dict, dict]:
    """Which (checkpoint, guidance) serves each S, with one guidance per checkpoint (it is recorded there).

    ``table``: ``(S, checkpoint, w, metrics, score)`` rows. The default serves the largest S with its best w
    (and every S beyond the listed ones). Then, for the smaller S in ascending order (the few-step settings
    first), the best-scoring row wins among the default at its fixed w and the other checkpoints at any w
    not yet fixed by a smaller S; the winner's w is then fixed. Returns ``({S: (checkpoint, w, metrics)},
    {checkpoint: w})``; a checkpoint that serves no S keeps its best w at the smallest S.
    """
    rows = {(s, n, w): (m, sc) for s, n, w, m, sc in table}
    top = max(step_counts)
    fixed = {DEFAULT: max((r for r in table if r[0] == top and r[1] == DEFAULT), key=lambda r: r[4])[2]}
    served = {top: (DEFAULT, fixed[DEFAULT], rows[(top, DEFAULT, fixed[DEFAULT])][0])}
    for s in sorted(step_counts)[:-1]:
        cands = [r for r in table if r[0] == s and fixed.get(r[1], r[2]) == r[2]]
        _, name, w, m, _ = max(cands, key=lambda r: r[4])
        fixed[name] = w
        served[s] = (name, w, m)
    for _, name, w, _, _ in sorted(table, key=lambda r: (r[0], -r[4])):
        fixed.setdefault(name, w)  # never chosen: its best w at the smallest S
    return served, fixed


def choose(step_counts=STEP_COUNTS, guidance=GUIDANCE) -> dict:
    table = []
    for s in step_counts:
        for name in (n for n in CANDIDATES if (CKPT / n / "meta.json").exists()):
            for w in guidance:
                m = evaluate(CKPT / name, w, s)
                ok = 0.5 <= m["mm_ratio"] <= 1.5
                score = float(np.mean([m[k] for k in SCORE])) if ok else -1.0
                table.append((s, name, w, m, score))
                print(
                    f"S={s:3d} {name:24s} w={w:.2f}: "
                    + ", ".join(f"{k} {m[k]:.3f}" for k in (*SCORE, "between", "mm_ratio"))
                    + f" -> score {score:.3f}",
                    flush=True,
                )
    served, fixed = assign(table, step_counts)
    for name, w in fixed.items():
        _set_guidance(CKPT / name, w)
    manifest = {"default": DEFAULT, "few_step": [], "chosen_by": "python -m experiments.ship", "scores": {}}
    for s in sorted(served):
        name, w, m = served[s]
        manifest["scores"][str(s)] = {"checkpoint": name, "guidance": w, **{k: round(v, 4) for k, v in m.items()}}
    # S' routes to the smallest listed max_steps >= S' (jgrounding.policy.sampling.shipped_checkpoint),
    # beyond the largest to the default; so every S below the largest is listed with its winner.
    if any(served[s][0] != DEFAULT for s in served):
        manifest["few_step"] = [{"max_steps": s, "checkpoint": served[s][0]} for s in sorted(served)[:-1]]
    manifest["candidates"] = [
        {"steps": s, "checkpoint": n, "guidance": w, "score": round(sc, 4), **{k: round(v, 4) for k, v in m.items()}}
        for s, n, w, m, sc in table
    ]
    return manifest


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--steps", type=int, default=STEPS, help="training steps of the default model and its reflow")
    p.add_argument("--few-step-steps", type=int, help="training steps of MeanFlow and the shortcut (default --steps)")
    p.add_argument("--no-train", action="store_true", help="only choose among the checkpoints already there")
    p.add_argument("--only", help=f"comma-separated checkpoints to train, of {','.join(CANDIDATES)} (default all)")
    p.add_argument("--dry-run", action="store_true", help="print the training commands only")
    args = p.parse_args(argv)
    only = CANDIDATES if args.only is None else tuple(args.only.split(","))
    if set(only) - set(CANDIDATES):
        p.error(f"--only: unknown checkpoint(s) {sorted(set(only) - set(CANDIDATES))}; valid: {', '.join(CANDIDATES)}")
    for name, argv_ in commands(args.steps, args.few_step_steps).items():
        if name not in only:
            continue
        print("python -m experiments.train " + " ".join(argv_), flush=True)
        if not (args.dry_run or args.no_train):
            train.main(argv_)
    if args.dry_run:
        return 0
    manifest = choose()
    print(json.dumps({k: v for k, v in manifest.items() if k != "candidates"}, indent=1))
    write_atomic(CKPT / "shipped.json", json.dumps(manifest, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
