"""Selective semantic grounding on the frozen evaluation sets: `python -m experiments.bench semantics`.

Reads the TEST splits only here (never tuned on): ``assets/semantics_eval_v2/test.jsonl`` (five styles of motion
texts and eight kinds of texts that call for no motion), the plainly worded ``assets/semantics_eval/test.jsonl`` and
the frozen blind bench of #34, ``assets/semantics_eval_v3/bench.jsonl`` (nine kinds of texts that call for no motion
and contrast texts that reject one motion and choose another; this script is the only reader of that file). The v3
bench is grounded once per reducer, outside the timing, with one more row: ``new, no rule``, the shipped head without
the explicit no-motion decision (:mod:`jgrounding.semantics.nomotion`), so the rule's effect is read off one run.
Three reducers run in the same process, each text grounded alone, warm (``semantics.warmup``: every token
bucket compiled before timing):

- ``new``: the shipped trained head (``jg.ground(text)``, its defaults; no MLLM endpoint may be configured);
- ``old``: the first trained head (``assets/semantic_head_v1.npz``, the embedding + Eq. (3) head of #15);
- ``cues``: the cue-list reducer (``backend="cues"``), the baseline.

Per style and overall: intent accuracy on motion texts, the share of motion texts acted on (confident), the
confident wrong motion rate (acted on with the wrong intent, share of motion texts), the share of no-behaviour
texts held (not acted on; the rest are motions where none was asked), intensity exact / within one level, ECE
(10 bins of the intent confidence against "right intent on a motion text", over all texts) and latency (warm
median, p99; the first call in a fresh process is timed in a subprocess, with the compilation cache warm and
cold; where a warm call's time goes, :func:`breakdown`). A risk-coverage curve (accuracy of the acted-on texts, a no-behaviour text counting as wrong, against the
share acted on, texts ranked by confidence) is saved as ``results/semantics_risk_coverage.png``. Writes
``results/bench_semantics.md`` and ``.json`` and the confusion matrix ``results/semantics_confusion.png``.
"""

from __future__ import annotations

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
from jgrounding.vocabulary import INTENSITIES, INTENTS

ROOT = Path(__file__).resolve().parent.parent
SPLITS = {
    "v2 test": ROOT / "assets" / "semantics_eval_v2" / "test.jsonl",
    "plain test": ROOT / "assets" / "semantics_eval" / "test.jsonl",
}
BENCH_V3 = {"v3 bench": ROOT / "assets" / "semantics_eval_v3" / "bench.jsonl"}  # accuracy only, not timed
OLD_HEAD = ROOT / "assets" / "semantic_head_v1.npz"
REDUCERS = {
    "new": "trained head, structure-aware (jg.ground)",
    "old": "first trained head (#15)",
    "cues": "cue-list reducer (baseline)",
}
NO_RULE = "new, no rule"  # the shipped head without the no-motion decision (v3 bench, accuracy only)
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
    "writer's brief, trained on: not shipped, in the vote's table: shipped), label smoothing, four tuned layers, a "
    "lighter generated corpus, model soups, 1,920 nearest-neighbour vote variants (one shipped), a stronger encoder "
    "(none in the registry that ships its weights fits the budget): docs/how_it_works.md, section 1",
    "ms_median": "bucketed padding, one compiled program per call, float16-stored matrices, less Python per text, "
    "XNNPACK and oneDNN, bfloat16, a fused QKV product, the classic runtime; the products' rate is in the bucket "
    "table above: docs/how_it_works.md, section 1, 'Speed'",
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
    ok = (m == true) & motion

    def mean(x):
        return float(np.mean(x)) if len(x) else None

    return {
        "n": len(items),
        "n_motion": int(motion.sum()),
        "n_none": int((~motion).sum()),
        "intent": mean(ok[motion]),
        "acted": mean(acted[motion]),
        "acted_accuracy": mean(ok[motion & acted]),
        "confident_wrong": mean((acted & ~ok)[motion]),
        "none_held": mean(~acted[~motion]),
        "exact": mean((z == z_true)[motion]),
        "within_one": mean((np.abs(z - z_true) <= 1)[motion]),
        "ece": calibration.expected_calibration_error(conf, ok),
    }


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
        ms, flops = float(np.median(program[buckets == b])), encoder.matmul_flops(b)
        by_bucket[b] = {"n": int((buckets == b).sum()), "program_ms_median": ms, "gflop": flops / 1e9}
        by_bucket[b]["gflops"] = flops / 1e6 / ms
    return {
        "prep_ms_median": float(np.median(prep)),
        "program_ms_median": float(np.median(program)),
        "program_ms_p99": float(np.percentile(program, 99)),
        "by_bucket": by_bucket,
    }


