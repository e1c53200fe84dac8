"""Table II reproduced: ``python -m experiments.ablation [--quick]`` (what ``make ablation`` runs).

Trains the five methods over several seeds (vmapped), evaluates them on the 64 held-out tuples with
the paper's metrics (success at tau = 0.35 of one sample per tuple, diversity over K_div = 30 samples,
warm single-trajectory latency), adds the oracle and wrong-intent references, simulates generated
samples on the trunk for the physics columns, and writes results/ablation.{md,csv,json} plus
results/ablation_rms.npz (per-sample RMS, reused by the sweeps). Every cell is mean ± std over seeds.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime
import io
import json
import platform
import time
from pathlib import Path

import jax
import numpy as np

from jgrounding import checkpoints, library, load_library, methods, metrics, semantics, trunk
from jgrounding.training import TrainConfig

PAPER = {  # Table II of the paper: success, diversity, time (ms)
    "raw_dense_cnn": (0.250, 0.000, 0.85), "tuple_dense_cnn": (0.488, 0.000, 0.51),
    "tuple_spline_cnn": (0.562, 0.000, 1.89), "tuple_spline_ddpm": (0.719, 0.165, 7.86),
    "tuple_spline_rf": (0.772, 0.148, 4.87),
}
SHAPE_TAU = 0.05  # m: whole-body shape success threshold (mean backbone distance)


@dataclasses.dataclass(frozen=True)
class AblationConfig:
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    steps: int = 10_000  # Table I
    k_div: int = 30  # Table I
    tau: float = metrics.TAU_RMS
    euler_steps: int = 50  # Table I: S
    physics_samples: int = 5  # samples per held-out tuple simulated (seed 0)
    methods: tuple[str, ...] = methods.METHODS
    out: str = "results"
    runs: str = "runs/ablation"


QUICK = dict(seeds=(0, 1), steps=300, k_div=8, physics_samples=2)


def mean_std(x) -> tuple[float, float]:
    x = np.asarray(x, float)
    return float(x.mean()), float(x.std())


def evaluate(method, trained, lib, cfg, cond_eval, key):
    ho = lib.heldout
    k_gen, k_lat = jax.random.split(key)
    t0 = time.perf_counter()
    u = methods.generate(trained, cond_eval, ho.intensity, k_gen, num_samples=cfg.k_div, steps=cfg.euler_steps)
    batch_s = time.perf_counter() - t0  # includes compilation on first use; re-timed below
    t0 = time.perf_counter()
    u = methods.generate(trained, cond_eval, ho.intensity, k_gen, num_samples=cfg.k_div, steps=cfg.euler_steps)
    batch_s = time.perf_counter() - t0
    r = np.asarray(metrics.rms(u, ho.u[None, :, None]))  # (S, 64, K)
    div = np.asarray(metrics.pairwise_diversity(u)).mean(axis=1)  # (S,)
    lat = methods.latency_fn(trained, 0, steps=cfg.euler_steps)
    jax.block_until_ready(lat(cond_eval[0], ho.intensity[0], k_lat))
    times = []
    for j in range(len(ho)):
        t0 = time.perf_counter()
        jax.block_until_ready(lat(cond_eval[j], ho.intensity[j], jax.random.fold_in(k_lat, j)))
        times.append(time.perf_counter() - t0)
    return u, r, div, 1e3 * float(np.mean(times)), u.shape[0] * u.shape[1] * u.shape[2] / batch_s


def physics(u_seed0, lib, cfg):
    """Shape RMS vs the held-out reference's simulated backbone, feasibility and shape success."""
    ho = lib.heldout
    k = min(cfg.physics_samples, u_seed0.shape[1])
    ref = trunk.rollout(ho.u).backbone  # (64, T, 11, 3)
    sim = trunk.rollout(u_seed0[:, :k].reshape(-1, 150, 4))
    bb = sim.backbone.reshape(len(ho), k, *ref.shape[1:])
    dist = np.linalg.norm(bb - ref[:, None], axis=-1).mean(axis=(-1, -2))  # (64, k) metres
    return {"shape_rms_m": float(dist.mean()), "shape_success": float((dist[:, 0] <= SHAPE_TAU).mean()),
            "feasible": float(trunk.feasible(sim).mean())}


