"""Table II reproduced: ``python -m experiments.ablation [--config quick] [--set section.field=value ...]``
(what ``make ablation`` runs). This module runs; :mod:`experiments.ablation_report` formats.

Trains the five methods over several seeds (each seed its own compiled program, the seeds in threads),
evaluates them on the 64 held-out tuples with the paper's metrics (success at tau = 0.35 of one sample per
tuple, diversity over K_div = 30 samples, warm single-trajectory latency), adds the oracle and wrong-intent
references, simulates the first ``eval.physics_samples`` (10 of K_div = 30) generated samples of every tuple
and seed on the trunk for the physics columns (batched, ``engine="auto"``:
native MuJoCo on CPU, MJX on an accelerator; shape success under a tolerance calibrated from the
library's own spread, shape diversity, feasibility), adds the physics-aware RF row (rejection-sampling
fine-tuning on screened samples, :mod:`jgrounding.training.physics`), and writes
results/ablation.{md,csv,json} plus results/ablation_rms.npz (per-sample RMS, reused by the sweeps).
:func:`run` returns the typed :class:`experiments.ablation_result.AblationResult` (saved and loaded by that
module). Every cell is mean ± std over seeds. The whole configuration (``jgrounding.config``: the named entry and
its overrides) and what varies between machines (threads, XLA flags) are recorded in results/ablation.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import platform
import time
from pathlib import Path

import jax
import numpy as np

from experiments import ablation_result, bench_sample
from experiments.ablation_report import (
    DISPLAY,
    REFERENCES,
    distribution_markdown,
    findings,
    fmt,
    markdown,
    write,
)
from experiments.ablation_result import NO_PHYSICS, AblationResult, Environment, Row, Timing
from experiments.ablation_scores import (
    TIME_ROUNDS,
    distribution_row,
    evaluate,
    mean_std,
    physics,
    public_row,
    references,
)
from jgrounding import config as configs
from jgrounding import library, load_library, semantics, sim
from jgrounding.config import Config
from jgrounding.evaluation import distribution, latency
from jgrounding.evaluation import physics as trunk_eval
from jgrounding.generators import methods
from jgrounding.training import checkpoints, distributed, trainer


def rows_of(cfg: Config, simulate: bool = True) -> list[str]:
    """The registry entries the run reports, in order (``eval.rows``; default :data:`methods.ABLATION_ROWS`);
    an entry that fine-tunes a base method needs the base listed before it, and the physics-aware one needs
    the simulator (skipped otherwise)."""
    rows = list(cfg.eval.rows or methods.ABLATION_ROWS)
    for name in rows:
        methods.spec(name)  # ValueError naming the valid entries
    return [
        m
        for m in rows
        if methods.spec(m).recipe == "fit" or (simulate and methods.spec(m).base in rows[: rows.index(m)])
    ]


def environment() -> Environment:
    """What can make a re-run differ on another machine: threads, XLA flags, versions (recorded in results)."""
    import os

    try:
        isa = bench_sample.cpu_isa()  # the one reading of the vector ISA every timing is printed with
    except OSError:  # no /proc/cpuinfo
        isa = platform.machine()
    return Environment(
        cpu_isa=isa,
        cpu_count=os.cpu_count() or 1,
        xla_flags=os.environ.get("XLA_FLAGS", ""),
        omp_num_threads=os.environ.get("OMP_NUM_THREADS", ""),
        jax=jax.__version__,
        backend=jax.default_backend(),
        devices=jax.device_count(),
        numpy=np.__version__,
        python=platform.python_version(),
    )


def run(cfg: Config, lib=None) -> AblationResult:
    """Train and evaluate every row of ``cfg.eval`` on ``lib`` (default: ``cfg.eval.library``), with the
    references, benchmark v3 and the run's provenance; also saves each row's checkpoint under ``eval.runs``."""
    t_run = time.perf_counter()
    ev_cfg = cfg.eval
    lib = lib or load_library(ev_cfg.library)
    num_tendons = int(lib.train.u.shape[-1])
    simulate = num_tendons == sim.NUM_CHANNELS
    if not simulate:
        print(
            f"note: physics columns and the physics-aware row skipped: the built-in simulator is the "
            f"{sim.NUM_CHANNELS}-tendon trunk, this library has N_u = {num_tendons}",
            flush=True,
        )
    intent_emb = semantics.intent_embeddings()
    todo = rows_of(cfg, simulate)
    text_emb = heldout_text = None
    if any(methods.spec(m).condition.needs_text for m in todo):
        text_emb = semantics.embed([t for row in lib.train.texts for t in row]).reshape(len(lib.train), -1, 384)
        heldout_text = semantics.embed([row[0] for row in lib.heldout.texts])
    train_cfg = dataclasses.replace(cfg.train, chunk=min(cfg.train.chunk, max(cfg.train.steps, 1)))
    mesh = None if ev_cfg.devices == 1 else distributed.make_mesh(ev_cfg.devices or None)
    rows, per_sample, samples = {}, {}, {}
    t_lib = time.perf_counter()  # the library simulated once: held-out references + the shape tolerance
    ref_backbone, tol = None, None
    if simulate:
        ref_backbone, tol = trunk_eval.library_references(
            lib, ev_cfg.tau, engine=ev_cfg.engine, trunk=cfg.physics.trunk
        )
        why = sim.trunk_mismatch(lib.meta.get("trunk"), cfg.physics.trunk)
        if why:  # the physics columns measure the given trunk; the library's feasibility was another's
            print(f"warning: library {lib.path} was {why}", flush=True)
        print(
            f"shape tolerance {tol.tau_m:.3f} m: the {tol.percentile:.1f}th percentile of the library's pairwise "
            f"shape RMS, as tau = {ev_cfg.tau} is of its actuation RMS (within-tuple median "
            f"{tol.within_tuple_median_m:.3f} m, wrong-intent {tol.wrong_intent_median_m:.3f} m)",
            flush=True,
        )
    physics_s = time.perf_counter() - t_lib
    timing = {"library_simulation_s": physics_s, "train_s": 0.0, "evaluate_s": 0.0, "distribution_s": 0.0}
    timing.update(public_s=None, distribution_references_s=None)
    ev = lib.evaluation
    radius = distribution.radius(ev) if ev is not None else None
    key = jax.random.key(2026)
    trained_by, time_calls = {}, {}
    for method in todo:
        entry = methods.spec(method)
        t0 = time.perf_counter()
        kwargs = {"text_emb": text_emb, "mesh": mesh} if entry.recipe == "fit" else {}
        trained, report = trainer.make(
            method,
            lib,
            ev_cfg.seeds,
            train_cfg,
            trained=trained_by,
            physics=cfg.physics,
            sample=cfg.sample,
            intent_emb=intent_emb,
            **kwargs,
        )
        physics_s += report.get("seconds", 0.0)  # a fine-tuning recipe's own simulation
        trained_by[method] = trained
        train_s = time.perf_counter() - t0
        timing["train_s"] += train_s
        checkpoints.save(
            Path(ev_cfg.runs) / method,
            trained.params,
            {
                **checkpoints.meta_of(trained),
                "variant": method,
                "config": dataclasses.asdict(train_cfg),
                "run_config": configs.to_dict(cfg),
                "library_sha256": library.file_hash(lib.path),
                "step": cfg.train.steps,
            },
        )
        cond_eval = entry.condition.conditions(lib.heldout, intent_emb, heldout_text)
        t_eval = time.perf_counter()
        u, r, div, cov, time_calls[method], throughput = evaluate(
            method, trained, lib, cfg, cond_eval, jax.random.fold_in(key, len(rows)), mesh
        )
        timing["evaluate_s"] += time.perf_counter() - t_eval
        t_dist = time.perf_counter()
        dist_row = (
            distribution_row(u, lib.heldout.intent, lib.heldout.intensity, ev, radius) if ev is not None else None
        )
        timing["distribution_s"] += time.perf_counter() - t_dist
        phys = (
            physics(u, ref_backbone, tol, ev_cfg.engine, ev_cfg.physics_samples, cfg.physics.trunk)
            if simulate
            else NO_PHYSICS
        )
        physics_s += phys.seconds
        samples[method] = u[0]  # seed 0, for the figures
        succ = (r[:, :, 0] <= ev_cfg.tau).mean(axis=1)  # one sample per held-out tuple (paper protocol)
        row = rows[method] = Row(
            success=mean_std(succ),
            success_all_samples=mean_std((r <= ev_cfg.tau).mean(axis=(1, 2))),
            rms=mean_std(r.mean(axis=(1, 2))),
            diversity=mean_std(div),
            coverage=mean_std(cov),
            time_ms=float("nan"),  # measured below, every method in alternation
            time_measures=latency.measures(trained),
            throughput_per_s=float(throughput),
            train_s=train_s,
            first_sample_success_per_seed=tuple(float(x) for x in succ),
            distribution=dist_row,
            physics=phys,
        )
        per_sample[method] = r
        print(
            f"{DISPLAY[method]:24s} success {row.success[0]:.3f} ± {row.success[1]:.3f}"
            f"  div {row.diversity[0]:.3f}  train {train_s:.0f} s  feasible "
            f"{phys.feasible[0]:.4f} over {phys.samples} simulated samples ({phys.seconds:.0f} s)",
            flush=True,
        )
    t_time = time.perf_counter()  # Table II's Time: the methods in alternation, so drift falls on all alike
    rounds = latency.interleaved_ms(time_calls, rounds=TIME_ROUNDS)
    for method, ms in rounds.items():
        med, lo, hi = latency.median_interval(ms)
        rows[method] = dataclasses.replace(
            rows[method], time_ms=med, time_rounds_ms=tuple(float(x) for x in ms), time_interval_ms=(lo, hi)
        )
        print(f"{DISPLAY[method]:24s} time {med:.3f} ms [{lo:.3f}, {hi:.3f}]", flush=True)
    timing["latency_s"] = time.perf_counter() - t_time
    public, dist_refs = {}, {}
    if ev is not None and ev_cfg.library is None:  # the shipped model through jg.sample, as users call it
        t_pub = time.perf_counter()
        public = {name: public_row(lib, cfg, radius, cur) for name, cur in (("default", "default"), ("none", None))}
        timing["public_s"] = time.perf_counter() - t_pub
        print(
            "jg.sample (shipped model): Prec@r default current "
            f"{fmt(public['default'].mean_std['prec_r'])}, current=None {fmt(public['none'].mean_std['prec_r'])}",
            flush=True,
        )
    if ev is not None:
        t_ref = time.perf_counter()
        dist_refs = {
            name: distribution_row(x[None], np.arange(64) // 4, np.arange(64) % 4, ev, radius)
            for name, x in distribution.reference_samples(lib, k=ev_cfg.num_samples).items()
        }
        timing["distribution_references_s"] = time.perf_counter() - t_ref
    refs, ref_phys = references(lib, ev_cfg, ref_backbone, tol, simulate, cfg.physics.trunk)
    physics_s += sum(p.seconds for p in ref_phys.values())
    timing["physics_s"] = physics_s
    timing["run_s"] = time.perf_counter() - t_run
    return AblationResult(
        config=cfg,
        rows=rows,
        references=refs,
        reference_physics=ref_phys,
        distribution_references=dist_refs,
        public=public,
        radius=None if radius is None else float(radius),
        shape_tolerance=tol,
        physics_engine=sim.resolve_engine(ev_cfg.engine),
        library_version=lib.meta.get("library_version"),
        timing=Timing(**timing),
        environment=environment(),
        date=datetime.datetime.now().isoformat(timespec="seconds"),
        machine=f"{platform.node()} · {bench_sample.cpu_model()} ({bench_sample.cpu_isa()}) · "
        f"{__import__('os').cpu_count()} cores · jax {jax.__version__} ({jax.default_backend()}) · "
        f"MuJoCo {__import__('mujoco').__version__}",
        per_sample_rms=per_sample,
        samples=samples,
    )


def cross_validate(cfg: Config, folds: int, only: int | None = None) -> int:
    """Run the ablation once per fold (realization k of every tuple held out) and pool the 4 x 64 targets;
    ``only``: that one fold (a smoke test of the whole path; the table then pools one fold)."""
    from jgrounding.io import write_atomic

    t0 = time.perf_counter()
    base = load_library(cfg.eval.library)
    per_fold = []
    for k in range(folds) if only is None else (only,):
        fcfg = configs.override(cfg, f"eval.runs={Path(cfg.eval.runs) / f'fold{k}'}")
        res = run(fcfg, lib=library.fold(base, k))
        per_fold.append(res)
        print(f"fold {k}: " + ", ".join(f"{m} {r.success[0]:.3f}" for m, r in res.rows.items()), flush=True)
    tau = float(cfg.eval.tau)
    lines = [
        f"{folds}-fold cross-validation (each realization held out once: {folds * 64} targets), "
        + ("" if only is None else f"fold {only} only ({len(per_fold) * 64} targets), ")
        + f"{len(cfg.eval.seeds)} seeds, {cfg.train.steps} steps, tau = {tau}.",
        "",
        "| Method | Succ. (mean ± std over seeds, pooled over folds) | per fold |",
        "|---|---|---|",
    ]
    pooled = {}
    for m in per_fold[0].rows:
        succ = np.stack([(f.per_sample_rms[m][:, :, 0] <= tau).mean(axis=1) for f in per_fold])  # (folds, S)
        pooled[m] = {"success": mean_std(succ.mean(axis=0)), "per_fold": [float(x) for x in succ.mean(axis=1)]}
        lines.append(
            f"| {DISPLAY[m]} | {fmt(pooled[m]['success'])} | "
            + ", ".join(f"{x:.3f}" for x in pooled[m]["per_fold"])
            + " |"
        )
    for name, label in REFERENCES:
        vals = [f.references[name].success[tau][0] for f in per_fold if name in f.references]
        if vals:
            lines.append(
                f"| {label} | {np.mean(vals):.3f} ± {np.std(vals):.3f} (over folds) | "
                + ", ".join(f"{x:.3f}" for x in vals)
                + " |"
            )
    run_s = time.perf_counter() - t0
    lines += ["", f"Run time: {run_s:.0f} s on {per_fold[0].machine}."]
    text = "\n".join(lines) + "\n"
    write_atomic(Path(cfg.eval.out) / "ablation_folds.md", text)
    write_atomic(
        Path(cfg.eval.out) / "ablation_folds.json",
        json.dumps(
            {"config": configs.to_dict(cfg), "folds": folds, "only_fold": only, "rows": pooled, "run_s": run_s},
            indent=1,
            default=float,
        ),
    )
    print(text)
    print(f"{folds}-fold cross-validation run time: {run_s:.0f} s")
    return 0


def rescore_public(cfg: Config) -> int:
    """Re-score only the shipped model's jg.sample rows of an existing <out>/ablation.json (after
    ``experiments.ship`` replaced the shipped model) and rewrite <out>/ablation.{md,csv,json}; Table II's rows,
    trained under the paper's protocol, do not depend on the shipped model and are kept."""
    from jgrounding.policy import sampling

    res = ablation_result.load(cfg.eval.out)
    lib = load_library(cfg.eval.library)
    sampling.load.cache_clear()
    t0 = time.perf_counter()
    public = {name: public_row(lib, cfg, res.radius, cur) for name, cur in (("default", "default"), ("none", None))}
    res = dataclasses.replace(
        res,
        public=public,
        timing=dataclasses.replace(res.timing, public_s=time.perf_counter() - t0),
        public_rescored=datetime.datetime.now().isoformat(timespec="seconds"),
    )
    ablation_result.save(res, cfg.eval.out)
    write(res, cfg.eval.out)
    print(distribution_markdown(res))
    return 0


