"""Table II's physics columns and the library's screening on the hand-tuned trunk and on a fitted one.

``python -m experiments.trunk_physics --trunk results/trunk_reference_fitted.xml [--runs runs/ablation]``.

Nothing is retrained. The methods ``python -m experiments.ablation`` saved under ``--runs`` are restored and draw
again the samples the ablation scored (:func:`experiments.ablation_scores.samples`: the same key per method, the same
K_div and steps, from the run configuration each checkpoint records). The first ``--per-tuple`` samples of every tuple
(default: the run's ``eval.physics_samples``, as in Table II) are simulated on the shipped, hand-tuned trunk and on
the given one, each against the held-out references simulated on that same trunk and under the shape tolerance
calibrated from the library's spread on it (:func:`jgrounding.evaluation.physics.library_references`). So the
hand-tuned column is Table II's own, and the report says whether it reproduces results/ablation.json. The references
the ablation simulates (oracle replay, wrong intent, tuple mean) are added for both trunks.

The library's screening: every one of its demonstrations (train and held-out) on both trunks, by the feasibility
margin (:func:`jgrounding.sim.margins`, what screened sampling keeps by) and by the library build's whole screening
(:func:`jgrounding.library.screening.screen`: bounds, smoothness, feasibility, each intent's kinematic signature;
the stored commands stand for their own reconstruction), per intent. Writes ``<out>.md`` and ``<out>.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import os
import time
from pathlib import Path

import jax
import numpy as np

from experiments import ablation, ablation_result, bench_sample
from experiments.ablation_report import DISPLAY
from experiments.ablation_scores import physics, references, samples
from jgrounding import config as configs
from jgrounding import load_library, semantics, sim
from jgrounding.evaluation import physics as trunk_eval
from jgrounding.generators import methods
from jgrounding.io import write_atomic
from jgrounding.library import screening
from jgrounding.training import checkpoints
from jgrounding.vocabulary import INTENTS

COLUMNS = (  # Physics field, header, digits
    ("shape_rms_m", "Shape RMS (m)", 3),
    ("shape_success", "Shape succ.", 3),
    ("shape_diversity_m", "Shape div. (m)", 3),
    ("feasible", "Feasible", 4),
)
REFERENCE_ROWS = {"oracle": "Oracle (replay same tuple)", "wrong_intent_any_intensity": "Wrong intent (replay)"}
REFERENCE_ROWS["tuple_mean"] = "Tuple mean"
GOAL_FEASIBLE = 0.95  # below this share of feasible demonstrations the library needs screening on the new trunk
KEY = 2026  # the ablation's base key (experiments.ablation.run): method i draws with fold_in(key, i)


def run_config(runs: Path, names: list[str]) -> configs.Config:
    """The configuration the ablation ran with, as its checkpoints record it (they must agree)."""
    cfgs = {}
    for name in names:
        meta = checkpoints.read_meta(runs / name)
        if "run_config" not in meta:
            raise ValueError(
                f"checkpoint {runs / name} records no run configuration: save it with experiments.ablation"
            )
        cfgs[name] = configs.from_dict(meta["run_config"])
    first = next(iter(cfgs.values()))
    other = [n for n, c in cfgs.items() if c.eval != first.eval or c.sample != first.sample]
    if other:
        raise ValueError(f"checkpoints in {runs} come from different runs: {', '.join(other)} differ from {names[0]}")
    return first


def screen_library(lib, trunk: str | None) -> dict:
    """Per intent (and in all): demonstrations, feasible by the margin, accepted by the build's screening."""
    u = np.concatenate([lib.train.u, lib.heldout.u]).astype(np.float32)
    intent = np.concatenate([lib.train.intent, lib.heldout.intent])
    intensity = np.concatenate([lib.train.intensity, lib.heldout.intensity])
    margin = sim.margins(u, engine="native", trunk=trunk)
    checks = screening.screen(u, u, intent, intensity=intensity, trunk=trunk)
    rows = {}
    for m, name in [*enumerate(INTENTS), (None, "all")]:
        sel = np.ones(len(u), bool) if m is None else intent == m
        rows[name] = {"demonstrations": int(sel.sum()), "feasible": int((margin[sel] >= 0).sum())}
        rows[name].update({c: int(checks[c][sel].sum()) for c in (*screening.CHECKS, "accepted")})
    return {"per_intent": rows, "min_margin": float(margin.min())}