def run(cfg: AblationConfig) -> dict:
    lib = load_library()
    intent_emb = semantics.intent_embeddings()
    train_texts = semantics.embed([t for row in lib.train.texts for t in row]).reshape(len(lib.train), -1, 384)
    heldout_text = semantics.embed([row[0] for row in lib.heldout.texts])
    train_cfg = TrainConfig(steps=cfg.steps, chunk=min(1000, cfg.steps))
    rows, per_sample = {}, {}
    key = jax.random.key(2026)
    for method in cfg.methods:
        raw = methods.spec(method).condition == "raw"
        t0 = time.perf_counter()
        trained = methods.train(method, lib, cfg.seeds, train_cfg, intent_emb=intent_emb,
                                text_emb=train_texts if raw else None)
        train_s = time.perf_counter() - t0
        checkpoints.save(Path(cfg.runs) / method, trained.params,
                         {"method": method, "seeds": list(cfg.seeds), "num_controls": 4,
                          "config": dataclasses.asdict(train_cfg), "library_sha256": library.file_hash(),
                          "step": cfg.steps})
        cond_eval = heldout_text if raw else intent_emb[lib.heldout.intent]
        u, r, div, lat_ms, throughput = evaluate(method, trained, lib, cfg, cond_eval, jax.random.fold_in(key, len(rows)))
        phys = physics(u[0], lib, cfg)
        succ = (r[:, :, 0] <= cfg.tau).mean(axis=1)  # one sample per held-out tuple (paper protocol)
        rows[method] = {
            "success": mean_std(succ), "success_all_samples": mean_std((r <= cfg.tau).mean(axis=(1, 2))),
            "rms": mean_std(r.mean(axis=(1, 2))), "diversity": mean_std(div), "time_ms": lat_ms,
            "throughput_per_s": throughput, "train_s": train_s, **phys,
        }
        per_sample[method] = r
        print(f"{methods.DISPLAY[method]:24s} success {rows[method]['success'][0]:.3f} ± {rows[method]['success'][1]:.3f}"
              f"  div {rows[method]['diversity'][0]:.3f}  time {lat_ms:.3f} ms  train {train_s:.0f} s", flush=True)
    refs = metrics.reference_baselines(lib, seed=0, draws=max(len(cfg.seeds), 5))
    ref_phys = {}
    rng = np.random.default_rng(0)
    for name in ("oracle", "wrong_intent_any_intensity"):
        pick = []
        for j in range(len(lib.heldout)):
            same = (lib.train.intent == lib.heldout.intent[j])
            pool = np.flatnonzero(same & (lib.train.intensity == lib.heldout.intensity[j])) if name == "oracle" \
                else np.flatnonzero(~same)
            pick.append(lib.train.u[rng.choice(pool)])
        ref_phys[name] = physics(np.stack(pick)[:, None], lib, dataclasses.replace(cfg, physics_samples=1))
    return {"config": dataclasses.asdict(cfg), "rows": rows, "references": refs, "reference_physics": ref_phys,
            "per_sample_rms": per_sample, "date": datetime.datetime.now().isoformat(timespec="seconds"),
            "machine": f"{platform.node()} · {platform.processor() or platform.machine()} · "
                       f"{__import__('os').cpu_count()} cores · jax {jax.__version__} ({jax.default_backend()})"}


def fmt(ms):
    return f"{ms[0]:.3f} ± {ms[1]:.3f}"


def markdown(res: dict) -> str:
    cfg = res["config"]
    lines = [f"Ablation (Table II), {len(cfg['seeds'])} seeds, {cfg['steps']} steps, K_div = {cfg['k_div']}, "
             f"tau = {cfg['tau']}, S = {cfg['euler_steps']}. {res['date']}, {res['machine']}.", "",
             "| Method | Succ. | Succ. (all samples) | Div. | Time (ms) | Shape RMS (m) | Shape succ. | Feasible |"
             " Paper Succ. / Div. / Time |",
             "|---|---|---|---|---|---|---|---|---|"]
    for m, r in res["rows"].items():
        p = PAPER[m]
        lines.append(f"| {methods.DISPLAY[m]} | {fmt(r['success'])} | {fmt(r['success_all_samples'])} | "
                     f"{fmt(r['diversity'])} | {r['time_ms']:.3f} | {r['shape_rms_m']:.3f} | {r['shape_success']:.3f} | "
                     f"{r['feasible']:.3f} | {p[0]:.3f} / {p[1]:.3f} / {p[2]:.2f} |")
    tau = float(cfg["tau"])
    for name, label in (("oracle", "Oracle (replay same tuple)"), ("wrong_intent_any_intensity", "Wrong intent (replay)")):
        s = res["references"][name]["success"][tau]
        ph = res["reference_physics"][name]
        lines.append(f"| {label} | {s[0]:.3f} ± {s[1]:.3f} | – | – | – | {ph['shape_rms_m']:.3f} | "
                     f"{ph['shape_success']:.3f} | {ph['feasible']:.3f} | – |")
    return "\n".join(lines) + "\n"