def matrix_precision(texts: list[str]) -> dict:
    """The encoder alone (:func:`jgrounding.semantics.encoder.pool_ids`, one text at a time) with the dense matrices
    as grounding keeps them (float16, widened in the program) against the same matrices in float32, alternating
    text by text so both see the machine in the same state. Milliseconds (medians) and their ratio."""
    from jgrounding.semantics import structure

    head = semantic_head.load()
    half = head.encoder_params()
    full = jax.tree.map(lambda a: a.astype(np.float32), half)  # same values, float32 storage
    kinds = {"float16": half, "float32": full}
    times = {k: [] for k in kinds}
    for text in texts:
        (_, ids, mask, pools), *_ = list(features.encoder_batches([text], [structure.analyse(text)]))
        for kind, params in kinds.items():
            encoder.pool_ids(params, ids, mask, pools).block_until_ready()  # compiled (or cached) outside the timing
        for kind, params in kinds.items():
            t0 = time.perf_counter()
            encoder.pool_ids(params, ids, mask, pools).block_until_ready()
            times[kind].append(time.perf_counter() - t0)
    med = {k: float(np.median(v) * 1e3) for k, v in times.items()}
    return {"float16_ms": med["float16"], "float32_ms": med["float32"], "ratio": med["float32"] / med["float16"]}


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


