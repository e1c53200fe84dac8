"""The results of ``python -m experiments.bench_semantics``: ``results/bench_semantics.md`` (a table per test
split and per frozen blind bench, latency, where the time goes, the goals) and ``.json``, the risk-coverage curves
and the confusion matrix of the shipped head on the v2 test split."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from experiments.bench_sample import cpu_model
from experiments.bench_semantics_peer import kept_peer, with_peer_block
from experiments.bench_semantics_scores import (
    NO_RULE,
    REDUCERS,
    RESULTS,
    SECOND_READER,
    SECOND_READER_FILE,
    blind_goal_rows,
    fmt,
    goal_rows,
    machine,
    shortfalls,
)
from experiments.bench_semantics_timing import TIMING_PASSES
from jgrounding.io import write_atomic
from jgrounding.semantics import head as semantic_head
from jgrounding.vocabulary import INTENTS

ROOT = Path(__file__).resolve().parent.parent


def write(
    *,
    splits,
    v3,
    sets,
    res,
    curves,
    latency,
    load,
    first_warm,
    first_cold,
    batched_ms,
    parts,
    precision,
    peak,
    peak_text,
    pinned,
    load_pinned,
    rule_held,
    learned_held,
    readers,
    new_preds,
    peer,
) -> None:
    """Print the results and write ``results/bench_semantics.md`` and ``.json`` and the two figures. ``sets``: each
    test split's and blind bench's file; ``peer``: this run's peer block and JSON, or None to keep the last run's."""
    head = semantic_head.load()
    test = splits["v2 test"]
    n_motion = sum(it["intent"] != "none" for it in test)
    lines = [
        f"Selective grounding on the frozen test splits: {sets['v2 test'].relative_to(ROOT)} ({len(test)} texts: "
        f"{n_motion} call for a motion in five styles, {len(test) - n_motion} for none) and the plainly worded "
        f"{sets['plain test'].relative_to(ROOT)} ({len(splits['plain test'])}). Never tuned on; dev splits chose and "
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
                    f"| {name} | {'**all**' if s == 'all' else s} | {r['n']} | {fmt(r['intent'])} | {fmt(r['acted'])} "
                    f"| {fmt(r['confident_wrong'])} | {fmt(r['none_held'])} | {fmt(r['exact'])} "
                    f"| {fmt(r['within_one'])} | {fmt(r['ece'])} |"
                )
        lines.append("")
    for split, items in v3.items():
        n_none = sum(it["intent"] == "none" for it in items)
        kinds = len({it["style"] for it in items if it["intent"] == "none"})
        motion_styles = sorted({it["style"] for it in items if it["intent"] != "none"})
        contents = [f"{n_none} call for no motion in {kinds} kinds"] if n_none else []
        contents += [f"{sum(it['style'] == st for it in items)} {st}" for st in motion_styles]
        lines += [
            f"#### {split} ({sets[split].relative_to(ROOT)}, {len(items)} texts: {', '.join(contents)}; written "
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
                    f"| {name} | {'**all**' if s == 'all' else s} | {r['n']} | {fmt(r['intent'])} | {fmt(r['acted'])} "
                    f"| {fmt(r['none_held'])} | {fmt(r['confident_wrong'])} | {fmt(r['exact'])} "
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
        "#### The goals (the frozen blind benches; the v2 test split for the motion styles they do not hold)",
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
        f"(tools.semantics_calibration.calibrate_threshold); params {head.meta['params_digest']}.",
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


def figure(curves: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    splits = list(dict.fromkeys(s for _, s in curves))  # in the order they were run
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
