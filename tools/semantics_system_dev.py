"""The whole grounding system on the dev sets, as users call it: ``jg.ground`` with its defaults (the head, the
vote, the no-motion decision), one text at a time, scored with ``bench semantics``' metrics (ECE included).

    python -m tools.semantics_system_dev --out /tmp/before.json             # the shipped system's dev figures
    python -m tools.semantics_system_dev --compare /tmp/before.json        # ... and the ship rule against them
    python -m tools.semantics_system_dev --compare /tmp/before.json --rule detector   # a retrained detector's rule

The sets: v2 dev and the plainly worded dev split (what a head and a vote are chosen on), the blind situation
hold-outs (:data:`tools.train_semantics.SITUATION_DEVS`, which calibrate the head and the vote's situation
temperature), the situation hold-out that nothing is fitted on (``assets/semantics/dev/situations_holdout/situations.jsonl``,
written from another brief), and two more sets that nothing is trained or fitted on: a second
unfitted situation hold-out (``assets/semantics/dev/situations_s26/situations.jsonl``, a blind writer from the situation brief)
and a no-motion dev set (``assets/semantics/dev/nomotion/dev.jsonl``, a blind writer from the no-motion brief: texts
that call for no motion and contrast texts). No test split or blind bench is read.

The ship rule for a change to calibration (:data:`RULE`, written before the first run of the change it judged, a situation
temperature): on v2 dev and plain dev, no metric worse (intent, acted, intensity exact, no-motion held; confident
wrong not higher; ECE of the two pooled not higher); on the unfitted hold-out a lower ECE, no lower intent and no more
confident wrongs; on the blind hold-outs, confident wrong within ``tools.train_semantics.SITUATION_TARGET_WRONG``.
A retrained head is compared the same way: head and vote together, as users call them.

The ship rule for a retrained no-motion detector (:data:`DETECTOR_RULE`, ``--rule detector``,
written before its first run): on v2 dev and plain dev the same clauses as :data:`RULE`'s; on the no-motion dev set
no-motion held, intent and acted not lower and confident wrong not higher; on the two unfitted situation hold-outs
pooled a lower ECE, acted not lower and confident wrong not higher; on the blind hold-outs ECE not higher and
confident wrong within ``tools.train_semantics.SITUATION_TARGET_WRONG``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from experiments import bench_semantics_scores as bs
from tools import semantic_sets
from tools import train_semantics as ts

ROOT = ts.ROOT
UNFITTED = "hold-out"  # the situation hold-out nothing is fitted on
UNFITTED2 = "s26 hold-out"  # a second one, from another blind writer
UNFITTED_BOTH = "hold-outs, unfitted"  # the two pooled
NO_MOTION_DEV = "no-motion dev"  # no-motion and contrast texts, never trained or fitted on
SETS = {
    "v2 dev": (ts.DEV,),
    "plain dev": (ts.DEV_PLAIN,),
    "blind hold-outs": ts.SITUATION_DEVS,
    UNFITTED: semantic_sets.files("dev/situations_holdout"),
    UNFITTED2: semantic_sets.files("dev/situations_s26"),
    NO_MOTION_DEV: semantic_sets.files("dev/nomotion"),
}
POOLED = {"v2 + plain dev": ("v2 dev", "plain dev"), UNFITTED_BOTH: (UNFITTED, UNFITTED2)}
HIGHER = ("intent", "acted", "exact", "none_held")  # none of these may fall on v2 dev or plain dev
RULE = (
    "v2 dev and plain dev: intent, acted, exact, no-motion held not lower, confident wrong not higher, their pooled ECE "
    "not higher; the unfitted situation hold-out: ECE lower, intent not lower, confident wrong not higher; the blind "
    f"hold-outs: confident wrong <= {ts.SITUATION_TARGET_WRONG}"
)
DETECTOR_RULE = (
    "v2 dev and plain dev: as the calibration rule; the no-motion dev set: no-motion held, intent and acted not lower, "
    "confident wrong not higher; the two unfitted situation hold-outs pooled: ECE lower, acted not lower, confident "
    f"wrong not higher; the blind hold-outs: ECE not higher, confident wrong <= {ts.SITUATION_TARGET_WRONG}"
)
RULES = {"calibration": RULE, "detector": DETECTOR_RULE}


def read(paths) -> list[dict]:
    return [row for path in paths for row in ts.read_jsonl(path)]


def evaluate() -> dict:
    """``bench semantics``' metrics of ``jg.ground`` on each dev set, and of the sets :data:`POOLED` pools."""
    import jgrounding as jg

    out, runs = {}, {}
    for name, paths in SETS.items():
        items = read(paths)
        runs[name] = items, [jg.ground(it["text"]) for it in items]
        out[name] = bs.metrics(*runs[name])
    for name, parts in POOLED.items():
        out[name] = bs.metrics(*(sum((runs[p][i] for p in parts), []) for i in (0, 1)))
    return out


EPS = 1e-9  # ties count as not worse


def _not_above(what: str, new: float, old: float) -> tuple[str, bool]:
    return f"{what} {new:.3f} <= {old:.3f}", new <= old + EPS


def _not_below(what: str, new: float, old: float) -> tuple[str, bool]:
    return f"{what} {new:.3f} >= {old:.3f}", new >= old - EPS


