"""Train, compare, select and calibrate the semantic head; write ``jgrounding/assets/semantic_head.npz``.

    python -m tools.semantics_corpus      # regenerate assets/semantics/train/corpora/generated.jsonl
    python -m tools.train_semantics       # train on assets/semantics/train/corpora/*.jsonl, select/calibrate on dev

Training data: every ``assets/semantics/train/corpora/*.jsonl`` (the independently written corpora and our generated
one; all disjoint from the evaluation sets, tests/semantics/test_training_data.py) and the blind writers'
training texts (:data:`tools.semantics_data.BLIND_TRAIN`: contrast texts and texts that call for no motion, in nine kinds,
situation-only and mixed texts; their frozen ``bench.jsonl`` is read only by ``python -m experiments.bench
semantics``; ``--no-blind`` leaves them out). Rows with intent ``"none"`` teach the
no-behaviour class; their
``style`` (addressee, quoted, system, ...) teaches the reason head that says why a text calls for no motion.

Options (:data:`tools.semantics_training.OPTIONS`) are compared on the dev splits: ``assets/semantics/dev/v2/dev.jsonl`` (the styles
real reasoners write, with no-behaviour texts), ``assets/semantics/dev/plain/dev.jsonl`` (plainly worded) and the blind
situation hold-outs (:data:`tools.semantics_data.SITUATION_DEVS`: two writers; v2 dev holds 29 situations). Each
option's softmax temperature is fitted on v2 dev and the situation hold-outs together (NLL over the 17 classes), so
are its intensity cut points (NLL of the motion texts' intensities, :func:`tools.semantics_calibration.fit_cut_points`), then its confidence
threshold:
the lowest at which the confident wrong motions on v2 dev (acted on with the wrong intent, or acted on a
no-behaviour text) stay within ``TARGET_WRONG`` and those on the situation hold-outs (pooled) within ``SITUATION_TARGET_WRONG``. The option with the best dev score (:func:`tools.semantics_calibration.dev_score`) is
shipped (:func:`tools.semantics_calibration.ship_choice`: of the options within
:data:`tools.semantics_calibration.SHIP_MARGIN` of the best, the fewest encoder layers). The
test splits are never read here. Deterministic: fixed keys and seeded minibatch order. Frozen encoder features are
cached in ``.cache/semantics/`` (keyed by the texts and the encoder and span code), so re-runs skip the encoder; the
"tuned" option (top encoder layers trained with the head) takes about 10 minutes on 2 cores, the "student" (its
encoder distilled into three layers, then trained with a new head) about 20 more, each further student sharing
that distillation about 5; all are cached (:func:`tools.semantics_training.cached_finetune`, :func:`tools.semantics_training.cached_distill`), so
the default ``--options tuned,student-sit,student-sit-z`` (what ships now) takes about 50 minutes the first time.
A new head makes the nearest-neighbour table (``jgrounding/assets/semantic_knn.npz``) stale: it is ignored until
``python -m tools.semantics_knn --write`` rebuilds it for the new head; so is the learned no-motion detector
(``jgrounding/assets/nomotion_detector.npz``, which reads the head's sentence vectors) until
``python -m tools.train_nomotion`` retrains it.

The job is split by module: the sets and the rows' labels (:mod:`tools.semantics_data`), training the options
(:mod:`tools.semantics_training`), their calibration and the ship rule (:mod:`tools.semantics_calibration`); this
module compares the options and writes the head.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
from pathlib import Path

from jgrounding.semantics import encoder, features
from jgrounding.semantics import head as sh
from tools.semantics_calibration import (
    SITUATION_TARGET_WRONG,
    TARGET_WRONG,
    calibrate,
    print_option,
    probs,
    recalibrate,
    selective,
    ship_choice,
)
from tools.semantics_data import (
    BLIND_TRAIN,
    DEV,
    DEV_PLAIN,
    REASON_TEXT,
    ROOT,
    SITUATION_DEVS,
    TRAIN_DIR,
    load_train,
    read_jsonl,
    read_situations,
    reason_classes,
    train_files,
)
from tools.semantics_training import OPTIONS, cached_finetune, cached_structure_features, fit, inputs

# The options a default run compares: those of the run that made the shipped head (the others stay available, and
# results/semantics_dev_options.json keeps only the options of the last run).
DEFAULT_OPTIONS = ("tuned", "student-sit", "student-sit-z")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--dev", default=str(DEV))
    p.add_argument("--dev-plain", default=str(DEV_PLAIN))
    p.add_argument(
        "--situations",
        default=",".join(str(x) for x in SITUATION_DEVS),
        help="situation-only hold-outs, comma-separated: calibration, threshold and one term of the ship score "
        "('' leaves them out)",
    )
    p.add_argument(
        "--recalibrate",
        action="store_true",
        help="train nothing: fit the calibration of the head at --out again (its trained cut points, temperature, "
        "threshold) on the dev splits and --situations, and write it back",
    )
    p.add_argument("--out", default=str(sh.ASSET))
    p.add_argument("--train-dir", default=str(TRAIN_DIR), help="folder of the training *.jsonl files")
    p.add_argument("--no-blind", action="store_true", help="leave out the blind writers' training splits (BLIND_TRAIN)")
    p.add_argument(
        "--options",
        default=",".join(DEFAULT_OPTIONS),
        help=f"options to compare (default: {','.join(DEFAULT_OPTIONS)}, the run that made the shipped head; "
        f"all: {', '.join(OPTIONS)})",
    )
    p.add_argument("--report", default=str(ROOT / "results" / "semantics_dev_options.json"))
    args = p.parse_args(argv)
    chosen = args.options.split(",")
    bad = [o for o in chosen if o not in OPTIONS]
    if bad:
        raise SystemExit(f"unknown option(s) {bad}; valid options: {', '.join(OPTIONS)}")
    blind = () if args.no_blind else BLIND_TRAIN
    rows, row_weight = load_train(args.train_dir, blind)
    dev = read_jsonl(args.dev) if Path(args.dev).exists() else []
    plain = read_jsonl(args.dev_plain)
    if not dev:
        print(f"{args.dev} missing: selecting and calibrating on {args.dev_plain} alone")
        dev = plain
    sit_paths = [Path(x) for x in args.situations.split(",") if x]
    sit = read_situations(sit_paths)
    situation_files = {x.name: hashlib.sha256(x.read_bytes()).hexdigest()[:16] for x in sit_paths}
    if args.recalibrate:
        return recalibrate(Path(args.out), dev, plain, sit, situation_files)
    reasons = reason_classes(rows)
    weights = {name: w for name, (_, w) in train_files(args.train_dir, blind).items()}
    print(f"train: {len(rows)} rows; dev: {len(dev)} + plain {len(plain)} rows; file weights {weights}")
    print(f"no-behaviour reasons: {reasons}")
    texts = [r["text"] for r in rows]
    if any(OPTIONS[o]["inputs"] != "tuned" for o in chosen):  # the frozen encoder's features (cached)
        xs = cached_structure_features(texts)
        xs_dev = cached_structure_features([r["text"] for r in dev])
        xs_plain = cached_structure_features([r["text"] for r in plain])
        xs_sit = cached_structure_features([r["text"] for r in sit]) if sit else None
    results = {}
    for name in chosen:
        opt = OPTIONS[name]
        deltas = None
        if opt["inputs"] == "tuned":
            student = bool(opt.get("encoder_layers"))  # an encoder of fewer layers: distilled from "tuned"
            if student and "tuned" not in results:
                raise SystemExit(f"the {name} option distils the tuned option's encoder: --options tuned,{name}")
            teacher = None
            if student:  # the tuned option's trained encoder, in float32
                t = results["tuned"]
                teacher = dict(encoder.load_numpy(), layers=sh.merged_layers(t["_deltas"], t["_cfg"]))
            params, deltas, cfg = cached_finetune(name, rows, row_weight, reasons, teacher)
            # Dev features through the shipped path: the float16 deltas on the frozen encoder, as ground() reads them.
            tuned = sh.Head(params, cfg, 1.0, 0.5, {}, sh.with_top(deltas, cfg))
            xd = features.head_inputs(tuned, [r["text"] for r in dev])
            xp = features.head_inputs(tuned, [r["text"] for r in plain])
            xsit = features.head_inputs(tuned, [r["text"] for r in sit]) if sit else None
        else:
            xd = inputs(opt["inputs"], xs_dev, [r["text"] for r in dev])
            xp = inputs(opt["inputs"], xs_plain, [r["text"] for r in plain])
            xsit = inputs(opt["inputs"], xs_sit, [r["text"] for r in sit]) if sit else None
            params, cfg = fit(inputs(opt["inputs"], xs, texts), rows, row_weight, reasons=reasons, **opt)
        results[name] = dict(
            option=opt, **calibrate(params, (xd, dev), (xp, plain), (xsit, sit)), _cfg=cfg, _deltas=deltas
        )
        print_option(name, results[name])
    best = ship_choice({k: (v["score"], v["_cfg"]) for k, v in results.items()})
    b = results[best]
    digests = {
        name: hashlib.sha256(path.read_bytes()).hexdigest()[:16]
        for name, (path, _) in train_files(args.train_dir, blind).items()
    }
    comparison = {k: {kk: vv for kk, vv in v.items() if not kk.startswith("_")} for k, v in results.items()}
    meta = {
        "temperature": b["temperature"],
        "threshold": b["threshold"],
        "cut_points": b["cut_points"],
        "selected": best,
        "option": b["option"],
        "reasons": reasons,
        "reason_text": {k: REASON_TEXT.get(k, k.replace("-", " ")) for k in reasons},
        "train_files": digests,
        "file_weights": weights,
        "dev_file": hashlib.sha256(Path(args.dev).read_bytes()).hexdigest()[:16] if Path(args.dev).exists() else "",
        "situation_files": situation_files,
        "dev": b["dev"],
        "dev_plain": b["dev_plain"],
        "dev_ece": b["dev"]["ece"],
        "dev_ece_uncalibrated": selective(*probs(b["_params"], b["_xd"]), dev, b["threshold"])["ece"],
        "target_wrong": TARGET_WRONG,
        "situation_target_wrong": SITUATION_TARGET_WRONG,
        "config": dataclasses.asdict(b["_cfg"]),
        "params_digest": sh.digest(b["_params"]),
        "comparison": comparison,
    }
    sh.save(args.out, b["_params"], b["_cfg"], meta, b["_deltas"])
    if args.report:
        from jgrounding.io import write_atomic

        write_atomic(args.report, json.dumps(comparison, indent=1, sort_keys=True) + "\n")
    print(f"selected {best}; temperature {b['temperature']:.2f}; threshold {b['threshold']:.3f}")
    print(f"wrote {args.out} (params {meta['params_digest']})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