SHORTHANDS = {  # flags kept from before the composed config: each is one override
    "seeds": "eval.seeds",
    "steps": "train.steps",
    "methods": "eval.rows",
    "engine": "eval.engine",
    "devices": "eval.devices",
}


def configure(args, p: argparse.ArgumentParser) -> Config:
    """The named config (``--config``, ``--quick`` = quick) with the shorthand flags and ``--set`` applied in
    that order; a bad name, section, field or value is a usage error naming the valid ones."""
    overrides = [f"{field}={getattr(args, flag)}" for flag, field in SHORTHANDS.items() if getattr(args, flag)]
    if args.devices is not None and not args.devices:
        overrides.append("eval.devices=0")
    if args.no_physics_aware:
        rows = (args.methods or ",".join(methods.ABLATION_ROWS)).split(",")
        overrides.append("eval.rows=" + ",".join(m for m in rows if methods.spec(m).recipe == "fit"))
    if args.out:
        overrides += [f"eval.out={args.out}", f"eval.runs={Path(args.out) / 'runs'}"]
    if args.library:  # its results go beside the shipped ones, not over them
        out = args.out or str(Path("results") / Path(args.library).stem)
        overrides += [f"eval.library={args.library}", f"eval.out={out}", f"eval.runs={Path(out) / 'runs'}"]
    try:
        return configs.get("quick" if args.quick else args.config, [*overrides, *args.set])
    except ValueError as e:
        p.error(str(e))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    configs.add_arguments(p, "eval.seeds=0,1")
    p.add_argument(
        "--rescore-public",
        action="store_true",
        help="only re-score the shipped model's jg.sample rows of an existing <out>/ablation.json",
    )
    p.add_argument("--quick", action="store_true", help="= --config quick (tiny configuration for smoke tests)")
    p.add_argument("--seeds", help="comma-separated seeds (= --set eval.seeds=...)")
    p.add_argument("--steps", type=int, help="training steps (= --set train.steps=...)")
    p.add_argument("--out", help="results folder (its checkpoints under <out>/runs)")
    p.add_argument(
        "--methods",
        help=f"comma-separated registry entries (= --set eval.rows=...; default {','.join(methods.ABLATION_ROWS)})",
    )
    p.add_argument("--engine", choices=sim.ENGINES, help="trunk engine of the physics columns (default auto)")
    p.add_argument("--no-physics-aware", action="store_true", help="skip the physics-aware RF row")
    p.add_argument(
        "--devices", type=int, help="devices of the mesh (0 = all; default 1 = no mesh); see docs/distributed.md"
    )
    p.add_argument(
        "--library",
        help="library .npz to run Table II on (default: the shipped one), e.g. imported "
        "with python -m jgrounding.library import; results go to results/<its name> unless --out",
    )
    p.add_argument(
        "--folds",
        type=int,
        choices=(4,),
        help="4-fold cross-validation: each realization held out once "
        "(256 targets); writes <out>/ablation_folds.{md,json}",
    )
    p.add_argument("--only-fold", type=int, choices=range(4), help="with --folds: run this fold only (smoke test)")
    args = p.parse_args(argv)
    cfg = configure(args, p)
    if cfg.eval.devices != 1:
        distributed.initialize()
    t0 = time.perf_counter()
    if args.rescore_public:
        return rescore_public(cfg)
    if args.only_fold is not None and not args.folds:
        p.error("--only-fold needs --folds 4")
    if args.folds:
        return cross_validate(cfg, args.folds, only=args.only_fold)
    res = run(cfg)
    ablation_result.save(res, cfg.eval.out)
    write(res, cfg.eval.out)
    from experiments import ablation_figures

    if cfg.eval.library is None:  # the figures show tuples of the shipped library
        for path in ablation_figures.write(res.samples, load_library(), cfg.eval.out):
            print(f"wrote {path}")
    print()
    print(markdown(res))
    for f in findings(res):
        print("-", f)
    print()
    print(distribution_markdown(res))
    print(
        f"\nphysics ({res.config.eval.physics_samples} of each tuple's {res.config.eval.num_samples} samples simulated, "
        f"engine {res.physics_engine}): {res.timing.physics_s:.0f} s of the run's "
        f"{res.timing.run_s:.0f} s ({100 * res.timing.physics_s / res.timing.run_s:.0f}%)"
    )
    print(f"wrote {cfg.eval.out}/ablation.{{md,csv,json}} in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