def main(argv=None) -> int:
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
    splits = {name: read_jsonl(path) for name, path in SPLITS.items()}
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
    v3 = {name: read_jsonl(path) for name, path in BENCH_V3.items()}  # the only read of the frozen v3 bench
    for name in [*names, NO_RULE]:
        fn = fns.get(name) or grounder(name)
        for split, items in v3.items():
            preds = run(items, fn)[0]
            res[(name, split, "all")] = metrics(items, preds)
            for s in sorted({it["style"] for it in items}):
                group = [i for i, it in enumerate(items) if it["style"] == s]
                res[(name, split, s)] = metrics([items[i] for i in group], [preds[i] for i in group])
            if name == "new":
                rule_held = {s: 0 for s in {it["style"] for it in items}}
                for it, g in zip(items, preds):
                    rule_held[it["style"]] += bool(g.no_motion)
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
        f"Selective grounding on the frozen test splits: assets/semantics_eval_v2/test.jsonl ({len(test)} texts: "
        f"{n_motion} call for a motion in five styles, {len(test) - n_motion} for none) and the plainly worded "
        f"assets/semantics_eval/test.jsonl ({len(splits['plain test'])}). Never tuned on; dev splits chose and "
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
        lines += [
            f"#### {split} (assets/semantics_eval_v3/bench.jsonl, {len(items)} texts: {n_none} call for no motion in "
            f"nine kinds, {len(items) - n_none} contrast texts; written blind, frozen, read only here)",
            "",
            "Columns: n; intent = intent accuracy on the contrast texts; acted = share of them acted on; none held = "
            "share of no-motion texts held; conf. wrong = acted on with the wrong intent (share of contrast texts); "
            "rule = texts the no-motion rule held (`new` only). `new, no rule`: the shipped head without the rule.",
            "",
            "| reducer | style | n | intent | acted | none held | conf. wrong | rule |",
            "|---|---|---|---|---|---|---|---|",
        ]
        styles = ["all", *sorted({it["style"] for it in items})]
        for name in ["new", NO_RULE, "old", "cues"]:
            for s in styles:
                r = res[(name, split, s)]
                held = sum(rule_held.values()) if s == "all" else rule_held[s]
                lines.append(
                    f"| {name} | {'**all**' if s == 'all' else s} | {r['n']} | {_fmt(r['intent'])} | {_fmt(r['acted'])} "
                    f"| {_fmt(r['none_held'])} | {_fmt(r['confident_wrong'])} | {held if name == 'new' else ''} |"
                )
        lines.append("")
    lines += [
        f"#### Latency (ms per response, each text alone, both test splits, {TIMING_PASSES} passes per reducer in "
        f"rotated order; {os.cpu_count()} CPU cores ({cpu_model()}, {cpu_isa()}) shared with other work: load average "
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
        f"First `jg.ground` in a fresh process (import, weights, compile or cache load): {np.median(first_warm):.2f} s "
        f"with the compilation cache warm (median of 3: {', '.join(f'{x:.2f}' for x in first_warm)}), "
        f"{first_cold:.2f} s with an empty cache. Batched (`jg.ground_many`, v2 test at once, warm, median of 3): {batched_ms:.2f} ms "
        "per response.",
        "",
    ]
    if parts:
        lines += [
            f"Where a warm `jg.ground` of one text goes (same texts, load average {os.getloadavg()[0]:.1f}): "
            f"{parts['prep_ms_median']:.2f} ms median preparing the inputs in Python (structure rules, tokenizer, "
            f"span pools, cues), {parts['program_ms_median']:.2f} ms (p99 {parts['program_ms_p99']:.2f}) in the one "
            "compiled program (the six encoder layers at the text's token bucket, then the head); the rest of the "
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
            f"The encoder alone on the v2 test texts, one at a time, with its dense matrices stored in float16 as "
            f"grounding keeps them (widened to float32 in the program): {precision['float16_ms']:.2f} ms median, "
            f"against {precision['float32_ms']:.2f} ms with the same matrices stored in float32, alternating text by "
            f"text ({precision['ratio']:.2f}x).",
            "",
        ]
    checks = goal_rows(res, latency, first_warm)
    lines += ["#### Goals (v2 test, the shipped head)", "", "| goal | met | measured |", "|---|---|---|"]
    lines += [f"| {g} | {'yes' if ok else '**no**'} | {v} |" for _, g, ok, v in checks]
    if tried := shortfalls(checks):
        lines += ["", "What was tried for each goal not met:", "", *[f"- {m}" for m in tried]]
    lines += [
        "",
        f"Shipped head: option `{head.meta.get('selected')}`, temperature {head.temperature:.2f} and confidence "
        f"threshold {head.threshold:.3f} fitted on v2 dev; params {head.meta['params_digest']}.",
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
    write_atomic(RESULTS / "bench_semantics.md", "\n".join(lines) + "\n")
    payload = {
        "metrics": {f"{n}|{sp}|{st}": v for (n, sp, st), v in res.items()},
        "latency": latency,
        "load_average": [load[0], os.getloadavg()[0]],
        "cpu": cpu_model(),
        "v3_rule_held": rule_held if v3 else {},
        "first_call_s": {"cache_warm": first_warm, "cache_cold": first_cold},
        "batched_ms_per_response": batched_ms,
        "breakdown": parts,
        "matrix_precision": precision,
        "one_core": pinned,
        "goals": {g: {"met": bool(ok), "measured": v} for _, g, ok, v in checks},
        "head": {k: head.meta.get(k) for k in ("selected", "temperature", "threshold", "params_digest")},
        "risk_coverage": {
            f"{n}|{sp}": {"coverage": c[::4].round(4).tolist(), "accuracy": a[::4].round(4).tolist()}
            for (n, sp), (c, a, _) in curves.items()
        },
    }
    write_atomic(RESULTS / "bench_semantics.json", json.dumps(payload, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