def _dev_clauses(new: dict, old: dict) -> list[tuple[str, bool]]:
    """The clauses on v2 dev and plain dev that every rule has."""
    clauses = []
    for name in ("v2 dev", "plain dev"):
        n, o = new[name], old[name]
        clauses += [_not_below(f"{name} {k}", n[k], o[k]) for k in HIGHER if o[k] is not None]
        clauses.append(_not_above(f"{name} confident wrong", n["confident_wrong"], o["confident_wrong"]))
    clauses.append(_not_above("v2 + plain dev ECE", new["v2 + plain dev"]["ece"], old["v2 + plain dev"]["ece"]))
    return clauses


def ship_rule(new: dict, old: dict) -> list[tuple[str, bool]]:
    """Each clause of :data:`RULE` and whether ``new`` meets it against ``old`` (both :func:`evaluate`'s)."""
    clauses = _dev_clauses(new, old)
    n, o = new[UNFITTED], old[UNFITTED]
    clauses.append((f"{UNFITTED} ECE {n['ece']:.3f} < {o['ece']:.3f}", n["ece"] < o["ece"] - EPS))
    clauses.append(_not_below(f"{UNFITTED} intent", n["intent"], o["intent"]))
    clauses.append(_not_above(f"{UNFITTED} confident wrong", n["confident_wrong"], o["confident_wrong"]))
    b = new["blind hold-outs"]["confident_wrong"]
    limit = ts.SITUATION_TARGET_WRONG
    clauses.append((f"blind hold-outs confident wrong {b:.3f} <= {limit}", b <= limit + EPS))
    return clauses


def detector_rule(new: dict, old: dict) -> list[tuple[str, bool]]:
    """Each clause of :data:`DETECTOR_RULE` and whether ``new`` meets it against ``old`` (both :func:`evaluate`'s)."""
    clauses = _dev_clauses(new, old)
    n, o = new[NO_MOTION_DEV], old[NO_MOTION_DEV]
    clauses += [_not_below(f"{NO_MOTION_DEV} {k}", n[k], o[k]) for k in ("none_held", "intent", "acted")]
    clauses.append(_not_above(f"{NO_MOTION_DEV} confident wrong", n["confident_wrong"], o["confident_wrong"]))
    n, o = new[UNFITTED_BOTH], old[UNFITTED_BOTH]
    clauses.append((f"{UNFITTED_BOTH} ECE {n['ece']:.3f} < {o['ece']:.3f}", n["ece"] < o["ece"] - EPS))
    clauses.append(_not_below(f"{UNFITTED_BOTH} acted", n["acted"], o["acted"]))
    clauses.append(_not_above(f"{UNFITTED_BOTH} confident wrong", n["confident_wrong"], o["confident_wrong"]))
    n, o = new["blind hold-outs"], old["blind hold-outs"]
    clauses.append(_not_above("blind hold-outs ECE", n["ece"], o["ece"]))
    limit = ts.SITUATION_TARGET_WRONG
    b = n["confident_wrong"]
    clauses.append((f"blind hold-outs confident wrong {b:.3f} <= {limit}", b <= limit + EPS))
    return clauses


CHECKS = {"calibration": ship_rule, "detector": detector_rule}


def line(name: str, r: dict) -> str:
    f = lambda v: "–" if v is None else f"{v:.3f}"  # noqa: E731
    return (
        f"  {name:16s} n {r['n']:4d} | intent {f(r['intent'])} acted {f(r['acted'])} wrong {f(r['confident_wrong'])}"
        f" held {f(r['none_held'])} exact {f(r['exact'])} within1 {f(r['within_one'])} ECE {f(r['ece'])}"
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=None, help="write the figures (JSON) here")
    p.add_argument("--compare", default=None, help="a previous run's --out: apply the ship rule against it")
    p.add_argument(
        "--rule", choices=sorted(RULES), default="calibration", help="which change's ship rule --compare applies"
    )
    args = p.parse_args(argv)
    from jgrounding.semantics import decision
    from jgrounding.semantics import head as sh

    head = sh.load()
    knn = head.knn["meta"] if head.knn else {}
    point = decision.point()
    print(
        f"jg.ground on the dev sets ({bs.machine()}): head {head.meta['params_digest']},"
        f" vote {knn.get('digest', 'none')} (situation temperature {knn.get('situation_temperature', 1.0):.3f}),"
        f" head threshold {head.threshold:.3f}, thresholds per kind {point.thresholds} (detector {point.detector})"
    )
    res = evaluate()
    for name, r in res.items():
        print(line(name, r))
    if args.out:
        from jgrounding.io import write_atomic

        write_atomic(args.out, json.dumps(res, indent=1, sort_keys=True) + "\n")
        print(f"wrote {args.out}")
    if args.compare:
        old = json.loads(Path(args.compare).read_text())
        missing = [name for name in res if name not in old]
        if missing:
            raise SystemExit(f"{args.compare} has no figures for {', '.join(missing)}: run --out again with this code")
        clauses = CHECKS[args.rule](res, old)
        print(f"{args.rule} ship rule against {args.compare} ({RULES[args.rule]}):")
        for text, ok in clauses:
            print(f"  {'yes' if ok else 'NO '} {text}")
        passed = all(ok for _, ok in clauses)
        print(f"ship rule: {'passed' if passed else 'failed'}")
        return 0 if passed else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