def _cell(p: dict, field: str, digits: int) -> str:
    mean, std = p[field]
    if mean is None:
        return "–"
    return f"{mean:.{digits}f} ± {std:.{digits}f}" if std is not None else f"{mean:.{digits}f}"


def reproduces(mine: dict, table: dict) -> str:
    """Whether the hand-tuned physics of one row match the ablation's: exactly, within its std, or not (a reference
    row, one replay per tuple, has no diversity and no std: exactly or not)."""
    fields = [f for f, _, _ in COLUMNS if mine[f][0] is not None]
    diffs = {f: abs(mine[f][0] - table[f][0]) for f in fields}
    if max(diffs.values()) == 0.0:
        return "exact"
    return "within std" if all(d <= (mine[f][1] is not None) * table[f][1] for f, d in diffs.items()) else "no"


def markdown(res: dict) -> str:
    hand, fit = "hand-tuned", "fitted"
    head = ["Method"] + [f"{h} {t}" for _, h, _ in COLUMNS for t in (hand, fit)] + ["= Table II"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for name, row in {**res["methods"], **res["references"]}.items():
        cells = [_cell(row[t], f, d) for f, _, d in COLUMNS for t in ("hand_tuned", "fitted")]
        label = DISPLAY.get(name) or REFERENCE_ROWS[name]
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {row.get('reproduces', '–')} |")
    tol = res["shape_tolerance_m"]
    m = res["machine"]
    out = [
        "# Table II's physics columns on the hand-tuned and the fitted trunk",
        "",
        f"Written by `{res['command']}` on {res['date']}: {m['cpu']}, {m['cores']} cores, jax {m['jax']} "
        f"({m['backend']}), MuJoCo {m['mujoco']}; {res['seconds']:.0f} s (load average {m['load']:.1f} at the start).",
        "",
        f"- hand-tuned trunk: the shipped jgrounding/assets/trunk.xml, sha256 {res['trunks']['hand_tuned']['sha256']}",
        f"- fitted trunk: {res['trunks']['fitted']['path']}, sha256 {res['trunks']['fitted']['sha256']}",
        f"- methods: the checkpoints in {res['runs']} (not retrained); the first {res['per_tuple']} of each tuple's "
        f"{res['num_samples']} samples, {len(res['seeds'])} seeds; mean ± std over seeds.",
        f"- shape tolerance (from the library simulated on each trunk): hand-tuned {tol['hand_tuned']:.3f} m, "
        f"fitted {tol['fitted']:.3f} m: each trunk's shape success is under its own, calibrated as Table II's.",
        "",
        *lines,
        "",
        f"= Table II: whether the hand-tuned column reproduces {res['ablation']['path']} (exact, within the "
        f"ablation's std, or no); {res['ablation']['note']}",
        "",
        "## The library's screening",
        "",
        "Every demonstration (train and held-out) simulated on each trunk: feasible (margin >= 0, what screened "
        "sampling keeps by) and accepted by the library build's screening (bounds, smoothness, feasibility, the "
        "intent's kinematic signature).",
        "",
        "| Intent | n | feasible hand-tuned | feasible fitted | accepted hand-tuned | accepted fitted |",
        "|---|---|---|---|---|---|",
    ]
    scr = res["screening"]
    for name, a in scr["hand_tuned"]["per_intent"].items():
        b = scr["fitted"]["per_intent"][name]
        out.append(
            f"| {name} | {a['demonstrations']} | {a['feasible']} | {b['feasible']} | {a['accepted']} | "
            f"{b['accepted']} |"
        )
    out += ["", res["verdict"], ""]
    return "\n".join(out)


def verdict(scr: dict) -> str:
    """The screening's finding in words: how many demonstrations stay feasible on the fitted trunk, against the goal."""
    a = scr["fitted"]["per_intent"]["all"]
    n, feas, acc = a["demonstrations"], a["feasible"], a["accepted"]
    goal = f"{100 * GOAL_FEASIBLE:.0f} %"
    text = f"On the fitted trunk {feas} of the {n} demonstrations stay feasible ({100 * feas / n:.1f} %): "
    if feas < GOAL_FEASIBLE * n:
        text += f"fewer than {goal}, so a library screened on the fitted trunk is then the next step."
    else:
        text += f"at least {goal}, so the library's feasibility carries over to the fitted trunk."
    text += f" {acc} ({100 * acc / n:.1f} %) pass the library build's whole screening"
    if acc == n:
        return text + "."
    worst = min((r["accepted"] / r["demonstrations"], k) for k, r in scr["fitted"]["per_intent"].items())
    return text + (
        f" ({n - a['semantic']} fail their intent's kinematic signature on the fitted trunk); fewest: {worst[1]}, "
        f"{100 * worst[0]:.0f} %."
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--trunk", required=True, help="the fitted trunk's MJCF (python -m jgrounding.sim calibrate)")
    p.add_argument("--runs", default="runs/ablation", help="the checkpoints python -m experiments.ablation saved")
    p.add_argument(
        "--methods", help=f"comma-separated subset (default: those of {', '.join(methods.ABLATION_ROWS)} in --runs)"
    )
    p.add_argument("--per-tuple", type=int, help="samples simulated per tuple (default: the run's physics_samples)")
    p.add_argument("--ablation", default="results", help="folder of the ablation.json the hand-tuned column is checked")
    p.add_argument("--out", default="results/trunk_physics", help="writes <out>.md and <out>.json")
    args = p.parse_args(argv)
    t_run, load = time.perf_counter(), os.getloadavg()[0]
    runs = Path(args.runs)
    try:
        trunk = sim.resolve_trunk(args.trunk)
    except FileNotFoundError as e:
        p.error(str(e))
    if not runs.is_dir():
        p.error(f"--runs {runs} is not a folder: run python -m experiments.ablation first (it saves runs/ablation)")
    saved = [m for m in methods.ALL_METHODS if (runs / m / "meta.json").is_file()]
    names = args.methods.split(",") if args.methods else [m for m in saved if m in methods.ABLATION_ROWS]
    missing = [m for m in names if m not in saved]
    if not names or missing:
        p.error(f"no checkpoint in {runs} for {missing or 'any method'}; saved there: {', '.join(saved) or 'none'}")
    try:
        cfg = run_config(runs, names)
    except ValueError as e:
        p.error(str(e))
    ev_cfg = cfg.eval
    per_tuple = args.per_tuple or ev_cfg.physics_samples
    if not 1 <= per_tuple <= ev_cfg.num_samples:
        p.error(f"--per-tuple must be in 1..{ev_cfg.num_samples} (the run's samples per tuple), got {per_tuple}")
    order = ablation.rows_of(cfg)  # the ablation's order: method i drew its samples with fold_in(key, i)
    if set(names) - set(order):
        p.error(f"{', '.join(sorted(set(names) - set(order)))}: not a row of that run; its rows: {', '.join(order)}")
    lib = load_library(ev_cfg.library)
    trunks = {"hand_tuned": None, "fitted": trunk}
    t0 = time.perf_counter()
    refs = {t: trunk_eval.library_references(lib, ev_cfg.tau, engine=ev_cfg.engine, trunk=v) for t, v in trunks.items()}
    print(f"library simulated on both trunks ({time.perf_counter() - t0:.0f} s)", flush=True)
    try:
        table = ablation_result.from_json((Path(args.ablation) / "ablation.json").read_text())
        comparable = table.config.eval == ev_cfg
        note = "its configuration matches the checkpoints'" if comparable else "its configuration differs"
    except (FileNotFoundError, ValueError) as e:
        table, comparable, note = None, False, f"not read ({e})"
    if per_tuple != ev_cfg.physics_samples:
        comparable, note = False, f"not comparable: {per_tuple} samples per tuple, Table II {ev_cfg.physics_samples}"
    intent_emb = semantics.intent_embeddings()
    heldout_text = None
    if any(methods.spec(m).condition.needs_text for m in names):
        heldout_text = semantics.embed([row[0] for row in lib.heldout.texts])
    plain = lambda ph: {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(ph).items()}  # noqa: E731
    rows = {}
    for method in names:
        t0 = time.perf_counter()
        trained = checkpoints.restore_trained(runs / method, method)
        cond = methods.spec(method).condition.conditions(lib.heldout, intent_emb, heldout_text)
        u = samples(trained, lib, cfg, cond, jax.random.fold_in(jax.random.key(KEY), order.index(method)))
        rows[method] = {t: plain(physics(u, *refs[t], ev_cfg.engine, per_tuple, v)) for t, v in trunks.items()}
        if table is not None and comparable and method in table.rows:
            rows[method]["reproduces"] = reproduces(rows[method]["hand_tuned"], plain(table.rows[method].physics))
        h, f = rows[method]["hand_tuned"], rows[method]["fitted"]
        print(
            f"{DISPLAY[method]:40s} shape succ. {h['shape_success'][0]:.3f} -> {f['shape_success'][0]:.3f}  feasible "
            f"{h['feasible'][0]:.4f} -> {f['feasible'][0]:.4f}  (= Table II: {rows[method].get('reproduces', '–')}; "
            f"{time.perf_counter() - t0:.0f} s)",
            flush=True,
        )
    ref_rows = {}
    for t, v in trunks.items():
        for name, ph in references(lib, ev_cfg, *refs[t], True, v)[1].items():
            ph = plain(ph)
            ref_rows.setdefault(name, {})[t] = {**ph, **{f: [ph[f][0], None] for f, _, _ in COLUMNS}}
            ref_rows[name][t]["shape_diversity_m"] = [None, None]  # one replay per tuple: no diversity
    for name, row in ref_rows.items():
        if table is not None and comparable and name in table.reference_physics:
            row["reproduces"] = reproduces(row["hand_tuned"], plain(table.reference_physics[name]))
    print("references simulated on both trunks", flush=True)
    scr = {t: screen_library(lib, v) for t, v in trunks.items()}
    res = {
        "command": "python -m experiments.trunk_physics "
        + " ".join(f"--{k.replace('_', '-')} {v}" for k, v in vars(args).items() if v is not None),
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "machine": {
            "cpu": bench_sample.cpu_model(),
            "cores": os.cpu_count(),
            "jax": jax.__version__,
            "backend": jax.default_backend(),
            "mujoco": __import__("mujoco").__version__,
            "load": load,
        },
        "trunks": {t: {**sim.trunk_identity(v), "path": v and args.trunk} for t, v in trunks.items()},
        "runs": str(runs),
        "per_tuple": per_tuple,
        "num_samples": ev_cfg.num_samples,
        "seeds": list(ev_cfg.seeds),
        "shape_tolerance_m": {t: r[1].tau_m for t, r in refs.items()},
        "ablation": {"path": str(Path(args.ablation) / "ablation.json"), "note": note},
        "methods": rows,
        "references": ref_rows,
        "screening": scr,
        "verdict": verdict(scr),
    }
    res["seconds"] = time.perf_counter() - t_run
    text = markdown(res)
    write_atomic(f"{args.out}.json", json.dumps(res, indent=1, default=float))
    write_atomic(f"{args.out}.md", text)
    print(text)
    print(f"wrote {args.out}.md and {args.out}.json in {res['seconds']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
