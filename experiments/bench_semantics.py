"""Selective semantic grounding on the frozen evaluation sets: `python -m experiments.bench semantics`.

Reads the sets of role ``bench`` of ``assets/semantics/sets.toml`` only here (never tuned on): the test splits
(:data:`SPLITS`: v2's five styles of motion texts and eight kinds of texts that call for no motion, and the plainly
worded one) and the frozen blind benches (:data:`BENCH_V3`: no-motion and contrast texts, v3, w3, w4, w5, w6, w9 and
w10, and situation-only texts, s3 with mixed texts, s4, s10, s11, s14, s22 and s23, each written by writers who saw no
code, corpus or evaluation set); this script is the only reader of those files. Each
blind bench is grounded once per reducer, outside the timing, with one more row: ``new, no rule``, the shipped head without
the explicit no-motion decision (:mod:`jgrounding.semantics.nomotion`: the rule and the learned detector), so the
decision's effect is read off one run; the ``new`` rows count the texts the rule held and those the detector held.
Three reducers run in the same process, each text grounded alone, warm (``semantics.warmup``: every token
bucket compiled before timing):

- ``new``: the shipped trained head (``jg.ground(text)``, its defaults; no MLLM endpoint may be configured);
- ``old``: the first trained head (the set ``bench/head_v1``: the sentence embedding + Eq. (3) head);
- ``cues``: the cue-list reducer (``backend="cues"``), the baseline.

Per style and overall: intent accuracy on motion texts, the share of motion texts acted on (confident), the
confident wrong motion rate (acted on with the wrong intent, share of motion texts), the share of no-behaviour
texts held (not acted on; the rest are motions where none was asked), intensity exact / within one level, ECE
(10 bins of the intent confidence against "right intent on a motion text", over all texts) and latency (warm
median, p99; the first call in a fresh process is timed in a subprocess, with the compilation cache warm and
cold; where a warm call's time goes, :func:`experiments.bench_semantics_timing.breakdown`). A risk-coverage curve (accuracy of the acted-on texts, a no-behaviour text counting as wrong, against the
share acted on, texts ranked by confidence) is saved as ``results/semantics_risk_coverage.png``. Writes
``results/bench_semantics.md`` and ``.json`` and the confusion matrix ``results/semantics_confusion.png``.

The PyTorch peer (:mod:`experiments.bench_semantics_peer`), first in the same run: with ``--peer-python PATH`` (default
``.venv-peer/bin/python`` where it exists, else skipped with a note), a sample of the test splits' texts is tokenized
by us and, with the weights of the encoder jg.ground runs, exported to experiments/peer_torch_encoder.py, which
rebuilds MiniLM in PyTorch and times it eager and under ``torch.compile`` (``--no-peer`` skips it); our encoder alone and ``jg.ground`` are
timed on the same texts, pass by pass in alternation with it. The embeddings must agree
(cosine >= 0.999 for every text, else a parity error stops the run). The ratios, the achieved GFLOP/s of both against a
matmul rate measured in the same run, and the CPU go into the peer block of ``results/bench_semantics.md`` (between
``<!-- semantics-peer:start -->`` and ``<!-- semantics-peer:end -->``) and under ``"peer"`` in the ``.json``; a run
without the peer keeps the block. ``--peer-only`` (``make bench-peer``) runs the peer alone and rewrites only that
block. Where the shipped encoder runs fewer layers than MiniLM's six (the distilled student), the peer also runs the six-layer all-MiniLM-L6-v2 from
its own weights, eager, what a user of sentence-transformers would run instead; the speed goal is read off the
peer rows. The metrics and the goals (on the v2 test split and on the frozen blind benches, a table each) are those
of :mod:`experiments.bench_semantics_scores`; the results are written by :mod:`experiments.bench_semantics_report`.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

import jgrounding as jg
from experiments import bench_semantics_report as report
from experiments.bench_sample import cpu_isa, cpu_model, peak_gflops
from experiments.bench_semantics_peer import (
    PEER_COMPILE_TIMEOUT_S,
    PEER_PYTHON,
    PEER_REPS,
    PEER_TEXTS,
    peer_comparison,
    write_peer_section,
)
from experiments.bench_semantics_scores import (
    NO_RULE,
    REDUCERS,
    RESULTS,
    SECOND_READER,
    metrics,
    read_jsonl,
    reader_metrics,
    risk_coverage,
    run,
    second_reader,
)
from experiments.bench_semantics_timing import (
    TIMING_PASSES,
    breakdown,
    first_call_seconds,
    matrix_precision,
    one_core_latency,
)
from jgrounding import semantics
from jgrounding.semantics import embedded, encoder
from jgrounding.semantics import head as semantic_head
from jgrounding.semantics.nomotion import LEARNED
from tools import semantic_sets

ROOT = Path(__file__).resolve().parent.parent
# The sets are named in assets/semantics/sets.toml (tools.semantic_sets): the test splits, then the frozen blind
# benches in the manifest's order (two writers' (v3) and a third writer's (w3) no-motion and contrast texts, a fourth
# writer's (s3) situation-only and mixed texts, and the writers' sets added once the others had been read many times).
SPLITS = {"v2 test": semantic_sets.path("bench/v2"), "plain test": semantic_sets.path("bench/plain")}
BENCH_V3 = {
    f"{s.name.split('/')[1]} bench": s.file("bench.jsonl")
    for s in semantic_sets.select(role="bench", reader="bench")
    if "bench.jsonl" in s.file_names
}
OLD_HEAD = semantic_sets.path("bench/head_v1")


def grounder(name: str):
    if name == "new":
        return jg.ground  # what users call, with its defaults
    if name == "cues":
        return lambda t: jg.ground(t, backend="cues")
    if name == NO_RULE:
        return lambda t: embedded.ground_embedded_many([t])[0]
    old = semantic_head.load(str(OLD_HEAD))
    return lambda t: embedded.ground_embedded_many([t], head=old)[0]


def parse_args(argv=None):
    p = argparse.ArgumentParser(prog="python -m experiments.bench_semantics", description=__doc__.split("\n")[0])
    p.add_argument(
        "--peer-python",
        help=f"the PyTorch environment's python for the encoder peer (default: {PEER_PYTHON.relative_to(ROOT)} if "
        "it exists, else the peer is skipped; `make .venv-peer/.installed` makes it)",
    )
    p.add_argument(
        "--peer-only",
        action="store_true",
        help="only the PyTorch peer (1-2 min): update the peer section of results/bench_semantics.md and .json",
    )
    p.add_argument(
        "--no-peer", action="store_true", help="skip the PyTorch peer (its section of the results is kept as it was)"
    )
    p.add_argument("--peer-texts", type=int, default=PEER_TEXTS, help="texts sampled from the test splits")
    p.add_argument("--peer-reps", type=int, default=PEER_REPS, help="rounds of one timed pass each, ours and peer")
    p.add_argument("--peer-compile-timeout", type=float, default=PEER_COMPILE_TIMEOUT_S, help="seconds")
    args = p.parse_args(argv)
    if args.no_peer and (args.peer_only or args.peer_python):
        p.error("--no-peer skips the peer: drop --peer-only and --peer-python")
    if args.peer_python is None and PEER_PYTHON.exists() and not args.no_peer:
        args.peer_python = str(PEER_PYTHON)
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    missing = [str(p) for p in [*SPLITS.values(), *BENCH_V3.values(), OLD_HEAD] if not p.exists()]
    if missing:
        print(f"missing: {', '.join(missing)}")
        return 1
    if semantics.mllm_configured():
        print(
            "an MLLM endpoint is configured (JGROUNDING_MLLM_URL): jg.ground would escalate unsure texts to it; "
            "unset it, bench semantics measures the offline reducer with jg.ground's defaults"
        )
        return 1
    if args.peer_python is not None and not Path(args.peer_python).exists():
        print(f"--peer-python {args.peer_python} not found (`make .venv-peer/.installed` makes .venv-peer)")
        return 1
    splits = {name: read_jsonl(path) for name, path in SPLITS.items()}
    peer = None
    if args.peer_python is None:
        print(
            f"PyTorch peer skipped: --no-peer, or {PEER_PYTHON.relative_to(ROOT)} not found and no --peer-python given "
            "(`make .venv-peer/.installed` makes it; the peer section of the results is kept as it was)"
        )
        if args.peer_only:
            return 1
    else:  # first: a parity failure stops the run before the long part
        peer = peer_comparison(splits, args.peer_python, args.peer_texts, args.peer_reps, args.peer_compile_timeout)
        print(f"CPU: {cpu_model()} ({cpu_isa()})")
        print(peer[0])
        if args.peer_only:
            write_peer_section(RESULTS / "bench_semantics.md", RESULTS / "bench_semantics.json", *peer)
            return 0
    with tempfile.TemporaryDirectory() as cold:
        first_cold = first_call_seconds(cold)
    first_call_seconds(None)  # fill the user's compilation cache (a no-op when it is already warm)
    first_warm = [first_call_seconds(None) for _ in range(3)]
    fns = {name: grounder(name) for name in REDUCERS}
    semantics.warmup(256)  # warm: weights loaded, every token bucket compiled (or loaded from the cache)
    encoder.warmup(256)  # the first head's and the cue-list reducer's encoder
    for fn in fns.values():
        fn(splits["v2 test"][0]["text"])
    res, curves, latency = {}, {}, {}
    load = os.getloadavg()
    # Timing passes: every reducer grounds both splits TIMING_PASSES times, in an order rotated each pass, so a
    # shared machine's drift in speed (minutes long on the VMs we run on) falls on every reducer alike; the
    # latency is over all passes. Accuracy is read from the first pass (grounding is deterministic).
    names = list(fns)
    times = {name: [] for name in names}
    first = {}
    for p in range(TIMING_PASSES):
        for name in names[p % len(names) :] + names[: p % len(names)]:
            for split, items in splits.items():
                fns[name](items[0]["text"])
                preds, t = run(items, fns[name])
                times[name].append(t)
                first.setdefault((name, split), preds)
    for name in names:
        for split, items in splits.items():
            preds = first[(name, split)]
            styles = sorted({it.get("style", "all") for it in items})
            res[(name, split, "all")] = metrics(items, preds)
            for s in styles:
                group = [i for i, it in enumerate(items) if it.get("style") == s]
                res[(name, split, s)] = metrics([items[i] for i in group], [preds[i] for i in group])
            cov, acc = risk_coverage(items, preds)
            acted = [g.confident for g in preds]
            right = [g.intent == it["intent"] for g, it in zip(preds, items)]
            point = (float(np.mean(acted)), float(np.mean([r for r, a in zip(right, acted) if a] or [np.nan])))
            curves[(name, split)] = (cov, acc, point)
            if name == "new" and split == "v2 test":
                new_preds = preds
        t = np.concatenate(times[name]) * 1e3
        per_pass = [
            float(np.median(np.concatenate(times[name][i : i + len(splits)])) * 1e3)
            for i in range(0, len(times[name]), len(splits))
        ]
        latency[name] = {
            "ms_median": float(np.median(t)),
            "ms_p99": float(np.percentile(t, 99)),
            "n": len(t),
            "ms_median_per_pass": per_pass,
        }
    parts = breakdown([it["text"] for split in splits.values() for it in split])
    precision = matrix_precision([it["text"] for it in splits["v2 test"]])
    peak, peak_text = peak_gflops()
    load_pinned = os.getloadavg()[0]
    pinned = one_core_latency([it["text"] for split in splits.values() for it in split])
    v3 = {name: read_jsonl(path) for name, path in BENCH_V3.items()}  # the only read of the frozen blind benches
    rule_held, learned_held = {}, {}
    for name in [*names, NO_RULE]:
        fn = fns.get(name) or grounder(name)
        for split, items in v3.items():
            preds = run(items, fn)[0]
            res[(name, split, "all")] = metrics(items, preds)
            for s in sorted({it["style"] for it in items}):
                group = [i for i, it in enumerate(items) if it["style"] == s]
                res[(name, split, s)] = metrics([items[i] for i in group], [preds[i] for i in group])
            if name == "new":  # held by the rule, and by the learned detector
                rule_held[split] = {s: 0 for s in {it["style"] for it in items}}
                learned_held[split] = dict(rule_held[split])
                for it, g in zip(items, preds):
                    rule_held[split][it["style"]] += bool(g.no_motion) and g.no_motion != LEARNED
                    learned_held[split][it["style"]] += g.no_motion == LEARNED
    readers = {split: second_reader(BENCH_V3[split]) for split in v3}
    for split, labels in readers.items():
        if labels is not None:
            items = v3[split]
            res[(SECOND_READER, split, "all")] = reader_metrics(items, labels)
            for s in sorted({it["style"] for it in items}):
                res[(SECOND_READER, split, s)] = reader_metrics([it for it in items if it["style"] == s], labels)
    batch = [it["text"] for it in splits["v2 test"]]
    jg.ground_many(batch)  # compiles (or loads) the batch programs outside the timing, as warmup() does for one text
    batched = []
    for _ in range(3):
        t0 = time.perf_counter()
        jg.ground_many(batch)
        batched.append(time.perf_counter() - t0)
    batched_ms = 1e3 * float(np.median(batched)) / len(batch)
    report.write(
        splits=splits,
        v3=v3,
        sets={**SPLITS, **BENCH_V3},
        res=res,
        curves=curves,
        latency=latency,
        load=load,
        first_warm=first_warm,
        first_cold=first_cold,
        batched_ms=batched_ms,
        parts=parts,
        precision=precision,
        peak=peak,
        peak_text=peak_text,
        pinned=pinned,
        load_pinned=load_pinned,
        rule_held=rule_held,
        learned_held=learned_held,
        readers=readers,
        new_preds=new_preds,
        peer=peer,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
