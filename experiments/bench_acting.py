"""Act when asked, on the frozen blind benches: the shipped act/hold decision before and after it became one
decision per kind of text, read once: `python -m experiments.bench_acting`.

Reads the frozen blind benches of ``experiments.bench_semantics`` (:data:`experiments.bench_semantics.BENCH_V3`,
through its own reader; nothing here is fitted or selected) and grounds each text once, alone, as ``jg.ground`` does
(the shipped head's pass with its sentence vector). The same pass gives both decisions:

- **before**: one threshold, the head's calibrated one, for every text, then the no-motion decision at the
  detector's own threshold (:func:`jgrounding.semantics.nomotion.apply`): ``jg.ground`` as it was shipped;
- **after**: :func:`jgrounding.semantics.decision.decide` at the shipped operating point: ``jg.ground`` now.

One table (``results/bench_acting.md`` and ``.json``): for texts that ask outright (every motion style but
situation-only: contrast and mixed on these benches) and for situations, the share acted on with the right intent,
held, and acted on with a wrong intent, and for texts that call for no motion the share held; then the measure a user
feels, the share of explicit motion requests (texts that ask outright) acted on, and the expected cost
(:data:`jgrounding.semantics.decision.COSTS`) per text. Against the goals: acted right >= 0.97 outright and >= 0.85 on
situations, no-motion held >= 0.95, acted wrong <= 1 % (:data:`GOALS`).

    python -m experiments.bench_acting            # about 5,400 texts: some minutes on 2 busy cores
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from experiments import bench_semantics
from experiments import bench_semantics_scores as bs

OUT = bs.RESULTS / "bench_acting"
GOALS = {"outright": 0.97, "situation": 0.85, "none_held": 0.95, "acted_wrong": 0.01}
GROUPS = ("outright", "situation")


def before_and_after(text: str):
    """The grounding of ``text`` by the decision before (one threshold) and after (per kind), from one pass."""
    from jgrounding.semantics import decision, embedded, nomotion, structure
    from jgrounding.semantics import head as semantic_head

    (g,), vectors = embedded.ground_embedded_vectors([text], threshold=0.0)
    v = None if vectors is None else vectors[0]
    st = structure.spans(text)
    t = semantic_head.load().threshold
    old = g
    if g.confident and g.confidence < t:  # what the head's own threshold did before
        old = dataclasses.replace(g, confident=False, reason=f"low confidence: below the calibrated threshold {t:.2f}")
    return nomotion.apply(text, old, st, v), decision.decide(text, g, st, v)


def group(item: dict) -> str:
    """``none``, ``situation`` or ``outright`` (every other motion style: the text asks for its motion)."""
    if item["intent"] == "none":
        return "none"
    return "situation" if item["style"] == "situation" else "outright"


def figures(items: list[dict], preds: list) -> dict:
    """Per group of :data:`GROUPS`: acted right, held and acted wrong (shares of its motion texts); no-motion held;
    explicit requests acted on; the expected cost per text."""
    from jgrounding.semantics.decision import cost

    kinds = np.array([group(it) for it in items])
    acted = np.array([g.confident for g in preds])
    right = np.array([g.intent == it["intent"] for g, it in zip(preds, items)])
    out = {}
    for name in GROUPS:
        m = kinds == name
        out[name] = {
            "n": int(m.sum()),
            "acted_right": float((acted & right)[m].mean()),
            "held": float((~acted)[m].mean()),
            "acted_wrong": float((acted & ~right)[m].mean()),
        }
    motion = kinds != "none"
    out["none"] = {"n": int((~motion).sum()), "held": float((~acted)[~motion].mean())}
    out["explicit_acted"] = float(acted[kinds == "outright"].mean())
    out["acted_wrong"] = float((acted & ~right)[motion].mean())
    out["cost"] = float(np.mean([cost(mo, a, r) for mo, a, r in zip(motion, acted, right)]))
    return out


def table(res: dict) -> str:
    b, a = res["before"], res["after"]
    f = lambda x: f"{x:.3f}"  # noqa: E731
    rows = [
        "| frozen blind benches | n | before (one threshold) | after (per kind) | goal |",
        "|---|---|---|---|---|",
    ]
    for g in GROUPS:
        label = "texts that ask outright" if g == "outright" else "situations"
        for key, what in (("acted_right", "acted right"), ("held", "held"), ("acted_wrong", "acted wrong")):
            goal = f">= {GOALS[g]}" if key == "acted_right" else ""
            rows.append(f"| {label}: {what} | {a[g]['n']} | {f(b[g][key])} | {f(a[g][key])} | {goal} |")
    n_motion = a["outright"]["n"] + a["situation"]["n"]
    rows.append(
        f"| no-motion texts held | {a['none']['n']} | {f(b['none']['held'])} | {f(a['none']['held'])} | "
        f">= {GOALS['none_held']} |"
    )
    rows.append(
        f"| motion texts acted wrong | {n_motion} | {f(b['acted_wrong'])} | {f(a['acted_wrong'])} | "
        f"<= {GOALS['acted_wrong']} |"
    )
    rows.append(
        f"| explicit motion requests acted on | {a['outright']['n']} | {f(b['explicit_acted'])} | "
        f"{f(a['explicit_acted'])} | |"
    )
    rows.append(f"| expected cost per text | {n_motion + a['none']['n']} | {f(b['cost'])} | {f(a['cost'])} | |")
    return "\n".join(rows)


def goals_met(a: dict) -> dict:
    return {
        "outright": a["outright"]["acted_right"] >= GOALS["outright"],
        "situation": a["situation"]["acted_right"] >= GOALS["situation"],
        "none_held": a["none"]["held"] >= GOALS["none_held"],
        "acted_wrong": a["acted_wrong"] <= GOALS["acted_wrong"],
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=str(OUT), help="write OUT.md and OUT.json")
    args = p.parse_args(argv)
    from jgrounding import semantics
    from jgrounding.io import write_atomic
    from jgrounding.semantics import decision

    if semantics.mllm_configured():
        print("an MLLM endpoint is configured (JGROUNDING_MLLM_URL): unset it, this reads the offline decision")
        return 1
    items = [it for path in bench_semantics.BENCH_V3.values() for it in bs.read_jsonl(path)]
    point = decision.point()
    print(f"the frozen blind benches, {len(items)} texts ({bs.machine()}); operating point {point.thresholds}")
    before, after = [], []
    for i, it in enumerate(items):
        b, a = before_and_after(it["text"])
        before.append(b)
        after.append(a)
        if (i + 1) % 500 == 0 or i + 1 == len(items):
            print(f"  grounded {i + 1}/{len(items)}", flush=True)
    res = {"before": figures(items, before), "after": figures(items, after)}
    res["goals"] = GOALS
    res["goals_met_after"] = goals_met(res["after"])
    res["point"] = {"thresholds": point.thresholds, "detector": point.detector}
    res["benches"] = sorted(bench_semantics.BENCH_V3)
    text = table(res)
    print(text)
    met = res["goals_met_after"]
    verdict = "goals met after: " + ", ".join(f"{k} {'yes' if v else 'no'}" for k, v in met.items())
    print(verdict)
    out = Path(args.out)
    md = (
        f"The act/hold decision on the frozen blind benches, read once (`python -m experiments.bench_acting`; "
        f"{bs.machine()}): {len(items)} texts of {len(bench_semantics.BENCH_V3)} benches ({', '.join(sorted(bench_semantics.BENCH_V3))}), each "
        "grounded alone by the shipped head. Before: one threshold (the head's calibrated one) for every text. After: "
        "one decision per kind of text at the operating point fitted on dev "
        f"(`results/nomotion_frontier.md`: {json.dumps(point.thresholds)}, detector {point.detector}). Texts that ask "
        "outright: every motion style but situation-only.\n\n" + text + "\n\n" + verdict + "\n"
    )
    write_atomic(out.with_suffix(".md"), md)
    write_atomic(out.with_suffix(".json"), json.dumps(res, indent=1, sort_keys=True) + "\n")
    print(f"wrote {out.with_suffix('.md')} and .json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
