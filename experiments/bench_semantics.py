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
- ``old``: the first trained head (``assets/semantics/bench/head_v1/semantic_head_v1.npz``, the embedding + Eq. (3) head of #15);
- ``cues``: the cue-list reducer (``backend="cues"``), the baseline.

Per style and overall: intent accuracy on motion texts, the share of motion texts acted on (confident), the
confident wrong motion rate (acted on with the wrong intent, share of motion texts), the share of no-behaviour
texts held (not acted on; the rest are motions where none was asked), intensity exact / within one level, ECE
(10 bins of the intent confidence against "right intent on a motion text", over all texts) and latency (warm
median, p99; the first call in a fresh process is timed in a subprocess, with the compilation cache warm and
cold; where a warm call's time goes, :func:`breakdown`). A risk-coverage curve (accuracy of the acted-on texts, a no-behaviour text counting as wrong, against the
share acted on, texts ranked by confidence) is saved as ``results/semantics_risk_coverage.png``. Writes
``results/bench_semantics.md`` and ``.json`` and the confusion matrix ``results/semantics_confusion.png``.

The PyTorch peer (issue #34 item 3), first in the same run: with ``--peer-python PATH`` (default
``.venv-peer/bin/python`` where it exists, else skipped with a note), a sample of the test splits' texts is tokenized
by us and, with the weights of the encoder jg.ground runs, exported to experiments/peer_torch_encoder.py, which
rebuilds MiniLM in PyTorch and times it eager and under ``torch.compile`` (``--no-peer`` skips it); our encoder alone and ``jg.ground`` are
timed on the same texts, pass by pass in alternation with it (:func:`peer_comparison`). The embeddings must agree
(cosine >= 0.999 for every text, else :class:`ParityError`). The ratios, the achieved GFLOP/s of both against a
matmul rate measured in the same run, and the CPU go into the peer block of ``results/bench_semantics.md`` (between
``<!-- semantics-peer:start -->`` and ``<!-- semantics-peer:end -->``) and under ``"peer"`` in the ``.json``; a run
without the peer keeps the block. ``--peer-only`` (``make bench-peer``) runs the peer alone and rewrites only that
block. Where the shipped encoder runs fewer layers than MiniLM's six (the distilled student), the peer also runs the six-layer all-MiniLM-L6-v2 from
its own weights, eager, what a user of sentence-transformers would run instead; #34's speed goal is read off the
peer rows (:func:`speed_goal_line`). #34's accuracy goals are read on both frozen blind benches
(:func:`blind_goal_rows`, its own table after #24's).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

import jgrounding as jg
from experiments.bench_sample import cpu_isa, cpu_model, peak_gflops
from jgrounding import semantics
from jgrounding.io import write_atomic
from jgrounding.semantics import calibration, embedded, encoder, features
from jgrounding.semantics import head as semantic_head
from jgrounding.semantics.nomotion import LEARNED
from jgrounding.vocabulary import INTENSITIES, INTENTS
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
REDUCERS = {
    "new": "trained head, structure-aware (jg.ground)",
    "old": "first trained head (#15)",
    "cues": "cue-list reducer (baseline)",
}
SECOND_READER = "second reader"  # a blind bench's second human-style reading (second_reader.jsonl), a reference row
SECOND_READER_FILE = "second_reader.jsonl"
NO_RULE = "new, no rule"  # the shipped head without the no-motion decision, rule and detector (v3 bench, accuracy only)
RESULTS = ROOT / "results"
TIMING_PASSES = 3  # per reducer, in rotated order (see main)
GOALS = {
    "intent": 0.95,
    "confident_wrong": 0.03,
    "none_held": 0.90,
    "exact": 0.75,
    "within_one": 0.97,
    "ece": 0.05,
    "ms_median": 5.0,
    "ms_p99": 15.0,
    "first_call_s": 1.5,
}
# Where what was tried is written up, for the goals (keys of GOALS) that fell short in some run.
TRIED = {
    "intent": "more training situations (640 shipped; 256 and 1,024 more, not shipped; 1,024 written from the v2 "
    "writer's brief, trained on: not shipped, in the vote's table: shipped; 3,520 from eleven blind writers: shipped), "
    "calibration on situations (shipped), label smoothing, four tuned layers, a "
    "lighter generated corpus, model soups, 1,920 nearest-neighbour vote variants (one shipped), a stronger encoder "
    "(none in the registry that ships its weights fits the budget): docs/how_it_works.md, section 1",
    "ms_median": "bucketed padding, one compiled program per call, float16- then int8-stored matrices, less Python per text, "
    "XNNPACK and oneDNN, bfloat16, a fused QKV product, the classic runtime, a three-layer distilled student "
    "(shipped); the products' rate is in the bucket table above: docs/how_it_works.md, section 1, 'Speed'",
    "ms_p99": "pinning the process to one core under load: docs/how_it_works.md, section 1, 'Speed'",
}
FIRST_CALL = (
    "import time; t = time.perf_counter(); import jgrounding as jg; "
    "jg.ground('The user looks sad; comfort them gently.'); print(time.perf_counter() - t)"
)


def read_jsonl(path) -> list[dict]:
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def grounder(name: str):
    if name == "new":
        return jg.ground  # what users call, with its defaults
    if name == "cues":
        return lambda t: jg.ground(t, backend="cues")
    if name == NO_RULE:
        return lambda t: embedded.ground_embedded_many([t])[0]
    old = semantic_head.load(str(OLD_HEAD))
    return lambda t: embedded.ground_embedded_many([t], head=old)[0]


def run(items: list[dict], fn) -> tuple[list, np.ndarray]:
    """Ground every item alone; the groundings and the seconds each took."""
    preds, times = [], []
    for it in items:
        t0 = time.perf_counter()
        preds.append(fn(it["text"]))
        times.append(time.perf_counter() - t0)
    return preds, np.array(times)


def metrics(items: list[dict], preds: list) -> dict:
    """Selective-grounding metrics of a group of items (see the module docstring)."""
    true = np.array([-1 if it["intent"] == "none" else INTENTS.index(it["intent"]) for it in items])
    motion = true >= 0
    m = np.array([INTENTS.index(g.intent) for g in preds])
    z = np.array([INTENSITIES.index(g.intensity) for g in preds])
    z_true = np.array([INTENSITIES.index(it["intensity"]) if it["intent"] != "none" else -9 for it in items])
    acted = np.array([g.confident for g in preds])
    conf = np.array([g.confidence for g in preds])
    return _rates(motion, (m == true) & motion, z, z_true, ~acted, acted, conf)


def _rates(motion, ok, z, z_true, held, acted=None, conf=None) -> dict:
    """The columns of :func:`metrics` from per-text arrays: ``motion`` (the text calls for a motion), ``ok`` (right
    intent on a motion text), intensity levels ``z`` / ``z_true``, ``held`` (no motion made), and, for a reducer,
    ``acted`` and ``conf`` (a reading without confidence: None, and its columns None)."""

    def mean(x):
        return float(np.mean(x)) if len(x) else None

    return {
        "n": len(motion),
        "n_motion": int(motion.sum()),
        "n_none": int((~motion).sum()),
        "intent": mean(ok[motion]),
        "acted": None if acted is None else mean(acted[motion]),
        "acted_accuracy": None if acted is None else mean(ok[motion & acted]),
        "confident_wrong": None if acted is None else mean((acted & ~ok)[motion]),
        "none_held": mean(held[~motion]),
        "exact": mean((z == z_true)[motion]),
        "within_one": mean((np.abs(z - z_true) <= 1)[motion]),
        "ece": None if conf is None else calibration.expected_calibration_error(conf, ok),
    }


def second_reader(path: Path) -> dict[str, tuple[str, str]] | None:
    """A blind bench's second reading (``second_reader.jsonl`` beside its ``bench.jsonl``: ``{"id", "intent",
    "intensity"}`` per text, labelled by a reader who saw only the texts and a labelling brief), or None."""
    path = Path(path).with_name(SECOND_READER_FILE)
    if not path.exists():
        return None
    return {r["id"]: (r["intent"], r["intensity"]) for r in read_jsonl(path)}


def reader_metrics(items: list[dict], labels: dict[str, tuple[str, str]]) -> dict:
    """How a second reader's labels agree with the writer's on ``items``: the columns of :func:`metrics` that a
    reading without confidence has (intent on motion texts, no-motion held, intensity exact and within one); the
    rest None. The human reference beside the head's rows: a goal above it asks more than two readers agree on."""
    missing = [it["id"] for it in items if it["id"] not in labels]
    if missing:
        raise ValueError(f"the second reader did not label {len(missing)} texts, e.g. {missing[:3]}")
    true = np.array([it["intent"] for it in items])
    got = np.array([labels[it["id"]][0] for it in items])
    motion = true != "none"
    level = {z: i for i, z in enumerate(INTENSITIES)}
    z_true = np.array([level.get(it["intensity"], -9) for it in items])
    z = np.array([level.get(labels[it["id"]][1], 99) for it in items])
    return _rates(motion, (got == true) & motion, z, z_true, got == "none")


def risk_coverage(items: list[dict], preds: list) -> tuple[np.ndarray, np.ndarray]:
    """Accuracy of the k most confident groundings (a no-behaviour text is never right) against coverage k/N."""
    true = [it["intent"] for it in items]
    conf = np.array([g.confidence for g in preds])
    ok = np.array([g.intent == t for g, t in zip(preds, true)], float)
    order = np.argsort(-conf, kind="stable")
    k = np.arange(1, len(items) + 1)
    return k / len(items), np.cumsum(ok[order]) / k


def goal_rows(res: dict, latency: dict, first_warm: list[float]) -> list[tuple[str, str, bool, str]]:
    """#24's goals on the v2 test split for the shipped reducer: ``(key, goal, met, measured)`` per row, ``key``
    one of :data:`GOALS` (or ``plain`` for the plain test split's intent against the first head)."""
    t = res[("new", "v2 test", "all")]
    styles = [k[2] for k in res if k[:2] == ("new", "v2 test") and k[2] != "all"]
    worst = min(
        res[("new", "v2 test", s)]["intent"]
        for s in styles
        if res[("new", "v2 test", s)]["n_motion"] and res[("new", "v2 test", s)]["intent"] is not None
    )
    new_plain, old_plain = res[("new", "plain test", "all")]["intent"], res[("old", "plain test", "all")]["intent"]
    first = float(np.median(first_warm))
    return [
        (
            "intent",
            "intent >= 0.95 on motion texts in every style",
            worst >= GOALS["intent"],
            f"lowest style {worst:.3f}",
        ),
        (
            "confident_wrong",
            "confident wrong motion <= 3%",
            t["confident_wrong"] <= GOALS["confident_wrong"],
            f"{t['confident_wrong']:.3f}",
        ),
        ("none_held", "no-behaviour texts held >= 90%", t["none_held"] >= GOALS["none_held"], f"{t['none_held']:.3f}"),
        ("exact", "intensity exact >= 0.75", t["exact"] >= GOALS["exact"], f"{t['exact']:.3f}"),
        (
            "within_one",
            "intensity within one >= 0.97",
            t["within_one"] >= GOALS["within_one"],
            f"{t['within_one']:.3f}",
        ),
        ("ece", "ECE <= 0.05", t["ece"] <= GOALS["ece"], f"{t['ece']:.3f}"),
        (
            "ms_median",
            "warm median <= 5 ms",
            latency["new"]["ms_median"] <= GOALS["ms_median"],
            f"{latency['new']['ms_median']:.2f} ms",
        ),
        ("ms_p99", "p99 <= 15 ms", latency["new"]["ms_p99"] <= GOALS["ms_p99"], f"{latency['new']['ms_p99']:.2f} ms"),
        ("first_call_s", "first call <= 1.5 s (cache warm)", first <= GOALS["first_call_s"], f"{first:.2f} s"),
        (
            "plain",
            "plain test intent does not fall (new >= old)",
            new_plain >= old_plain,
            f"{new_plain:.3f} vs {old_plain:.3f}",
        ),
    ]


# Issue #34's goals, on each frozen blind bench (contrast texts and texts that call for no motion) and, for the
# styles the blind benches do not hold, on the v2 test split's motion styles.
GOALS_34 = {
    "none_held": 0.95,
    "confident_wrong": 0.01,
    "intent": 0.95,
    "exact": 0.80,
    "ece": 0.05,
    "situation": 0.90,
    "styles": 0.95,
}


def blind_goal_rows(res: dict, benches) -> list[tuple[str, str, bool, str, str]]:
    """#34's goals (:data:`GOALS_34`) for the shipped reducer: ``(key, goal, met, measured, second reader)`` per
    row. Per frozen blind bench: no-motion held (where it holds such texts), confident wrong motion, the intent of
    each motion style it holds (situation-only against its own goal, every other style against ``styles``; a bench
    of one motion style, as v3's contrast, gives it as ``intent``), intensity exact and ECE. Then the v2 test split's
    situation-only style and its other motion styles. The last field is the same measure of the bench's second
    reader (``res[(SECOND_READER, bench, style)]``, :func:`reader_metrics`) where it has one, else ``""``."""
    g, rows = GOALS_34, []

    def reader(b, style, key):
        r = res.get((SECOND_READER, b, style))
        return "" if r is None or r.get(key) is None else f"{r[key]:.3f}"

    for b in benches:
        r = res[("new", b, "all")]
        motion = {k[2]: v for k, v in res.items() if k[:2] == ("new", b) and k[2] != "all" and v.get("n_motion")}
        if r.get("n_none", 1):
            rows.append(
                (
                    "34_none_held",
                    f"{b}: no-motion held >= {g['none_held']}",
                    r["none_held"] >= g["none_held"],
                    f"{r['none_held']:.3f}",
                    reader(b, "all", "none_held"),
                )
            )
        rows.append(
            (
                "34_confident_wrong",
                f"{b}: confident wrong motion <= {g['confident_wrong']:.0%} of motion texts",
                r["confident_wrong"] <= g["confident_wrong"],
                f"{r['confident_wrong']:.3f}",
                "",
            )
        )
        if not motion:  # the bench's motion texts are of one style (v3, w3: contrast)
            rows.append(
                (
                    "34_intent",
                    f"{b}: contrast intent >= {g['intent']}",
                    r["intent"] >= g["intent"],
                    f"{r['intent']:.3f}",
                    reader(b, "all", "intent"),
                )
            )
        for style, v in sorted(motion.items()):
            goal = g["situation"] if style == "situation" else g["styles"]
            rows.append(
                (
                    f"34_{style}",
                    f"{b}: {style} intent >= {goal}",
                    v["intent"] >= goal,
                    f"{v['intent']:.3f}",
                    reader(b, style, "intent"),
                )
            )
        rows += [
            (
                "34_exact",
                f"{b}: intensity exact >= {g['exact']}",
                r["exact"] >= g["exact"],
                f"{r['exact']:.3f}",
                reader(b, "all", "exact"),
            ),
            ("34_ece", f"{b}: ECE <= {g['ece']}", r["ece"] <= g["ece"], f"{r['ece']:.3f}", ""),
        ]
    styles = {k[2]: v for k, v in res.items() if k[:2] == ("new", "v2 test") and k[2] != "all" and v["n_motion"]}
    sit = styles.pop("situation", None)
    if sit is not None:
        rows.append(
            (
                "34_situation",
                f"v2 test: situation-only intent >= {g['situation']}",
                sit["intent"] >= g["situation"],
                f"{sit['intent']:.3f}",
                "",
            )
        )
    worst = min(styles, key=lambda k: styles[k]["intent"])
    rows.append(
        (
            "34_styles",
            f"v2 test: every other style's intent >= {g['styles']}",
            styles[worst]["intent"] >= g["styles"],
            f"lowest {worst} {styles[worst]['intent']:.3f}",
            "",
        )
    )
    return rows


def shortfalls(rows) -> list[str]:
    """For each goal of :func:`goal_rows` not met, what was tried (:data:`TRIED`); a goal missed for the first
    time, with nothing tried yet, says so."""
    return [f"{g}: {TRIED.get(key, 'nothing tried yet (a new shortfall)')}" for key, g, ok, _ in rows if not ok]


def breakdown(texts: list[str]) -> dict:
    """Where a warm single-text ``jg.ground`` spends its time (the shipped tuned head): preparing the inputs in
    Python (structure rules, tokenizer, span pools, named actions and degree cues) and the one compiled program
    (encoder, head and nearest-neighbour vote: :meth:`Head.run_tuned`), per token bucket. Milliseconds."""
    from jgrounding.semantics import structure

    head = semantic_head.load()
    if not head.config.features.one_program:
        return {}
    prep, program, buckets = [], [], []
    for text in texts:
        t0 = time.perf_counter()
        st = structure.analyse(text)
        extras = features.tuned_extras(text, st)[None]
        (_, ids, mask, pools), *_ = list(features.encoder_batches([text], [st]))
        t1 = time.perf_counter()
        out = head.run_tuned(ids, mask, pools, extras)  # the program jg.ground runs, the vote included
        np.asarray(out[0])
        t2 = time.perf_counter()
        prep.append(t1 - t0)
        program.append(t2 - t1)
        buckets.append(ids.shape[1])
    prep, program, buckets = np.array(prep) * 1e3, np.array(program) * 1e3, np.array(buckets)
    by_bucket = {}
    for b in map(int, np.unique(buckets)):
        ms = float(np.median(program[buckets == b]))
        flops = encoder.matmul_flops(b, layers=head.config.num_encoder_layers)
        by_bucket[b] = {"n": int((buckets == b).sum()), "program_ms_median": ms, "gflop": flops / 1e9}
        by_bucket[b]["gflops"] = flops / 1e6 / ms
    return {
        "encoder_layers": head.config.num_encoder_layers,
        "prep_ms_median": float(np.median(prep)),
        "program_ms_median": float(np.median(program)),
        "program_ms_p99": float(np.percentile(program, 99)),
        "by_bucket": by_bucket,
    }


def matrix_precision(texts: list[str]) -> dict:
    """The encoder alone (:func:`jgrounding.semantics.encoder.pool_ids`, one text at a time) with the dense matrices
    stored in each of :data:`jgrounding.semantics.encoder.STORAGES` (grounding keeps
    :data:`~jgrounding.semantics.encoder.MATRIX_STORAGE`), all from the weights jg.ground runs, rotating text by
    text so all see the machine in the same state. Milliseconds (medians) by storage, and each one's speed-up over
    float32."""
    from jgrounding.semantics import structure

    head = semantic_head.load()
    values = encoder.float_matrices(jax.tree.map(np.asarray, head.encoder_params()))
    kinds = {k: jax.device_put(encoder.stored_matrices(values, k)) for k in encoder.STORAGES}
    times = {k: [] for k in kinds}
    for i, text in enumerate(texts):
        (_, ids, mask, pools), *_ = list(features.encoder_batches([text], [structure.analyse(text)]))
        order = list(kinds)[i % len(kinds) :] + list(kinds)[: i % len(kinds)]
        for kind in order:
            encoder.pool_ids(kinds[kind], ids, mask, pools).block_until_ready()  # compiled outside the timing
        for kind in order:
            t0 = time.perf_counter()
            encoder.pool_ids(kinds[kind], ids, mask, pools).block_until_ready()
            times[kind].append(time.perf_counter() - t0)
    med = {k: float(np.median(v) * 1e3) for k, v in times.items()}
    return {"ms": med, "speedup": {k: med["float32"] / med[k] for k in med}, "shipped": encoder.MATRIX_STORAGE}


ONE_CORE = """
import json, os, sys, time
os.sched_setaffinity(0, {int(sys.argv[1])})  # before JAX starts: its thread pools get one thread
import numpy as np
import jgrounding as jg
from jgrounding import semantics
semantics.warmup(256)
texts = json.loads(sys.stdin.read())
jg.ground(texts[0])
t = []
for text in texts:
    t0 = time.perf_counter()
    jg.ground(text)
    t.append(time.perf_counter() - t0)
t = np.array(t) * 1e3
print(json.dumps({"ms_median": float(np.median(t)), "ms_p99": float(np.percentile(t, 99)), "n": len(t)}))
"""


def one_core_latency(texts: list[str]) -> dict | None:
    """Warm latency of ``jg.ground`` in a process pinned to one CPU core (``taskset -c N`` does the same): JAX then
    runs each program in one thread, so it never waits for a second thread on a core another process holds.
    None where CPU affinity cannot be set (not Linux)."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    core = min(os.sched_getaffinity(0))
    out = subprocess.run(
        [sys.executable, "-c", ONE_CORE, str(core)], input=json.dumps(texts), cwd=ROOT, capture_output=True, text=True
    )
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1]) | {"core": core}


def first_call_seconds(cache: str | None) -> float:
    """The first ``jg.ground`` in a fresh process (import included); ``cache``: a compilation-cache folder."""
    env = dict(os.environ)
    if cache is not None:
        env["JGROUNDING_CACHE"] = cache
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], env=env, cwd=ROOT, capture_output=True, text=True)
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    return float(out.stdout.strip().splitlines()[-1])


# --- The PyTorch peer of the encoder, in the same run (issue #34 item 3; `make bench-peer`, or --peer-only) ------
PEER_PYTHON = ROOT / ".venv-peer" / "bin" / "python"  # made by the Makefile's $(PEER_VENV) rule
PEER_SCRIPT = ROOT / "experiments" / "peer_torch_encoder.py"
PEER_START, PEER_END = "<!-- semantics-peer:start -->", "<!-- semantics-peer:end -->"  # the peer block's markers
PEER_TEXTS = 120  # texts sampled evenly from the test splits (SPLITS) for the peer comparison
PEER_REPS = 3  # rounds: a timed pass of ours and one of the peer's each, alternating
PEER_MIN_COSINE = 0.999  # JAX vs PyTorch sentence embeddings, every text
PEER_COMPILE_TIMEOUT_S = 300  # torch.compile's whole run (compile + timing); past it, the eager rows stand alone
MATMUL_LARGE = 1024  # tokens of the second matmul-rate shape (a long batch: the machine's sustained rate)


class ParityError(AssertionError):
    """JAX and PyTorch embeddings of the same text disagree (below :data:`PEER_MIN_COSINE`)."""


def encoder_flops(
    length: int,
    *,
    hidden: int = encoder.HIDDEN,
    intermediate: int = encoder.INTERMEDIATE,
    layers: int = encoder.NUM_LAYERS,
) -> int:
    """FLOPs (two per multiply-add) of one text of ``length`` tokens through a BERT encoder of these dims: per layer
    the four ``hidden x hidden`` products (query, key, value, output), the two ``hidden x intermediate`` ones (FFN)
    and attention's two ``length x length x hidden`` (scores, context). Norms, GELU, softmax, embeddings and pooling
    (``O(length x hidden)`` each) are left out, so a rate computed from it is a lower bound. MiniLM's dims give
    :func:`jgrounding.semantics.encoder.matmul_flops`."""
    dense = 4 * hidden * hidden + 2 * hidden * intermediate
    return layers * 2 * (length * dense + 2 * length * length * hidden)


def peer_sample(splits: dict, n: int = PEER_TEXTS) -> list[str]:
    """``n`` texts spread evenly over the test splits (in SPLITS order): the same texts every run."""
    texts = [it["text"] for items in splits.values() for it in items]
    idx = np.unique(np.linspace(0, len(texts) - 1, min(n, len(texts))).round().astype(int))
    return [texts[i] for i in idx]


def tokenize_one(text: str) -> tuple[np.ndarray, np.ndarray, int]:
    """Our tokenizer for one text as the encoder takes it: ids and mask ``(1, bucket)`` int32, and its token count."""
    enc = encoder.tokenizer().encode(text)
    ids, mask = encoder.pad_rows([enc], encoder.bucket_length(len(enc.ids)), 1)
    return ids, mask, len(enc.ids)


def export_peer(params: dict, texts: list[str], path) -> dict:
    """Write what experiments/peer_torch_encoder.py rebuilds and runs: the encoder's weights (``params``, the JAX
    pytree flattened with ``/``, every leaf as float32: stored matrices widened to the values the program computes
    with, :func:`jgrounding.semantics.encoder.float_matrices`), our tokenization of ``texts`` (ids and mask padded to the longest bucket, with each text's
    token count and bucket), the head count and the LayerNorm epsilon. Returns the token arrays."""
    toks = [tokenize_one(t) for t in texts]
    width = max(ids.shape[1] for ids, _, _ in toks)
    tokens = {
        "ids": np.zeros((len(texts), width), np.int32),
        "mask": np.zeros((len(texts), width), np.int32),
        "lengths": np.array([n for *_, n in toks], np.int32),
        "buckets": np.array([ids.shape[1] for ids, _, _ in toks], np.int32),
    }
    for i, (ids, mask, _) in enumerate(toks):
        tokens["ids"][i, : ids.shape[1]], tokens["mask"][i, : ids.shape[1]] = ids[0], mask[0]
    values = encoder.float_matrices(jax.tree.map(np.asarray, params))  # int8 or float16 widened, scales applied
    weights = {k: np.asarray(v, np.float32) for k, v in semantic_head.flatten(values).items()}
    config = {"num_heads": np.int32(encoder.NUM_HEADS), "ln_eps": np.float64(encoder.LN_EPS)}
    np.savez(path, **weights, **tokens, **config)
    return tokens


def check_parity(ours, peer, label: str = "torch", min_cosine: float = PEER_MIN_COSINE) -> float:
    """The lowest cosine similarity between matching rows of two ``(N, D)`` embedding arrays; raises
    :class:`ParityError` (naming the worst text) when any row is below ``min_cosine``, not finite, or the shapes
    differ."""
    a, b = np.asarray(ours, np.float64), np.asarray(peer, np.float64)
    if a.shape != b.shape or a.ndim != 2:
        raise ParityError(f"{label}: embeddings of shape {b.shape}, ours {a.shape}")
    cos = (a * b).sum(1) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-30)
    bad = np.flatnonzero(~(cos >= min_cosine))  # NaN counts as bad
    if bad.size:
        worst = int(bad[np.argmin(np.nan_to_num(cos[bad], nan=-2.0))])
        raise ParityError(
            f"{label}: {bad.size} of {len(cos)} texts below cosine {min_cosine} against JAX "
            f"(worst: text {worst}, cosine {cos[worst]:.6f})"
        )
    return float(cos.min())


def matmul_gflops(tokens: int, reps: int = 200) -> float:
    """The machine's rate, measured now, for the encoder's dominant product: a plain jitted JAX float32
    ``(tokens x 384) @ (384 x 1536)`` (ff1's shape; ff2 is its transpose), inputs on the device, median of
    ``reps``."""
    rng = np.random.default_rng(0)
    a = jax.device_put(rng.standard_normal((tokens, encoder.HIDDEN), np.float32))
    b = jax.device_put(rng.standard_normal((encoder.HIDDEN, encoder.INTERMEDIATE), np.float32))
    f = jax.jit(lambda x, y: x @ y)
    f(a, b).block_until_ready()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        f(a, b).block_until_ready()
        times.append(time.perf_counter() - t0)
    return 2 * tokens * encoder.HIDDEN * encoder.INTERMEDIATE / float(np.median(times)) / 1e9


def _per_text_ms(calls: list, reps: int) -> list[float]:
    """Per call (one per text): the median milliseconds of ``reps`` passes over all of them (after one untimed)."""
    for call in calls:
        call()
    times = np.zeros((reps, len(calls)))
    for r in range(reps):
        for j, call in enumerate(calls):
            t0 = time.perf_counter()
            call()
            times[r, j] = time.perf_counter() - t0
    return (1e3 * np.median(times, axis=0)).tolist()


def ours_ms(params: dict, texts: list[str], reps: int) -> dict:
    """Per text (ms): our tokenization for the encoder (:func:`tokenize_one`), the JAX encoder alone on those
    inputs (``encoder.encode_ids`` with ``params``: ids and mask in, the unit sentence vector out) and the whole
    ``jg.ground``."""
    toks = [tokenize_one(t) for t in texts]
    return {
        "tokenize": _per_text_ms([lambda t=t: tokenize_one(t) for t in texts], reps),
        "encoder": _per_text_ms(
            [lambda i=i, m=m: encoder.encode_ids(params, i, m).block_until_ready() for i, m, _ in toks], reps
        ),
        "ground": _per_text_ms([lambda t=t: jg.ground(t) for t in texts], reps),
    }


def peer_isa_env(xla_flags: str | None = None) -> dict[str, str]:
    """The environment that limits PyTorch to the ISA ``XLA_FLAGS`` limits XLA to (``--xla_cpu_max_isa=AVX2``):
    ATen's kernels (``ATEN_CPU_CAPABILITY``), oneDNN (``ONEDNN_MAX_CPU_ISA``) and MKL's products
    (``MKL_ENABLE_INSTRUCTIONS``), so that both sides of the comparison run the same vector width (on an AVX-512
    machine an unlimited peer would run AVX-512 against our AVX2). Empty when XLA is not limited."""
    flags = os.environ.get("XLA_FLAGS", "") if xla_flags is None else xla_flags
    isa = next((f.split("=", 1)[1] for f in flags.split() if f.startswith("--xla_cpu_max_isa=")), "")
    if not isa:
        return {}
    return {
        "ATEN_CPU_CAPABILITY": isa.lower(),
        "ONEDNN_MAX_CPU_ISA": isa.upper(),
        "MKL_ENABLE_INSTRUCTIONS": isa.upper(),
    }


def run_peer(
    python, weights: Path, out: Path, modes: str, reps: int, timeout: float | None = None, inductor: Path | None = None
) -> dict:
    """experiments/peer_torch_encoder.py in the torch environment ``python`` (its output shown as it runs); its
    JSON. ``inductor``: TorchInductor's cache folder (default: a new one beside ``out``, so torch.compile's time is a
    cold compile's, as on a user's first run). Raises ``CalledProcessError`` / ``TimeoutExpired``."""
    cmd = [str(python), str(PEER_SCRIPT), str(weights), str(out), "--modes", modes, "--reps", str(reps)]
    cache = inductor or out.parent / f"inductor-{out.stem}"
    env = {**os.environ, "PYTHONPATH": "", "TORCHINDUCTOR_CACHE_DIR": str(cache), **peer_isa_env()}
    subprocess.run(cmd, check=True, cwd=ROOT, env=env, timeout=timeout)
    return json.loads(out.read_text())


def peer_comparison(splits: dict, python, n: int = PEER_TEXTS, reps: int = PEER_REPS, timeout=None) -> tuple:
    """Time our encoder, ``jg.ground`` and the PyTorch peer (eager, eager padded to our buckets, torch.compile) on
    the same texts in this run, alternating ours and the peer pass by pass (``reps`` rounds, the order flipped each
    round, so a shared machine's drift in speed falls on both); check parity; return ``(block, payload)``: the
    Markdown peer block (between :data:`PEER_START` and :data:`PEER_END`) and its JSON."""
    texts = peer_sample(splits, n)
    head = semantic_head.load()
    params = head.encoder_params()  # the encoder jg.ground runs (tuned top layers, stored matrices)
    num_layers = head.config.num_encoder_layers
    # An encoder of fewer layers than MiniLM's six (a distilled student) is also set beside the six-layer
    # all-MiniLM-L6-v2 that a user of sentence-transformers would run instead (its own weights, eager).
    six = encoder.load_params() if num_layers != encoder.NUM_LAYERS else None
    semantics.warmup(256)
    load = os.getloadavg()[0]
    ours_emb = np.stack([np.asarray(encoder.encode_ids(params, *tokenize_one(t)[:2]))[0] for t in texts])
    six_emb = None
    if six is not None:
        six_emb = np.stack([np.asarray(encoder.encode_ids(six, *tokenize_one(t)[:2]))[0] for t in texts])
    compile_note, ours_runs, peer_runs = None, [], []
    with tempfile.TemporaryDirectory() as tmp:
        weights = Path(tmp) / "minilm.npz"
        tokens = export_peer(params, texts, weights)
        if six is not None:
            export_peer(six, texts, Path(tmp) / "minilm6.npz")
        for r in range(reps):
            for who in ("ours", "peer") if r % 2 == 0 else ("peer", "ours"):
                if who == "ours":
                    ours_runs.append(ours_ms(params, texts, 1))
                    o = ours_runs[-1]
                    print(
                        f"ours, round {r + 1}: encoder {np.median(o['encoder']):.2f} ms, jg.ground "
                        f"{np.median(o['ground']):.2f} ms, tokenization {np.median(o['tokenize']):.3f} ms",
                        flush=True,
                    )
                    continue
                run = run_peer(python, weights, Path(tmp) / f"eager{r}.json", "eager,eager_padded", 1)
                if six is not None:
                    out6 = Path(tmp) / f"minilm6-{r}.json"
                    run["modes"]["eager_minilm6"] = run_peer(python, Path(tmp) / "minilm6.npz", out6, "eager", 1)[
                        "modes"
                    ]["eager"]
                if compile_note is None:  # one TorchInductor cache for every round: the first compiles cold
                    out, cache = Path(tmp) / f"compile{r}.json", Path(tmp) / "inductor"
                    try:
                        run["modes"] |= run_peer(python, weights, out, "compile", 1, timeout, cache)["modes"]
                    except subprocess.TimeoutExpired:
                        compile_note = f"torch.compile did not finish within {timeout:g} s: eager rows only"
                    except subprocess.CalledProcessError as e:
                        compile_note = (
                            f"torch.compile failed (exit {e.returncode}; its error is printed above): eager only"
                        )
                peer_runs.append(run)
    modes = [
        m for m in ("eager", "eager_padded", "compile", "eager_minilm6") if all(m in run["modes"] for run in peer_runs)
    ]
    peer = dict(peer_runs[0], modes={})
    for m in modes:
        ms = np.median([run["modes"][m]["ms"] for run in peer_runs], axis=0)  # per text, over the rounds
        peer["modes"][m] = {"ms": ms.tolist(), "embeddings": peer_runs[0]["modes"][m]["embeddings"]}
        peer["modes"][m]["round_ms_median"] = [float(np.median(run["modes"][m]["ms"])) for run in peer_runs]
        for run in peer_runs:  # every round's output must agree
            check_parity(six_emb if m == "eager_minilm6" else ours_emb, run["modes"][m]["embeddings"], f"torch {m}")
    compile_times = [run["modes"]["compile"]["compile_s"] for run in peer_runs] if "compile" in modes else []
    cosines = {
        mode: check_parity(six_emb if mode == "eager_minilm6" else ours_emb, v["embeddings"], f"torch {mode}")
        for mode, v in peer["modes"].items()
    }
    lengths, buckets = tokens["lengths"], tokens["buckets"]
    typical = int(np.median(buckets))
    rates = {"bucket": matmul_gflops(typical), "large": matmul_gflops(MATMUL_LARGE, reps=50)}
    flops = {
        "bucket": np.array([encoder_flops(int(b), layers=num_layers) for b in buckets], float),
        "own": np.array([encoder_flops(int(n), layers=num_layers) for n in lengths], float),
        "own6": np.array([encoder_flops(int(n)) for n in lengths], float),
    }
    ours = {k: np.median([run[k] for run in ours_runs], axis=0).tolist() for k in ours_runs[0]}
    round_ms = {k: [float(np.median(run[k])) for run in ours_runs] for k in ("encoder", "ground")}
    round_ms |= {f"torch_{m}": v["round_ms_median"] for m, v in peer["modes"].items()}

    def row(ms, shapes) -> dict:
        gflops = flops[shapes].sum() / 1e6 / float(np.sum(ms))
        return {
            "ms_median": float(np.median(ms)),
            "gflops": gflops,
            "share": gflops / rates["bucket"],  # of the matmul rate at the sample's median bucket
            "share_large": gflops / rates["large"],  # of the rate at MATMUL_LARGE tokens
        }

    rows = {
        "jax_encoder": row(ours["encoder"], "bucket"),
        "jg_ground": row(ours["ground"], "bucket"),
        **{
            f"torch_{m}": row(v["ms"], {"eager_padded": "bucket", "eager_minilm6": "own6"}.get(m, "own"))
            for m, v in peer["modes"].items()
        },
    }
    enc_ms, ground_ms = rows["jax_encoder"]["ms_median"], rows["jg_ground"]["ms_median"]
    for key, r in rows.items():
        if key.startswith("torch_"):
            r["vs_encoder"], r["vs_ground"] = r["ms_median"] / enc_ms, r["ms_median"] / ground_ms
    tok_ms = float(np.median(ours["tokenize"]))
    labels = {
        "jax_encoder": "JAX encoder alone (`encoder.encode_ids`, one text at its token bucket, matrices stored in "
        f"{encoder.MATRIX_STORAGE} as grounding keeps them)",
        "jg_ground": "`jg.ground` (the whole call: structure, tokenizer, encoder pooled 4 ways, head, vote)",
        "torch_eager": f"PyTorch {peer['torch']} eager, the text's own token count",
        "torch_eager_padded": f"PyTorch {peer['torch']} eager, padded to our token bucket",
        "torch_compile": f"PyTorch {peer['torch']} `torch.compile(dynamic=True)`, own token count",
        "torch_eager_minilm6": f"PyTorch {peer['torch']} eager, own token count: the six-layer all-MiniLM-L6-v2 "
        "(its own weights), what a sentence-transformers user runs instead",
    }

    def line(key) -> str:
        r = rows[key]
        ratios = f"{r['vs_encoder']:.2f}x | {r['vs_ground']:.2f}x" if "vs_encoder" in r else " | "
        lb = " (lower bound)" if key == "jg_ground" else ""
        shares = f"{100 * r['share']:.0f} % | {100 * r['share_large']:.0f} %"
        return f"| {labels[key]} | {r['ms_median']:.2f} | {ratios} | {r['gflops']:.0f}{lb} | {shares} |"

    compile_s = compile_times[0] if compile_times else None
    names = {"encoder": "JAX encoder", "ground": "`jg.ground`", "torch_eager": "eager", "torch_eager_padded": "padded"}
    names["torch_compile"] = "compiled"
    names["torch_eager_minilm6"] = "six-layer MiniLM"
    round_text = "; ".join(f"{names[k]} {', '.join(f'{x:.2f}' for x in v)} ms" for k, v in round_ms.items())
    cos_text = ", ".join(f"{cosines[m]:.6f} ({m})" for m in cosines)
    isa_env = peer_isa_env()
    lines = [
        PEER_START,
        "",
        "### PyTorch peer of the encoder, same run (`make bench-peer`, experiments/peer_torch_encoder.py)",
        "",
        f"CPU: {cpu_model()} ({cpu_isa()}), {os.cpu_count()} cores, load average {load:.2f} at the start; "
        f"PyTorch {peer['torch']} with {peer['threads']} threads ({peer['interop_threads']} inter-op; "
        f"kernels dispatched to {peer.get('cpu_capability', 'an unreported ISA')}"
        + (f", limited as XLA is: {', '.join(f'{k}={v}' for k, v in isa_env.items())}" if isa_env else "")
        + "), "
        f"JAX {jax.__version__} (XLA_FLAGS: {os.environ.get('XLA_FLAGS') or 'none'}). {len(texts)} texts spread "
        f"evenly over the v2 and plain test splits ({lengths.min()} to {lengths.max()} tokens, median "
        f"{np.median(lengths):g}; our buckets median {typical}), each alone, warm. Ours and the peer alternate pass "
        f"by pass, {reps} rounds with the order flipped each round, so the machine's drift falls on both; per text "
        "the median over the rounds, then the median over texts (GFLOP/s: total FLOPs over the sum of the texts' "
        f"medians). Each round's median: {round_text}. The peer rebuilds the same MiniLM from our exported weights "
        f"(the shipped head's encoder, {num_layers} layers, float32) "
        "as Hugging Face's BertModel with mean pooling and L2 norm, run as sentence-transformers users run it "
        "(`eval()`, `torch.inference_mode()`, one text per call).",
        "",
        "| encoder-only unless said | median ms | peer / JAX encoder | peer / `jg.ground` | GFLOP/s | "
        f"share of the matmul rate at T = {typical} | at T = {MATMUL_LARGE} |",
        "|---|---|---|---|---|---|---|",
        line("jax_encoder"),
        line("jg_ground"),
        *[line(k) for k in ("torch_eager", "torch_eager_padded", "torch_compile", "torch_eager_minilm6") if k in rows],
        "",
        speed_goal_line(rows),
        "",
        "Tokenization is not included on the peer side (its environment has no tokenizer; it gets our token ids "
        "and masks), nor in the JAX encoder row: the ratios compare encoder-only with encoder-only. Our "
        f"tokenization for the encoder (tokenizers + padding to the bucket) took {tok_ms:.3f} ms median per text; a "
        "whole sentence-embedding call adds it on either side. Ratios are of milliseconds: above 1x, ours is faster.",
        "",
        f"GFLOP/s: the matrix products of `encoder_flops` ({num_layers} layers, but for the six-layer MiniLM row: "
        "q, k, v, o 384 x 384, FFN 384 x 1536 twice, "
        f"attention's two L x L x 384) over the texts' times, at the shapes each runs (ours at the bucket, mean "
        f"{flops['bucket'].mean() / 1e6:.0f} MFLOP per text; the peer at the text's own length, mean "
        f"{flops['own'].mean() / 1e6:.0f} MFLOP, but for the padded row); `jg.ground`'s counts only the encoder. "
        f"Measured matmul rate in this run (jitted JAX float32 (T x 384) @ (384 x 1536), inputs on the device): "
        f"{rates['bucket']:.0f} GFLOP/s at T = {typical} tokens (the sample's median bucket: one text's product), "
        f"{rates['large']:.0f} GFLOP/s at T = {MATMUL_LARGE} (a long product: the machine's sustained rate). "
        "A share above 100 % means the implementation's products beat XLA's single product at that shape.",
        "",
        f"Parity: cosine of the JAX and PyTorch sentence embeddings, lowest over the {len(texts)} texts: {cos_text} "
        f"(each text must reach {PEER_MIN_COSINE}). "
        + (
            f"torch.compile: {compile_s:.1f} s to compile on the first call (one dynamic-shape graph, empty "
            f"TorchInductor cache; {', '.join(f'{x:.1f}' for x in compile_times[1:]) or '-'} s in the later "
            "rounds' fresh processes, the cache warm)."
            if compile_s is not None
            else compile_note
        ),
        "",
        PEER_END,
    ]
    payload = {
        "cpu": cpu_model(),
        "isa": cpu_isa(),
        "cores": os.cpu_count(),
        "load_average": load,
        "texts": len(texts),
        "reps": reps,
        "tokens": {"min": int(lengths.min()), "max": int(lengths.max()), "median": float(np.median(lengths))},
        "torch": peer["torch"],
        "torch_threads": peer["threads"],
        "torch_cpu_capability": peer.get("cpu_capability"),
        "torch_isa_env": isa_env,
        "jax": jax.__version__,
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "tokenize_ms_median": tok_ms,
        "encoder_layers": num_layers,
        "round_ms_median": round_ms,
        "rows": rows,
        "matmul_gflops": {f"T={typical}": rates["bucket"], f"T={MATMUL_LARGE}": rates["large"]},
        "min_cosine": cosines,
        "compile_s": compile_s,
        "compile_s_cache_warm": compile_times[1:],
        "compile_note": compile_note,
        "comparison": "encoder-only vs encoder-only; tokenization excluded on both sides (ours reported apart)",
    }
    return "\n".join(lines), payload


def speed_goal_line(rows: dict) -> str:
    """#34's speed goal, read off one peer run's rows: ``jg.ground``'s warm median at most 5 ms on an AVX2-only
    machine (or with XLA limited to AVX2), or at least twice as fast as the PyTorch peer in the same run; the ratio
    against the eager peer on the same weights decides, the six-layer MiniLM (where shown) is reported beside."""
    ground = rows["jg_ground"]["ms_median"]
    flags = os.environ.get("XLA_FLAGS", "")
    avx2 = cpu_isa() == "avx2+fma" or "xla_cpu_max_isa=AVX2" in flags
    eager = rows.get("torch_eager")
    ratio = eager["ms_median"] / ground if eager else float("nan")
    six = rows.get("torch_eager_minilm6")
    met_ms, met_ratio = avx2 and ground <= GOALS["ms_median"], ratio >= 2.0
    return (
        f"#34's speed goal: `jg.ground` {ground:.2f} ms warm median "
        f"({'AVX2 only' if avx2 else 'AVX-512 in use: the 5 ms goal is not judged here'}): 5 ms goal "
        f"{'met' if met_ms else 'not met'}; against the eager peer on the same weights {ratio:.2f}x (goal 2x: "
        f"{'met' if met_ratio else 'not met'})"
        + (f"; against the six-layer MiniLM a user would run instead {six['ms_median'] / ground:.2f}x" if six else "")
        + f". Goal {'met' if met_ms or met_ratio else 'not met'} in this run."
    )


def machine() -> str:
    """The machine a timing ran on, for every timing line: CPU model, its widest vector unit, and the XLA_FLAGS that
    may limit what XLA uses (``--xla_cpu_max_isa=AVX2``)."""
    return f"{os.cpu_count()} cores, {cpu_model()}, {cpu_isa()}, XLA_FLAGS {os.environ.get('XLA_FLAGS') or 'none'}"


def with_peer_block(text: str, block: str) -> str:
    """``text`` with its peer block (between :data:`PEER_START` and :data:`PEER_END`) replaced by ``block``, or
    ``block`` appended where it has none; the rest unchanged."""
    if PEER_START in text and PEER_END in text:
        return text[: text.index(PEER_START)] + block + text[text.index(PEER_END) + len(PEER_END) :]
    return (text.rstrip("\n") + "\n\n" if text.strip() else "") + block + "\n"


def kept_peer(md: Path, js: Path) -> tuple[str | None, dict | None]:
    """The peer block and JSON a previous run left in the results files (None where there is none)."""
    text = md.read_text() if md.exists() else ""
    block = None
    if PEER_START in text and PEER_END in text:
        block = text[text.index(PEER_START) : text.index(PEER_END) + len(PEER_END)]
    payload = json.loads(js.read_text()).get("peer") if js.exists() else None
    return block, payload


def write_peer_section(md: Path, js: Path, block: str, payload: dict) -> None:
    """Put the peer block into ``md`` and the peer JSON under ``"peer"`` in ``js``, keeping everything else in
    both; each written atomically."""
    write_atomic(md, with_peer_block(md.read_text() if md.exists() else "", block))
    data = json.loads(js.read_text()) if js.exists() else {}
    write_atomic(js, json.dumps(data | {"peer": payload}, indent=1) + "\n")


def _fmt(x, digits=3):
    return "–" if x is None else f"{x:.{digits}f}"


def figure(curves: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    splits = sorted({s for _, s in curves}, key=list(SPLITS).index)
    fig, axes = plt.subplots(1, len(splits), figsize=(5.2 * len(splits), 4.2), squeeze=False)
    for ax, split in zip(axes[0], splits):
        for (name, s), (cov, acc, point) in curves.items():
            if s != split:
                continue
            (line,) = ax.plot(cov, acc, label=f"{name}: {REDUCERS[name]}")
            ax.plot(*point, "o", color=line.get_color())
        ax.set_xlabel("coverage (share of texts acted on, most confident first)")
        ax.set_ylabel("accuracy of the acted-on texts")
        ax.set_title(f"risk-coverage, {split} (dot: the reducer's own threshold)", fontsize=9)
        ax.set_ylim(0.4, 1.01)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(path)
    return path


def confusion_figure(true, pred, path: Path, title: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [*INTENTS, "none"]
    cm = np.zeros((len(labels), len(labels)), int)
    np.add.at(cm, (true, pred), 1)
    fig, ax = plt.subplots(figsize=(8.5, 7.5))
    im = ax.imshow(cm, cmap="Blues")
    for i, j in zip(*np.nonzero(cm)):
        color = "white" if cm[i, j] > cm.max() / 2 else "black"
        ax.text(j, i, str(cm[i, j]), ha="center", va="center", fontsize=7, color=color)
    ax.set_xticks(range(len(labels)), labels, rotation=60, ha="right", fontsize=8)
    ax.set_yticks(range(len(labels)), labels, fontsize=8)
    ax.set_xlabel("grounded (none: held as no behaviour)")
    ax.set_ylabel("true")
    ax.set_title(title, fontsize=10)
    fig.colorbar(im, ax=ax, shrink=0.8)
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(path)
    return path


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

    head = semantic_head.load()
    test = splits["v2 test"]
    n_motion = sum(it["intent"] != "none" for it in test)
    lines = [
        f"Selective grounding on the frozen test splits: {SPLITS['v2 test'].relative_to(ROOT)} ({len(test)} texts: "
        f"{n_motion} call for a motion in five styles, {len(test) - n_motion} for none) and the plainly worded "
        f"{SPLITS['plain test'].relative_to(ROOT)} ({len(splits['plain test'])}). Never tuned on; dev splits chose and "
        "calibrated the head. Each text grounded alone, warm, in one run for every reducer.",
        "",
        "Columns: intent = intent accuracy on motion texts; acted = share of motion texts acted on (confident); "
        "conf. wrong = acted on with the wrong intent (share of motion texts); none held = share of no-behaviour "
        "texts not acted on (1 - motions where none was asked); exact / within one = intensity on motion texts; "
        "ECE = 10 bins of the intent confidence, all texts.",
        "",
    ]
    for split in splits:
        lines += [
            f"#### {split}",
            "",
            "| reducer | style | n | intent | acted | conf. wrong | none held | exact | within one | ECE |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        styles = [k[2] for k in res if k[0] == "new" and k[1] == split]
        for name in REDUCERS:
            for s in styles:
                r = res[(name, split, s)]
                lines.append(
                    f"| {name} | {'**all**' if s == 'all' else s} | {r['n']} | {_fmt(r['intent'])} | {_fmt(r['acted'])} "
                    f"| {_fmt(r['confident_wrong'])} | {_fmt(r['none_held'])} | {_fmt(r['exact'])} "
                    f"| {_fmt(r['within_one'])} | {_fmt(r['ece'])} |"
                )
        lines.append("")
    for split, items in v3.items():
        n_none = sum(it["intent"] == "none" for it in items)
        kinds = len({it["style"] for it in items if it["intent"] == "none"})
        motion_styles = sorted({it["style"] for it in items if it["intent"] != "none"})
        contents = [f"{n_none} call for no motion in {kinds} kinds"] if n_none else []
        contents += [f"{sum(it['style'] == st for it in items)} {st}" for st in motion_styles]
        lines += [
            f"#### {split} ({BENCH_V3[split].relative_to(ROOT)}, {len(items)} texts: {', '.join(contents)}; written "
            "blind, frozen, read only here)",
            "",
            "Columns: n; intent = intent accuracy on the motion texts; acted = share of them acted on; none held = "
            "share of no-motion texts held; conf. wrong = acted on with the wrong intent (share of motion texts); "
            "exact = intensity exact on motion texts; rule, detector = texts the no-motion rule held, and texts the "
            "learned no-motion detector held (`new` only; on motion texts these are false holds). `new, no rule`: "
            "the shipped head without the no-motion decision (rule and detector)."
            + (
                f" `{SECOND_READER}`: a second reading of every text by a helper who saw only the texts and a labelling "
                f"brief ({SECOND_READER_FILE}), against the writer's labels: the human reference."
                if readers[split]
                else ""
            ),
            "",
            "| reducer | style | n | intent | acted | none held | conf. wrong | exact | rule | detector |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        styles = ["all", *sorted({it["style"] for it in items})]
        for name in ["new", NO_RULE, "old", "cues", *([SECOND_READER] if readers[split] else [])]:
            for s in styles:
                r = res[(name, split, s)]
                held = sum(rule_held[split].values()) if s == "all" else rule_held[split][s]
                learned = sum(learned_held[split].values()) if s == "all" else learned_held[split][s]
                lines.append(
                    f"| {name} | {'**all**' if s == 'all' else s} | {r['n']} | {_fmt(r['intent'])} | {_fmt(r['acted'])} "
                    f"| {_fmt(r['none_held'])} | {_fmt(r['confident_wrong'])} | {_fmt(r['exact'])} "
                    f"| {held if name == 'new' else ''} "
                    f"| {learned if name == 'new' else ''} |"
                )
        lines.append("")
    lines += [
        f"#### Latency (ms per response, each text alone, both test splits, {TIMING_PASSES} passes per reducer in "
        f"rotated order; {machine()}; shared with other work: load average "
        f"{load[0]:.1f} before and {os.getloadavg()[0]:.1f} after the timed runs)",
        "",
        "| reducer | warm median | p99 | median of each pass |",
        "|---|---|---|---|",
        *[
            f"| {n} | {latency[n]['ms_median']:.2f} | {latency[n]['ms_p99']:.2f} | "
            f"{', '.join(f'{x:.2f}' for x in latency[n]['ms_median_per_pass'])} |"
            for n in REDUCERS
        ],
        *(
            [
                f"| new, process pinned to one core (CPU {pinned['core']}; load average {load_pinned:.1f} before) "
                f"| {pinned['ms_median']:.2f} | {pinned['ms_p99']:.2f} | |"
            ]
            if pinned
            else []
        ),
        "",
        f"First `jg.ground` in a fresh process ({machine()}; import, weights, compile or cache load): "
        f"{np.median(first_warm):.2f} s "
        f"with the compilation cache warm (median of 3: {', '.join(f'{x:.2f}' for x in first_warm)}), "
        f"{first_cold:.2f} s with an empty cache. Batched (`jg.ground_many`, v2 test at once, warm, median of 3): {batched_ms:.2f} ms "
        "per response.",
        "",
    ]
    if parts:
        lines += [
            f"Where a warm `jg.ground` of one text goes (same texts, {machine()}, load average "
            f"{os.getloadavg()[0]:.1f}): "
            f"{parts['prep_ms_median']:.2f} ms median preparing the inputs in Python (structure rules, tokenizer, "
            f"span pools, cues), {parts['program_ms_median']:.2f} ms (p99 {parts['program_ms_p99']:.2f}) in the one "
            f"compiled program (the encoder's {parts['encoder_layers']} layers at the text's token bucket, then the "
            "head); the rest of the "
            "warm median is Python around them (checks, caveats, the Grounding). The program by bucket:",
            "",
            "| token bucket | texts | program, median ms | encoder products, GFLOP | GFLOP/s | share of peak |",
            "|---|---|---|---|---|---|",
            *[
                f"| {b} | {v['n']} | {v['program_ms_median']:.2f} | {v['gflop']:.3f} | {v['gflops']:.0f} "
                f"| {100 * v['gflops'] / peak:.0f} % |"
                for b, v in parts["by_bucket"].items()
            ],
            "",
            f"GFLOP/s: the encoder's matrix products (`encoder.matmul_flops`: the six dense products and attention's "
            f"two per layer; norms, GELU, softmax, the head and the vote left out) over the whole program's median "
            f"time, a lower bound on the rate; peak: {peak_text}.",
            "",
            f"The encoder alone on the v2 test texts ({machine()}), one at a time, by how its dense matrices are "
            f"stored (widened to float32 in the program; grounding keeps {precision['shipped']}), rotating text by "
            "text: "
            + ", ".join(
                f"{k} {precision['ms'][k]:.2f} ms ({precision['speedup'][k]:.2f}x float32)" for k in precision["ms"]
            )
            + ".",
            "",
        ]
    checks = goal_rows(res, latency, first_warm)
    lines += [
        f"#### Goals (v2 test, the shipped head; timings on {machine()})",
        "",
        "| goal | met | measured |",
        "|---|---|---|",
    ]
    lines += [f"| {g} | {'yes' if ok else '**no**'} | {v} |" for _, g, ok, v in checks]
    if tried := shortfalls(checks):
        lines += ["", "What was tried for each goal not met:", "", *[f"- {m}" for m in tried]]
    checks_34 = blind_goal_rows(res, list(v3))
    lines += [
        "",
        "#### Goals of #34 (the frozen blind benches; the v2 test split for the motion styles they do not hold)",
        "",
        "Second reader: the same measure of the bench's second reading (`second_reader.jsonl`: a helper who saw "
        "only the texts and a labelling brief labelled every text again), where it has one; a human reading has no "
        "confidence, so no confident-wrong or ECE. A goal above it asks more than two readers agree on.",
        "",
        "| goal | met | measured | second reader |",
        "|---|---|---|---|",
        *[f"| {g} | {'yes' if ok else '**no**'} | {v} | {ref} |" for _, g, ok, v, ref in checks_34],
    ]
    lines += [
        "",
        f"Shipped head: option `{head.meta.get('selected')}`, temperature {head.temperature:.2f} fitted on v2 dev and the blind situation hold-outs, "
        f"confidence threshold {head.threshold:.3f} on v2 dev and the blind situation hold-outs "
        f"(tools.train_semantics.calibrate_threshold); params {head.meta['params_digest']}.",
    ]
    fig = figure(curves, RESULTS / "semantics_risk_coverage.png")
    true = [len(INTENTS) if it["intent"] == "none" else INTENTS.index(it["intent"]) for it in test]
    pred = [
        INTENTS.index(g.intent) if g.confident or "no behaviour" not in g.reason else len(INTENTS) for g in new_preds
    ]
    conf_fig = confusion_figure(
        true,
        pred,
        RESULTS / "semantics_confusion.png",
        f"jg.ground on the v2 test split (intent {res[('new', 'v2 test', 'all')]['intent']:.3f})",
    )
    lines += ["", f"Risk-coverage curves: {fig.relative_to(ROOT)}; confusion matrix: {conf_fig.relative_to(ROOT)}"]
    print(f"CPU: {cpu_model()}")
    print("\n".join(lines))
    peer_block, peer_payload = peer or kept_peer(RESULTS / "bench_semantics.md", RESULTS / "bench_semantics.json")
    md = "\n".join(lines) + "\n"
    write_atomic(RESULTS / "bench_semantics.md", with_peer_block(md, peer_block) if peer_block else md)
    payload = {
        "metrics": {f"{n}|{sp}|{st}": v for (n, sp, st), v in res.items()},
        "latency": latency,
        "load_average": [load[0], os.getloadavg()[0]],
        "cpu": cpu_model(),
        "blind_rule_held": rule_held,  # {bench: {style: texts held by the rule}}
        "blind_detector_held": learned_held,
        "first_call_s": {"cache_warm": first_warm, "cache_cold": first_cold},
        "batched_ms_per_response": batched_ms,
        "breakdown": parts,
        "matrix_precision": precision,
        "one_core": pinned,
        "goals": {g: {"met": bool(ok), "measured": v} for _, g, ok, v in checks},
        "goals_34": {
            g: {"met": bool(ok), "measured": v, **({"second_reader": ref} if ref else {})}
            for _, g, ok, v, ref in checks_34
        },
        "head": {k: head.meta.get(k) for k in ("selected", "temperature", "threshold", "params_digest")},
        "peer": peer_payload,
        "risk_coverage": {
            f"{n}|{sp}": {"coverage": c[::4].round(4).tolist(), "accuracy": a[::4].round(4).tolist()}
            for (n, sp), (c, a, _) in curves.items()
        },
    }
    write_atomic(RESULTS / "bench_semantics.json", json.dumps(payload, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
