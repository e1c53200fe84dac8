"""A nearest-neighbour vote over the training texts, blended with the shipped tuned head (dev only).

    python -m tools.semantics_knn          # compare the variants: results/semantics_dev_knn.json
    python -m tools.semantics_knn --write  # the best variant of CHOICES: jgrounding/assets/semantic_knn.npz

For every text the shipped head (``jgrounding/assets/semantic_head.npz``) already computes its tuned encoder's four pooled
vectors and its hidden layer. Here the training texts (``assets/semantics/train/corpora/*.jsonl``) are put through the
same path once, and a dev text's intent distribution becomes

    p = (1 - a) p_head + a p_knn,    p_knn = the (similarity-weighted) intent vote of its k nearest training texts

(cosine similarity in one of the head's representations; the vote is over the 16 intents and "none"). The
intensity stays the head's, or, in the variants with an intensity vote (:data:`CHOICES`), the same neighbours'
intensities are blended into it with weight b. For each variant (representation, which training rows form the table, when the vote
applies, k, a) the confidence threshold is refitted on v2 dev as :mod:`tools.train_semantics` does (optionally a
temperature on the blend first), and the variant is scored with its functions, and on the two situation hold-outs
(:data:`HOLDOUTS`) at that threshold. The table may hold, beyond the training texts, rows the head was never trained
on (:data:`VOTE_ROWS`). The test splits are never read.
Features are cached in ``.cache/semantics/`` keyed by the head's digest and the texts. The vote's parts (features,
representations, the vote, its gate, a variant's score and the ship rule) are :mod:`tools.semantics_vote`; this module
compares the variants and writes the table.
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import numpy as np

from jgrounding.semantics import head as sh
from tools import semantic_sets
from tools import semantics_calibration as calib
from tools import semantics_data as data
from tools import semantics_vote as sv

ROOT = data.ROOT
REPORT = ROOT / "results" / "semantics_dev_knn.json"
# Situation-only texts written for selection by writers who saw neither the code, the training corpora nor the
# evaluation sets (v2 dev holds 29 situations): scored beside v2 dev, never trained on, not part of the vote's ship
# rule (the "blind" ones are a term of the head's ship score in tools.train_semantics: data.SITUATION_DEVS).
# "hold-out": 320 texts from docs/semantics_writing_brief.md (a brief that says which situations call for which
# behaviour); "blind": data.SITUATION_DEVS, as the head's calibration reads them: 256 texts from
# docs/semantics_blind_brief.md (the intents' descriptions and the style, as the v2 evaluation set's writer had them)
# and a second writer's 320 from the same brief.
HOLDOUTS = {
    "hold-out": semantic_sets.files("dev/situations_holdout"),
    "blind": data.SITUATION_DEVS,
}
# Rows the vote's table holds beyond the training corpora (the head is not trained on them, so
# tools.train_semantics still rebuilds the shipped head): 1,024 situations written from the blind brief.
VOTE_ROWS = semantic_sets.files("train/vote")
# The shipped variant, chosen on v2 dev: the tuned sentence vector; the table without the templated generated
# corpus; the vote only for texts that read as a situation; the centre of the (k, a) region where the variants of
# this family pass the ship rule; the head's own temperature (no refit on the blend), the threshold refitted.
# An intensity vote (b: its weight; 0: none) from the same neighbours, and a table that also holds the blind
# writers' training situations (data.BLIND_TRAIN), are chosen on v2 dev as the rest (:data:`CHOICES`).
CHOSEN = dict(representation="sentence", table="no-generated", gate="no motion words", k=10, tau=0.05, a=0.5, b=0.0)
# The variants of the chosen family that `--write` (and `--chosen-only`) scores through the shipped blend: each
# table, with and without the intensity vote. The one written is the highest v2 dev score among those that pass
# the ship rule (:func:`tools.semantics_vote.qualifies`), ties to the earlier.
CHOICES = tuple(dict(CHOSEN, table=table, b=b) for table in ("no-generated", "no-generated+blind") for b in (0.0, 0.5))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--report", default=str(REPORT))
    p.add_argument(
        "--write",
        action="store_true",
        help=f"write the best of the chosen family's variants (CHOICES) that passes the ship rule to {sh.KNN_ASSET.name}",
    )
    p.add_argument(
        "--head",
        default=None,
        help="compare the variants for another head file (e.g. one retrained by tools.train_semantics --out); "
        "the shipped table is written only for the shipped head",
    )
    p.add_argument(
        "--chosen-only", action="store_true", help="score only the chosen family's variants (CHOICES), write nothing"
    )
    p.add_argument(
        "--situation-temperature",
        action="store_true",
        help="with --write or --chosen-only: also fit a temperature for the texts the vote's gate lets through, on the "
        "blind situation hold-outs (fit_situation_temperature), with the threshold refitted; whether it ships is "
        "decided through jg.ground (tools.semantics_system_dev)",
    )
    args = p.parse_args(argv)
    if args.situation_temperature and not (args.write or args.chosen_only):
        raise SystemExit("--situation-temperature goes with --write or --chosen-only (it fits the chosen variant's)")
    if args.head and args.write:
        raise SystemExit("--write builds the shipped head's table; drop --head (or use --chosen-only)")
    head = sh.load(args.head)
    if head.knn is not None:  # compare against the head alone
        head = sh.Head(
            head.params, head.config, head.temperature, float(head.meta["threshold"]), head.meta, head.encoder
        )
    rows, files = table_rows()
    # Every set a variant is scored on: v2 dev (threshold and ship rule), plain dev and the hold-outs.
    sets = {"dev": data.read_jsonl(data.DEV), "plain": data.read_jsonl(data.DEV_PLAIN)}
    holds = [name for name, paths in HOLDOUTS.items() if all(path.exists() for path in paths)]
    sets |= {name: data.read_situations(HOLDOUTS[name]) for name in holds}
    x_train = sv.head_features(head, [r["text"] for r in rows])
    x = {n: sv.head_features(head, [r["text"] for r in set_rows]) for n, set_rows in sets.items()}
    p_head = {n: [np.asarray(a, np.float64) for a in sh.predict(head.params, x[n], head.temperature)] for n in sets}
    pz_head = {n: p[1] for n, p in p_head.items()}  # the intensity stays the head's (unless an intensity vote)

    def scored(pm: dict, refit: bool, budgets=(), pz: dict | None = None, target=None) -> dict:
        """:func:`evaluate` of intent probabilities for every set, with the head's intensities or ``pz``'s, at the
        dev budget ``target`` (default: the votes', :func:`tools.semantics_vote.vote_target`; the head alone is scored at calib.TARGET_WRONG)."""
        pz = pz or pz_head
        held = {n: (pm[n], pz[n], sets[n]) for n in holds}
        return sv.evaluate(
            pm["dev"],
            pz["dev"],
            sets["dev"],
            pm["plain"],
            pz["plain"],
            sets["plain"],
            refit,
            held=held,
            budgets=budgets,
            target=sv.vote_target(base) if target is None else target,
        )

    train_intent, train_intensity = data.labels(rows)
    style = np.array([r.get("style") or "" for r in rows])
    dev, plain = sets["dev"], sets["plain"]
    base = scored({n: p[0] for n, p in p_head.items()}, False, target=calib.TARGET_WRONG)
    assert base["threshold"] == head.threshold, "the refit must give the shipped head's threshold"
    print(
        f"shipped head: score {base['score']:.3f} situation {base['situation']:.3f} "
        f"thr {base['threshold']:.3f} {json.dumps({k: round(v, 3) for k, v in base['dev'].items()})} "
        f"plain {base['plain_intent']:.3f} {_holdout_line(base)}",
        flush=True,
    )
    blind = np.char.startswith(files.astype(str), "blind/")
    tables = {  # every table but "no-generated+blind" leaves the blind writers' splits out, as before they voted
        "all": ~blind,
        "no-generated": (files != "generated.jsonl") & ~blind,
        "no-generated+blind": files != "generated.jsonl",
        "situations": (style == "situation") & ~blind,
        "situations+none": ((style == "situation") | (train_intent == sh.NONE)) & ~blind,
    }
    if args.write or args.chosen_only:
        opts = dict(dry=not args.write, situation_temperature=args.situation_temperature)
        return write(head, x_train, train_intent, train_intensity, tables, x, p_head, scored, base, **opts)
    gates = {
        "always": {n: np.ones(len(sets[n]), bool) for n in sets},
        "no motion words": {n: sv.no_motion_words(x[n]) for n in sets},
    }
    print(
        f"no motion words: {gates['no motion words']['dev'].sum()} of {len(dev)} v2 dev texts, "
        f"{gates['no motion words']['plain'].sum()} of {len(plain)} plain dev texts"
    )
    variants = []
    for rep in ("sentence", "chosen", "pools", "hidden"):
        t_all = sv.representation(rep, head.params, x_train)
        q = {n: sv.representation(rep, head.params, x[n]) for n in sets}
        for (tname, tmask), (gname, gate) in itertools.product(tables.items(), gates.items()):
            if tname.startswith("situations") and gname == "always":
                continue  # a situation-only table votes for every text only behind the gate
            for k, tau in itertools.product((5, 10, 20, 40), (0.0, 0.05)):
                votes = {n: sv.knn_vote(q[n], t_all[tmask], train_intent[tmask], k, tau) for n in sets}
                for a, refit in itertools.product((0.1, 0.2, 0.3, 0.5, 0.7), (False, True)):
                    blend = {
                        n: np.where(gate[n][:, None], (1 - a) * p_head[n][0] + a * votes[n], p_head[n][0]) for n in sets
                    }
                    r = scored(blend, refit)
                    r |= dict(representation=rep, table=tname, gate=gname, k=k, tau=tau, a=a, refit_temperature=refit)
                    r["qualifies"] = sv.qualifies(r, base)
                    variants.append(r)
    print(f"{len(variants)} variants; {sum(v['qualifies'] for v in variants)} pass the ship rule on dev")
    keys = ("representation", "table", "gate")
    best = {}
    for v in variants:  # best score per (representation, table, gate): what the report's table lists
        kk = tuple(v[k] for k in keys)
        if kk not in best or (v["score"], v["situation"]) > (best[kk]["score"], best[kk]["situation"]):
            best[kk] = v
    sit = np.array([row.get("style") == "situation" for row in dev])
    intent, _ = data.labels(dev)
    for v in sorted(best.values(), key=lambda v: -v["score"]):
        d = v["dev"]
        fixed = [dev[i]["id"] for i in np.where(sit & (v["_m"] == intent) & (base["_m"] != intent))[0]]
        broke = [dev[i]["id"] for i in np.where((v["_m"] != intent) & (base["_m"] == intent))[0]]
        print(
            f"  {v['representation']:8s} {v['table']:15s} {v['gate']:15s} k={v['k']:2d} tau={v['tau']} a={v['a']}"
            f" T={'fit' if v['refit_temperature'] else '1'}: score {v['score']:.3f} sit {v['situation']:.3f}"
            f" intent {d['intent_motion']:.3f} exact {d['intensity_exact']:.3f} acted {d['coverage_motion']:.3f}"
            f" wrong {d['confident_wrong']:.3f} held {d['none_held']:.3f} ECE {d['ece']:.3f}"
            f" plain {v['plain_intent']:.3f} thr {v['threshold']:.3f} {_holdout_line(v)} ship={v['qualifies']}"
            f" fixed {fixed} broke {broke}",
            flush=True,
        )
    strip = lambda v: {k: w for k, w in v.items() if not k.startswith("_")}  # noqa: E731
    report = {
        "shipped": strip(base),
        "best_per_family": [strip(v) for v in sorted(best.values(), key=lambda v: -v["score"])],
        "qualifying": [strip(v) for v in variants if v["qualifies"]],
        "num_variants": len(variants),
    }
    from jgrounding.io import write_atomic

    write_atomic(args.report, json.dumps(report, indent=1, sort_keys=True) + "\n")
    print(f"wrote {args.report}")
    return 0


def _holdout_line(v: dict) -> str:
    if not v.get("holdout"):
        return "hold-outs: none"
    return " ".join(
        f"{name}: intent {h['intent_motion']:.3f} acted {h['coverage_motion']:.3f}"
        f" wrong {h['confident_wrong']:.3f} exact {h['intensity_exact']:.3f}"
        for name, h in v["holdout"].items()
    )


def table_rows() -> tuple[list[dict], np.ndarray]:
    """The rows the vote's table may hold: the training corpora (``assets/semantics/train/corpora/``), the vote-only rows
    (:data:`VOTE_ROWS`) and then the blind writers' training splits (:data:`tools.train_semantics.BLIND_TRAIN`),
    with each row's file name ``(N,)`` (a blind split's as ``blind/<folder>/<name>``)."""
    rows, files = [], []
    named = [(path, path.name) for path in [*sorted(data.TRAIN_DIR.glob("*.jsonl")), *VOTE_ROWS]]
    named += [(Path(path), f"blind/{Path(path).parent.name}/{Path(path).name}") for path in data.BLIND_TRAIN]
    for path, name in named:
        part = data.read_jsonl(path)
        rows += part
        files += [name] * len(part)
    return rows, np.array(files)


def write(
    head,
    x_train,
    train_intent,
    train_intensity,
    tables,
    x,
    p_head,
    scored,
    base,
    dry: bool = False,
    situation_temperature: bool = False,
) -> int:
    """Score each of :data:`CHOICES` (the chosen family's tables, with and without the intensity vote) through the
    shipped blend (:func:`jgrounding.semantics.head.knn_blend`, float16 table) and write the highest v2 dev score
    among those that pass the ship rule as ``jgrounding/assets/semantic_knn.npz``. Every other table is scored
    the same way first, for the record. ``x``, ``p_head``: each evaluation set's head inputs and the head's
    probabilities, by name; ``scored``: their evaluation (main's). ``dry``: print the scores, write nothing.
    ``situation_temperature``: the picked variant also gets :func:`fit_situation_temperature` (the threshold
    refitted with it), written when its scores print; the ship rule of that step is the whole system's, through
    ``jg.ground`` (``tools.semantics_system_dev``)."""
    if CHOSEN["representation"] not in sh.KNN_POOLS:
        raise SystemExit(f"the shipped blend reads one pooled vector: {', '.join(sh.KNN_POOLS)}")
    pool = sh.KNN_POOLS.index(CHOSEN["representation"])
    gate = sv.gate_vector(x["dev"].shape[1] - sv.POOLED)
    if CHOSEN["gate"] == "always":
        gate = np.zeros_like(gate)
    refit = CHOSEN.get("refit_temperature", False)

    def blended(mask, b: float = 0.0):
        table = sv.representation(CHOSEN["representation"], head.params, x_train[mask]).astype(np.float16)
        labels, intensities = train_intent[mask], train_intensity[mask]
        knn = {"table": table, "onehot": np.eye(sh.NUM_CLASSES, dtype=np.float32)[labels], "gate": gate}
        knn |= {"tau": np.float32(CHOSEN["tau"]), "a": np.float32(CHOSEN["a"])}
        if b > 0:  # as sh.load_knn builds it: unlabelled rows vote for no intensity
            knn |= {"onehot_z": sh.intensity_onehot(intensities), "b": np.float32(b)}

        def vote(xs, p):
            if not len(xs):
                return p
            q = xs[:, pool * sv.POOL : (pool + 1) * sv.POOL]
            pm, pz = sh.knn_blend(
                knn, p[0].astype(np.float32), p[1].astype(np.float32), q, xs[:, sv.POOLED :], CHOSEN["k"]
            )
            return np.asarray(pm, np.float64), np.asarray(pz, np.float64)

        out = {n: vote(x[n], p) for n, p in p_head.items()}
        r = scored({n: o[0] for n, o in out.items()}, refit, sv.BUDGETS, pz={n: o[1] for n, o in out.items()})
        return table, labels, intensities, r | {"_out": out}

    for name, mask in tables.items():
        if name not in {c["table"] for c in CHOICES}:
            _, labels, _, r = blended(mask)
            print(
                f"  table {name} ({len(labels)} rows): score {r['score']:.3f} situation {r['situation']:.3f}"
                f" thr {r['threshold']:.3f} {_holdout_line(r)}"
            )
    scored_choices = []
    for choice in CHOICES:
        table, labels, intensities, r = blended(tables[choice["table"]], choice["b"])
        ok = sv.qualifies(r, base)
        d = r["dev"]
        print(
            f"{choice} ({len(labels)} rows): score {r['score']:.3f} situation {r['situation']:.3f}"
            f" thr {r['threshold']:.3f} {json.dumps({k: round(v, 3) for k, v in d.items()})}"
            f" plain {r['plain_intent']:.3f} {_holdout_line(r)}; ship rule: {ok}"
        )
        print(
            f"  confident-wrong budgets on v2 dev (TARGET_WRONG {calib.TARGET_WRONG}; situation hold-out"
            f" {calib.SITUATION_TARGET_WRONG} or the budget): {sv.budget_line(r)}"
        )
        scored_choices.append((choice, table, labels, intensities, r, ok))
    pick = sv.best_passing([c[4]["score"] for c in scored_choices], [c[-1] for c in scored_choices])
    if dry and pick is not None:
        print(f"would write {scored_choices[pick][0]}")
    if dry and (pick is None or not situation_temperature):
        return 0
    if pick is None:
        stale = ""
        if sh.KNN_ASSET.exists():  # a table made for an earlier head: grounding ignores it; remove it
            with np.load(sh.KNN_ASSET) as f:
                made_for = json.loads(str(f["meta"])).get("head_digest")
            if made_for != head.meta["params_digest"]:
                sh.KNN_ASSET.unlink()
                stale = f"; removed {sh.KNN_ASSET.name}, made for another head ({made_for})"
        raise SystemExit(f"no variant of {CHOICES} passes the ship rule on dev: no vote ships{stale}")
    choice, table, labels, intensities, r, _ = scored_choices[pick]
    t_sit = 1.0
    if situation_temperature:
        blended_choice = r["_out"]
        gated = {n: sv.no_motion_words(x[n]) if gate.any() else np.ones(len(x[n]), bool) for n in x}
        rows = data.read_situations(HOLDOUTS["blind"])
        t_sit = sv.fit_situation_temperature(blended_choice["blind"][0], gated["blind"], rows)
        sharp = {n: np.where(gated[n][:, None], sv.sharpen(o[0], t_sit), o[0]) for n, o in blended_choice.items()}
        r = scored(sharp, refit, sv.BUDGETS, pz={n: o[1] for n, o in blended_choice.items()})
        d = r["dev"]
        print(
            f"with a situation temperature {t_sit:.3f} (fitted on the blind hold-outs' gated texts): score"
            f" {r['score']:.3f} situation {r['situation']:.3f} thr {r['threshold']:.3f}"
            f" {json.dumps({k: round(v, 3) for k, v in d.items()})} plain {r['plain_intent']:.3f} {_holdout_line(r)}"
            f"; whether it ships: tools.semantics_system_dev (the whole system, through jg.ground)"
        )
        if dry:
            return 0
    meta = dict(
        k=choice["k"],
        tau=choice["tau"],
        a=choice["a"],
        b=choice["b"],
        head_digest=head.meta["params_digest"],
        representation=choice["representation"],
        gate=choice["gate"],
        temperature=float(r["blend_temperature"]),  # 1: none (sh.knn_blend applies any other)
        situation_temperature=float(t_sit),  # 1: none; the gated texts' (fit_situation_temperature)
        threshold=r["threshold"],
        variant=choice,
        rows=int(len(labels)),
        dev=r["dev"],
        dev_situation=r["situation"],
        dev_plain_intent=r["plain_intent"],
        holdout=r["holdout"],
        dev_score=r["score"],
        head_alone={k: base[k] for k in ("score", "situation", "threshold", "dev", "plain_intent")},
    )
    z_labels = intensities if choice["b"] > 0 else None  # only a table with an intensity vote stores them
    path = sh.save_knn(sh.KNN_ASSET, table, labels, gate, meta, z_labels)
    print(f"wrote {path}: {choice} ({len(labels)} rows, digest {sh.knn_digest(table, labels, z_labels)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
