"""The act/hold decision's operating point, chosen by its expected cost on the dev sets: the thresholds per kind of
text and the learned no-motion detector's threshold (:mod:`jgrounding.semantics.decision`).

    python -m tools.nomotion_frontier            # print the frontier and the chosen point, write results/nomotion_frontier.*
    python -m tools.nomotion_frontier --write    # ... and ship the chosen point (jgrounding/assets/operating_point.json)
    python -m tools.nomotion_frontier --check    # exit 1 when the shipped point is not the one dev chooses (writes nothing)
    python -m tools.nomotion_frontier --quick    # a few texts of each set (a smoke run; writes nothing unless --out)

The costs are :data:`jgrounding.semantics.decision.COSTS` (a motion text held 1, a no-motion text acted on 3, a wrong
intent acted on 5; the reasons are there). Every dev set of ``tools.semantics_system_dev`` is pooled, each text once,
so texts that choose a motion, situations and texts that call for no motion weigh as their dev shares; no frozen
bench is read. Each text is grounded alone as :func:`jgrounding.semantics.ground` grounds it (the head with no
threshold, its sentence vector, the rule, the chosen-motion clause and the detector's p), then the decision is
computed at every point of a grid: the detector's threshold (:data:`DETECTOR_GRID`) and, for each, each kind's
threshold (:data:`GRID`) independently (a kind's threshold changes only its own texts' decisions). The chosen point
is the grid point of least expected cost (ties: the middle of the tied thresholds, :func:`middle`). The frontier is the held share of
motion texts against the share of no-motion texts acted on and of wrong intents acted on.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from experiments import bench_semantics_scores as bs
from tools import semantics_system_dev as sd

GRID = tuple(round(x, 3) for x in np.arange(0.0, 1.0, 0.025)) + (1.01,)  # 1.01: that kind never acts
DETECTOR_GRID = (0.1, 0.2, 0.3, 0.4, 0.5, 0.5375, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99, 1.01)  # 1.01: the rule alone
OUT = bs.RESULTS / "nomotion_frontier"
BEFORE = "one threshold"  # the decision before it was per kind: the head's threshold on its own confidence


def records(sets: dict[str, list[dict]]) -> dict:
    """Per text (all sets in order), what the decision reads: arrays ``motion``, ``right`` (the head's intent is the
    text's), ``confidence`` (an order's: :func:`jgrounding.semantics.decision.order_confidence`), ``reducer_held``
    (the head's caveats or no-behaviour class), ``overridable`` (held only by the no-behaviour class, which an order
    overrides), ``rule`` (the rule would hold), ``chosen`` (a clause chooses a motion), ``detector`` (the learned
    detector's p), ``kind``, ``set``, ``style`` (the writer's: ``situation`` or ``outright``, every other style, as
    ``experiments.bench_acting`` groups the frozen benches), and the texts."""
    from jgrounding.semantics import decision, embedded, nomotion, structure

    det = nomotion.detector()
    if det is None:
        raise SystemExit("the shipped detector is off (made for another head): retrain it with tools.train_nomotion")
    keys = (
        "motion",
        "right",
        "confidence",
        "head_confidence",
        "reducer_held",
        "overridable",
        "rule",
        "chosen",
        "detector",
        "kind",
    )
    cols = {k: [] for k in keys}
    cols |= {"set": [], "style": [], "text": []}
    n = sum(len(items) for items in sets.values())
    done = 0
    for name, items in sets.items():
        for it in items:
            text = it["text"]
            (g,), vectors = embedded.ground_embedded_vectors([text], threshold=0.0)
            st = structure.spans(text)
            k, named = decision.kind(text, g.intent, st)
            cols["motion"].append(it["intent"] != "none")
            cols["right"].append(g.intent == it["intent"])
            cols["confidence"].append(decision.order_confidence(g, named) if k == "order" else g.confidence)
            cols["head_confidence"].append(g.confidence)
            cols["reducer_held"].append(not g.confident)
            cols["overridable"].append(decision.reads_as_no_behaviour(text, g))
            cols["rule"].append(nomotion.rule(text, st) is not None)
            cols["chosen"].append(nomotion.chosen_motion(text, st) is not None)
            cols["detector"].append(float(det.probability(vectors[0][None])[0]))
            cols["kind"].append(k)
            cols["set"].append(name)
            style = it.get("style")
            cols["style"].append(
                "none" if it["intent"] == "none" else "situation" if style == "situation" else "outright"
            )
            cols["text"].append(text)
            done += 1
            if done % 250 == 0 or done == n:
                print(f"  grounded {done}/{n} dev texts", flush=True)
    return {k: np.array(v) for k, v in cols.items()}


def held(r: dict, thresholds: dict, detector: float) -> np.ndarray:
    """Which texts the decision holds at a point (``thresholds`` per kind, the detector's threshold): the same
    decision as :func:`jgrounding.semantics.decision.decide`, on :func:`records`' arrays."""
    no_motion, unsure = held_parts(r, thresholds, detector)
    return no_motion | unsure


def held_parts(r: dict, thresholds: dict, detector: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`held` in its two parts: held by the no-motion decision (the rule, the detector, the head's caveats and
    no-behaviour class), and held by the threshold of the text's kind (the rest of the holds)."""
    no_motion = (r["rule"] | (r["detector"] >= detector)) & ~r["chosen"]
    no_motion |= r["reducer_held"] & ~((r["kind"] == "order") & r["overridable"])
    t = np.array([thresholds[k] for k in r["kind"]], float) if len(r["kind"]) else np.zeros(0)
    return no_motion, ~no_motion & (r["confidence"] < t)


def held_parts_before(r: dict, threshold: float, detector: float) -> tuple[np.ndarray, np.ndarray]:
    """The decision before it was made per kind of text, in :func:`held_parts`' two parts: one ``threshold`` on the
    head's own confidence for every text, and no order overriding the head's no-behaviour class."""
    no_motion = ((r["rule"] | (r["detector"] >= detector)) & ~r["chosen"]) | r["reducer_held"]
    return no_motion, ~no_motion & (r["head_confidence"] < threshold)


def costs(r: dict, hold: np.ndarray) -> np.ndarray:
    """Each text's cost (:data:`jgrounding.semantics.decision.COSTS`) under the decision ``hold``."""
    from jgrounding.semantics.decision import COSTS

    acted = ~hold
    return np.where(
        r["motion"],
        np.where(acted, np.where(r["right"], 0.0, COSTS["acted_wrong"]), COSTS["held_motion"]),
        np.where(acted, COSTS["acted_no_motion"], 0.0),
    )


def figures(r: dict, hold: np.ndarray, mask=None) -> dict:
    """Cost and shares of a decision over the texts in ``mask`` (default all)."""
    mask = np.ones(len(hold), bool) if mask is None else mask
    m, nm = r["motion"] & mask, ~r["motion"] & mask
    acted = ~hold

    def share(x, of):
        return float(x[of].mean()) if of.any() else None

    return {
        "n": int(mask.sum()),
        "n_motion": int(m.sum()),
        "n_none": int(nm.sum()),
        "cost": float(costs(r, hold)[mask].mean()) if mask.any() else None,
        "intent": share(r["right"], m),
        "acted_right": share(acted & r["right"], m),
        "held_motion": share(hold, m),
        "acted_wrong": share(acted & ~r["right"], m),
        "none_held": share(hold, nm),
    }


def choose(r: dict) -> tuple[dict, float, list]:
    """The least-cost point: ``(thresholds per kind, detector threshold, rows)``, ``rows`` the best point at each
    detector threshold with its cost (the frontier's points). A kind's threshold changes only its own texts'
    decisions, so each is chosen alone for every detector threshold (ties: :func:`middle`)."""
    from jgrounding.semantics.decision import KINDS

    rows = []
    for d in DETECTOR_GRID:
        best = {}
        for k in KINDS:
            mine = r["kind"] == k
            totals = [costs(r, held(r, dict.fromkeys(KINDS, t), d))[mine].sum() for t in GRID]
            best[k] = float(middle(GRID, totals))
        rows.append((best, d, float(costs(r, held(r, best, d)).mean())))
    detector = float(middle([d for _, d, _ in rows], [c for _, _, c in rows]))
    return next(t for t, d, _ in rows if d == detector), detector, rows


def middle(values, totals):
    """The value of least total; on a tie, the middle one of the tied values (sorted): a point inside a flat
    stretch of the cost rather than at its edge, where the next dev text would move it."""
    low = min(round(float(t), 9) for t in totals)
    tied = sorted(v for v, t in zip(values, totals) if round(float(t), 9) == low)
    return tied[len(tied) // 2]


def sweep(r: dict, thresholds: dict, detector: float) -> list[tuple[float, dict]]:
    """The frontier through the chosen point: every kind's threshold shifted by the same amount (``delta``), the
    detector's fixed."""
    from jgrounding.semantics.decision import KINDS

    out = []
    for delta in np.arange(-0.5, 0.301, 0.05):
        shifted = {k: float(np.clip(thresholds[k] + delta, 0.0, 1.01)) for k in KINDS}
        out.append((round(float(delta), 3), figures(r, held(r, shifted, detector))))
    return out


def report(r: dict, shipped, chosen: tuple[dict, float], rows, frontier) -> tuple[str, dict]:
    """The markdown and JSON of a run: the chosen point against the shipped one, by kind and by dev set."""
    from jgrounding.semantics import decision
    from jgrounding.semantics.decision import COST_REASONS, COSTS, KINDS

    one = decision.fallback_point()
    points = {BEFORE: (one.thresholds, one.detector), "shipped": (shipped.thresholds, shipped.detector)}
    points["chosen"] = chosen
    res = {}
    for label, (t, d) in points.items():
        by_no_motion, by_threshold = held_parts_before(r, t[KINDS[0]], d) if label == BEFORE else held_parts(r, t, d)
        hold = by_no_motion | by_threshold
        res[label] = {"thresholds": t, "detector": d, "all": figures(r, hold)}
        res[label] |= {f"kind {k}": figures(r, hold, r["kind"] == k) for k in KINDS}
        res[label] |= {f"style {s}": figures(r, hold, r["style"] == s) for s in ("outright", "situation")}
        for s in ("outright", "situation"):
            m = r["style"] == s
            res[label][f"style {s}"]["held_by_no_motion"] = float(by_no_motion[m].mean())
            res[label][f"style {s}"]["held_by_threshold"] = float(by_threshold[m].mean())
        res[label] |= {f"set {s}": figures(r, hold, r["set"] == s) for s in dict.fromkeys(r["set"].tolist())}
    f = bs.fmt
    lines = [
        "| point | " + " | ".join(f"{k} threshold" for k in KINDS) + " | detector | expected cost | motion acted right "
        "| motion held | wrong intent acted | no-motion held |",
        "|---|" + "---|" * (len(KINDS) + 6),
    ]
    for label, row in res.items():
        a = row["all"]
        cells = [f(row["thresholds"][k]) for k in KINDS] + [f(row["detector"], 4), f(a["cost"], 4)]
        cells += [f(a[k]) for k in ("acted_right", "held_motion", "acted_wrong", "none_held")]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    by = [
        "| group | n (motion / none) | cost one threshold / chosen | acted right | held motion | wrong acted | none held |"
    ]
    by.append("|---|---|---|---|---|---|---|")
    for g in [k for k in res["chosen"] if k != "all" and k not in ("thresholds", "detector")]:
        s, c = res[BEFORE][g], res["chosen"][g]
        pair = lambda k: f"{f(s[k])} / {f(c[k])}"  # noqa: E731
        by.append(
            f"| {g} | {c['n_motion']} / {c['n_none']} | {pair('cost')} | {pair('acted_right')} | "
            f"{pair('held_motion')} | {pair('acted_wrong')} | {pair('none_held')} |"
        )
    why = [
        "| motion texts (writer's style) | right intent, acted or not | acted right | held by the no-motion decision "
        "| held by the threshold | acted wrong |"
    ]
    why.append("|---|---|---|---|---|---|")
    for st in ("outright", "situation"):
        c = res["chosen"][f"style {st}"]
        cells = [c[k] for k in ("intent", "acted_right", "held_by_no_motion", "held_by_threshold", "acted_wrong")]
        why.append(f"| {st} | " + " | ".join(f(x) for x in cells) + " |")
    det = [
        "| detector threshold | best kind thresholds (order / chosen / situation) | expected cost |",
        "|---|---|---|",
    ]
    det += [f"| {d:.4f} | {' / '.join(f(t[k]) for k in KINDS)} | {c:.4f} |" for t, d, c in rows]
    costs_md = "\n".join(f"- {k.replace('_', ' ')}: **{COSTS[k]:g}**: {COST_REASONS[k]}" for k in COSTS)
    md = "\n\n".join(
        [
            "The act/hold decision's operating point on the dev sets (`python -m tools.nomotion_frontier`; "
            f"{bs.machine()}): {len(r['motion'])} texts of `tools.semantics_system_dev`'s sets pooled "
            f"({int(r['motion'].sum())} call for a motion, {int((~r['motion']).sum())} for none), each grounded alone "
            "as `jg.ground` grounds it; no frozen bench read. The costs:\n\n" + costs_md,
            "![frontier](nomotion_frontier.png)",
            "\n".join(lines),
            "One threshold: the decision as `jg.ground` made it before it was made per kind of text, the head's "
            "calibrated threshold on its own confidence for every text (no order's reading among the gestures it "
            "names, no order overriding the no-behaviour class) and the detector's own threshold. By kind of text "
            "(the decision's own split, `decision.kind`) and by dev set, one threshold / chosen:\n\n" + "\n".join(by),
            "What holds the motion texts at the chosen point, by the writer's style (outright: every style but "
            "situation-only):\n\n" + "\n".join(why),
            "The least cost at each detector threshold (each kind's threshold chosen for it):\n\n" + "\n".join(det),
        ]
    )
    payload = {"costs": COSTS, "points": res, "per_detector": [[t, d, c] for t, d, c in rows]}
    payload["frontier"] = [[delta, fig] for delta, fig in frontier]
    return md + "\n", payload


def figure(frontier, res, path) -> None:
    """Held motion texts against no-motion texts acted on and wrong intents acted on, the kinds' thresholds shifted
    together through the chosen point; the shipped and chosen points marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from jgrounding.apps import plotting

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    x = [fg["held_motion"] for _, fg in frontier]
    ax.plot(x, [1 - fg["none_held"] for _, fg in frontier], "o-", ms=3, label="no-motion texts acted on")
    ax.plot(x, [fg["acted_wrong"] for _, fg in frontier], "s-", ms=3, label="motion texts acted on, wrong intent")
    for label, marker in ((BEFORE, "x"), ("chosen", "*")):
        a = res[label]["all"]
        ax.plot([a["held_motion"]], [1 - a["none_held"]], marker, color="k", ms=9, label=f"{label} point")
        ax.plot([a["held_motion"]], [a["acted_wrong"]], marker, color="k", ms=9)
    ax.set_xlabel("motion texts held (share)")
    ax.set_ylabel("share")
    ax.set_title("dev sets: every kind's threshold shifted together (detector fixed)", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    plotting.save(fig, path)  # atomic, closes the figure


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=None, help=f"write OUT.md, OUT.json and OUT.png (default {OUT}; --quick: none)")
    p.add_argument("--write", action="store_true", help="ship the chosen point: jgrounding/assets/operating_point.json")
    p.add_argument("--check", action="store_true", help="exit 1 when the shipped point is not the chosen one")
    p.add_argument("--quick", action="store_true", help="eight texts of each set (a smoke run)")
    args = p.parse_args(argv)
    if args.quick and (args.write or args.check):
        p.error("--quick fits on a few texts: it cannot --write or --check the shipped point")
    if args.check and args.write:
        p.error("--check compares the shipped point with the chosen one: drop --write")
    from jgrounding.io import write_atomic
    from jgrounding.semantics import decision
    from jgrounding.semantics import head as sh

    head = sh.load()
    print(f"the act/hold decision on the dev sets ({bs.machine()}): head {head.meta['params_digest']}")
    sets = {name: sd.read(paths) for name, paths in sd.SETS.items()}
    if args.quick:
        sets = {name: items[::40][:8] for name, items in sets.items()}
    r = records(sets)
    thresholds, detector, rows = choose(r)
    shipped = decision.point()
    frontier = sweep(r, thresholds, detector)
    md, payload = report(r, shipped, (thresholds, detector), rows, frontier)
    print(md)
    if args.check:
        same = shipped.thresholds == thresholds and shipped.detector == detector
        print(f"the shipped point {'is' if same else 'is NOT'} the one dev chooses ({thresholds}, detector {detector})")
        return 0 if same else 1
    out = None if args.quick and args.out is None else Path(args.out or OUT)
    if out is not None:
        write_atomic(out.with_suffix(".md"), md)
        write_atomic(out.with_suffix(".json"), json.dumps(payload, indent=1, sort_keys=True) + "\n")
        figure(frontier, payload["points"], out.with_suffix(".png"))
        print(f"wrote {out.with_suffix('.md')}, .json and .png")
    if args.write:
        meta = {
            "head_digest": head.meta["params_digest"],
            "dev_texts": int(len(r["motion"])),
            "dev_cost": payload["points"]["chosen"]["all"]["cost"],
            "written_by": "python -m tools.nomotion_frontier --write",
        }
        point = decision.OperatingPoint(thresholds, detector, meta)
        print(f"wrote {write_atomic(decision.POINT_ASSET, point.to_json())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