def findings(res: dict) -> list[str]:
    r = res["rows"]
    out = []
    if "tuple_spline_rf" in r and "tuple_spline_ddpm" in r:
        a, b = r["tuple_spline_rf"], r["tuple_spline_ddpm"]
        out.append(f"RF vs DDPM success: {a['success'][0]:.3f} vs {b['success'][0]:.3f} "
                   f"({'RF higher' if a['success'][0] > b['success'][0] else 'RF not higher'}); "
                   f"time {a['time_ms']:.3f} vs {b['time_ms']:.3f} ms "
                   f"({'RF faster' if a['time_ms'] < b['time_ms'] else 'RF not faster'}).")
    cnn = [m for m in r if m.endswith("cnn")]
    if cnn:
        out.append("CNN diversity: " + ", ".join(f"{methods.DISPLAY[m]} {r[m]['diversity'][0]:.4f}" for m in cnn)
                   + (" (all 0: deterministic)" if all(r[m]['diversity'][0] < 1e-6 for m in cnn) else ""))
    if "tuple_spline_rf" in r and cnn:
        best_cnn = max(r[m]["success"][0] for m in cnn)
        out.append(f"RF success {r['tuple_spline_rf']['success'][0]:.3f} vs best CNN {best_cnn:.3f}.")
    return out


def write(res: dict, out: str) -> None:
    from jgrounding.export import write_atomic

    outdir = Path(out)
    md = markdown(res)
    write_atomic(outdir / "ablation.md", md + "\n" + "\n".join(f"- {f}" for f in findings(res)) + "\n")
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["method", "success_mean", "success_std", "success_all_mean", "success_all_std", "diversity_mean",
                "diversity_std", "rms_mean", "time_ms", "throughput_per_s", "shape_rms_m", "shape_success",
                "feasible", "train_s"])
    for m, r in res["rows"].items():
        w.writerow([m, *r["success"], *r["success_all_samples"], *r["diversity"], r["rms"][0], r["time_ms"],
                    r["throughput_per_s"], r["shape_rms_m"], r["shape_success"], r["feasible"], r["train_s"]])
    write_atomic(outdir / "ablation.csv", buf.getvalue())
    light = {k: v for k, v in res.items() if k != "per_sample_rms"}
    write_atomic(outdir / "ablation.json", json.dumps(light, indent=1, default=float))
    b = io.BytesIO()
    np.savez(b, **res["per_sample_rms"])
    write_atomic(outdir / "ablation_rms.npz", b.getvalue())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="tiny configuration for smoke tests")
    p.add_argument("--seeds", help="comma-separated seeds")
    p.add_argument("--steps", type=int)
    p.add_argument("--out")
    p.add_argument("--methods", help=f"comma-separated subset of {','.join(methods.METHODS)}")
    p.add_argument("--no-readme", action="store_true", help="do not regenerate the README results section")
    args = p.parse_args(argv)
    cfg = AblationConfig(**QUICK) if args.quick else AblationConfig()
    if args.seeds:
        cfg = dataclasses.replace(cfg, seeds=tuple(int(s) for s in args.seeds.split(",")))
    if args.steps:
        cfg = dataclasses.replace(cfg, steps=args.steps)
    if args.out:
        cfg = dataclasses.replace(cfg, out=args.out, runs=str(Path(args.out) / "runs"))
    if args.methods:
        chosen = tuple(args.methods.split(","))
        for m in chosen:
            methods.spec(m)
        cfg = dataclasses.replace(cfg, methods=chosen)
    t0 = time.perf_counter()
    res = run(cfg)
    write(res, cfg.out)
    print()
    print(markdown(res))
    for f in findings(res):
        print("-", f)
    print(f"\nwrote {cfg.out}/ablation.{{md,csv,json}} in {time.perf_counter() - t0:.0f} s")
    if not args.quick and not args.no_readme and not args.out:
        from experiments import readme

        readme.update()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
