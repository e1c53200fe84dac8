"""Calibration of the trunk checked: ``python -m experiments.trunk_calibration``.

Writes ``results/trunk_calibration.md`` (and ``.json``), section by section; a section not asked for keeps what an
earlier run wrote (each section names the command that made it):

- **Identifiability** (default): recordings made by our own MuJoCo trunk with its fitted parameters perturbed
  inside their bounds (each moved 5-20 %, seeded); calibration from the shipped values must recover each parameter
  within 5 % and the backbone within 1 mm (:mod:`jgrounding.sim.calibration`).
- **Time** (``--benchmark``): one calibration of 10 parameters on 64 recordings (5 s each, 2 markers at 120 Hz),
  timed, with this machine's CPU model, core count and load average.
- **Against the reference** (``--reference FOLDER``): FOLDER is the physical reference's recordings
  (the Cosserat-rod reference's output: ``train/`` and ``evaluation/`` recordings folders). The trunk is
  fitted on the training commands' recordings and judged on the evaluation set's, never fitted on: mean backbone
  RMS of the fitted and of the hand-tuned trunk (goals: <= 20 mm, and <= 1/3 of the hand-tuned trunk's).

``--quick``: one identifiability trial on 4 recordings (the test's size).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from jgrounding.io import write_atomic
from jgrounding.sim import calibration as cal
from jgrounding.sim import mjcf as tm

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "results" / "trunk_calibration"
FITTED = ROOT / "results" / "trunk_reference_fitted.xml"  # the trunk fitted to the reference (--reference)
MARKERS = (("mid", 0.35), ("tip", tm.TRUNK_LENGTH))
BENCH_PARAMETERS = (*cal.FIT_PARAMETERS, "slide_damping", "hinge_armature")
GOAL_REL, GOAL_RMS = 0.05, 0.001
REF_GOAL_M, REF_GOAL_RATIO = 0.020, 1 / 3


def machine() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        cpu = next(ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return f"{cpu}, {os.cpu_count()} cores, load average {load} (1, 5, 15 min)"


def perturbed(rng, parameters, low: float = 0.05, high: float = 0.20) -> tm.TrunkParams:
    """The shipped trunk with each of ``parameters`` moved by 5-20 % (random sign) inside its bounds; the delay
    (0 in the shipped trunk) drawn inside [2 dt, its upper bound / 2]."""
    base, values = tm.TrunkParams(), {}
    for name in parameters:
        lo, hi = cal.DEFAULT_BOUNDS[name]
        if name == "delay":
            values[name] = float(rng.uniform(2 * tm.TIMESTEP, hi / 2))
            continue
        v = getattr(base, name) * (1 + rng.choice([-1, 1]) * rng.uniform(low, high))
        values[name] = float(np.clip(v, lo, hi))
    return base.replace(**values)


def commands(count: int, seed: int) -> np.ndarray:
    from jgrounding import load_library

    lib = load_library()
    u = np.concatenate([lib.train.u, lib.heldout.u])
    return u[np.sort(np.random.default_rng(seed).choice(len(u), size=count, replace=False))]


def recordings(params, count: int, seed: int):
    from jgrounding.sim.synthetic import synthesize

    return synthesize(commands(count, seed), params, [m for m, _ in MARKERS], [s for _, s in MARKERS])


def stable_draw(rng, parameters, count: int, seed: int):
    """A perturbed trunk (:func:`perturbed`) that simulates all ``count`` commands without diverging, and its
    recordings; returns ``(truth, recordings, draws rejected)``. Some perturbations inside the bounds make the chain
    diverge at dt = 1/120 s on some library commands: those are drawn again (a lab's trunk does not diverge)."""
    for rejected in range(50):
        truth = perturbed(rng, parameters)
        try:
            return truth, recordings(truth, count, seed), rejected
        except cal.UnstableError:
            continue
    raise RuntimeError("50 perturbed trunks in a row diverged: the bounds are too wide for the chain")


def identifiability(trials: int, count: int, known: tuple[str, ...] = ()) -> dict:
    """Trials of fitting every default parameter but ``known`` (set to the truth, as a lab that weighed its trunk
    sets the density) on recordings of a perturbed trunk. Besides each parameter's error, the error of its ratio to
    the density (for ``known=()``): motion alone determines the ratios, the common scale only weakly."""
    rows = []
    fitted_names = tuple(n for n in cal.FIT_PARAMETERS if n not in known)
    for trial in range(trials):
        rng = np.random.default_rng(trial)
        truth, recs, rejected = stable_draw(rng, cal.FIT_PARAMETERS, count, seed=100 + trial)
        print(
            f"identifiability trial {trial + 1}/{trials}: {count} recordings ({rejected} diverging draws)", flush=True
        )
        base = tm.TrunkParams().replace(**{n: getattr(truth, n) for n in known})
        settings = cal.Settings(parameters=fitted_names, validation=0.25)
        res = cal.calibrate(recs, base, settings, log=lambda s: print("  " + s, flush=True))
        err = {n: getattr(res.fitted, n) / getattr(truth, n) - 1 for n in fitted_names}
        scale = 1 + err.get("density", 0.0)
        ratio = {n: (1 + e) / scale - 1 for n, e in err.items() if n not in ("density", "delay")}
        rows.append(
            {
                "trial": trial,
                "truth": {n: getattr(truth, n) for n in fitted_names},
                "fitted": {n: getattr(res.fitted, n) for n in fitted_names},
                "rel_error": err,
                "ratio_error": ratio,
                "rms_m": {k: d["after"][0] for k, d in res.rms.items()},
                "start_rms_m": res.rms["fit"]["before"][0],
                "iterations": res.iterations,
                "seconds": res.seconds,
                "diverging_draws": rejected,
            }
        )
    worst = max(abs(e) for r in rows for e in r["rel_error"].values())
    worst_rms = max(v for r in rows for v in r["rms_m"].values())
    flag = f" --known {','.join(known)}" if known else ""
    return {
        "command": f"python -m experiments.trunk_calibration --trials {trials} --count {count}{flag}",
        "known": list(known),
        "worst_ratio_error": max((abs(e) for r in rows for e in r["ratio_error"].values()), default=0.0),
        "rows": rows,
        "worst_rel_error": worst,
        "worst_rms_m": worst_rms,
        "met": bool(worst <= GOAL_REL and worst_rms <= GOAL_RMS),
    }


def benchmark(count: int = 64) -> dict:
    truth, recs, _ = stable_draw(np.random.default_rng(7), BENCH_PARAMETERS, count, seed=7)
    settings = cal.Settings(parameters=BENCH_PARAMETERS, validation=0.0)
    before = machine()
    print(f"benchmark: {len(BENCH_PARAMETERS)} parameters on {count} recordings; {before}", flush=True)
    t0 = time.perf_counter()
    res = cal.calibrate(recs, settings=settings, log=lambda s: print("  " + s, flush=True))
    seconds = time.perf_counter() - t0
    return {
        "command": "python -m experiments.trunk_calibration --benchmark",
        "parameters": list(BENCH_PARAMETERS),
        "recordings": count,
        "seconds": seconds,
        "optimizer_seconds": res.seconds,
        "iterations": res.iterations,
        "rms_after_m": res.rms["fit"]["after"][0],
        "machine_before": before,
        "machine_after": machine(),
        "max_rel_error": max(abs(getattr(res.fitted, n) / getattr(truth, n) - 1) for n in BENCH_PARAMETERS),
    }


def mean_rms(recs, params: tm.TrunkParams) -> float:
    """Mean over recordings of each recording's backbone RMS (m) on trunk ``params``."""
    settings = cal.Settings(parameters=("tendon_force",), validation=0.0)
    prob = cal.problem(recs, params, settings)
    per = [np.sqrt(np.mean(np.sum((rec - sim) ** 2, -1))) for _, _, rec, sim in cal.paths(prob, params)]
    return float(np.mean(per))


def against_reference(folder: Path, fit_count: int | None, max_iters: int) -> dict:
    from jgrounding.sim.recordings import load_recordings

    train, evaluation = load_recordings(folder / "train"), load_recordings(folder / "evaluation")
    if fit_count:
        train = [train[i] for i in np.linspace(0, len(train) - 1, fit_count).astype(int)]
    print(f"against the reference: fitting on {len(train)} recordings, judging on {len(evaluation)}", flush=True)
    res = cal.calibrate(train, settings=cal.Settings(validation=0.0, max_iters=max_iters), log=print)
    fitted, hand = mean_rms(evaluation, res.fitted), mean_rms(evaluation, tm.TrunkParams())
    from jgrounding.sim import calibration_report

    # The fitted trunk, with its provenance, for what runs on it next (Table II's physics columns, screening).
    FITTED.parent.mkdir(parents=True, exist_ok=True)
    calibration_report.write(res, FITTED, train, str(folder / "train"), html=False, log=print)
    return {
        "fitted_trunk": str(FITTED.relative_to(ROOT)) if FITTED.is_relative_to(ROOT) else str(FITTED),
        "command": f"python -m experiments.trunk_calibration --reference {folder}"
        + (f" --fit-count {fit_count}" if fit_count else ""),
        "fit": len(train),
        "evaluation": len(evaluation),
        "fitted": {n: getattr(res.fitted, n) for n in res.settings.parameters},
        "at_bound": {n: v for n, v in res.at_bound.items() if v},
        "fitted_rms_m": fitted,
        "hand_tuned_rms_m": hand,
        "fit_rms_m": res.rms["fit"]["after"][0],
        "met": bool(fitted <= REF_GOAL_M and fitted <= REF_GOAL_RATIO * hand),
        "seconds": res.seconds,
    }


def _identifiability(ident: dict) -> list[str]:
    out = [
        f"`{ident['command']}`: recordings of our own MuJoCo trunk with each fitted parameter moved 5-20 % inside "
        f"its bounds, fitted from the shipped values. Goal: every parameter within {GOAL_REL:.0%}, backbone RMS within "
        f"{1000 * GOAL_RMS:.0f} mm. Worst relative error {100 * ident['worst_rel_error']:.3f} %, worst backbone RMS "
        f"{1000 * ident['worst_rms_m']:.4f} mm: **{'met' if ident['met'] else 'not met'}**.",
    ]
    if not ident.get("known"):
        out[0] += (
            f" Ratios of the stiffnesses, dampings, tendon force and slide stiffness to the density (what the motion "
            f"determines; a common scale of all of them changes it only through the joints' armature and the slide "
            f"damping) are within {100 * ident.get('worst_ratio_error', float('nan')):.3f} %."
        )
    out += ["", "| trial | parameter | truth | fitted | error |", "|---|---|---|---|---|"]
    for r in ident["rows"]:
        for n in r["truth"]:
            out.append(
                f"| {r['trial']} | {n} | {r['truth'][n]:.5g} | {r['fitted'][n]:.5g} | {100 * r['rel_error'][n]:+.3f} % |"
            )
    out += ["", "| trial | start RMS (mm) | fit RMS (mm) | validation RMS (mm) | iterations | seconds |"]
    out += ["|---|---|---|---|---|---|"]
    for r in ident["rows"]:
        val = r["rms_m"].get("validation")
        out.append(
            f"| {r['trial']} | {1000 * r['start_rms_m']:.2f} | {1000 * r['rms_m']['fit']:.4f} | "
            f"{'-' if val is None else f'{1000 * val:.4f}'} | {r['iterations']} | {r['seconds']:.1f} |"
        )
    return out


def markdown(sections: dict) -> str:
    out = ["# Trunk calibration", "", "Written by `python -m experiments.trunk_calibration` (docs/trunk.md).", ""]
    out += ["## Identifiability", ""]
    ident, known = sections.get("identifiability"), sections.get("identifiability_known")
    out += _identifiability(ident) if ident else ["Not run yet: `python -m experiments.trunk_calibration`."]
    if known:
        out += ["", f"### With {', '.join(known['known'])} known (weighed), the rest fitted", ""]
        out += _identifiability(known)
    bench = sections.get("benchmark")
    out += ["", "## Time", ""]
    if bench:
        out += [
            f"`{bench['command']}`: {len(bench['parameters'])} parameters ({', '.join(bench['parameters'])}) on "
            f"{bench['recordings']} recordings: **{bench['seconds']:.0f} s** in all ({bench['optimizer_seconds']:.0f} s "
            f"in the optimizer, {bench['iterations']} iterations; goal <= 300 s on 2 cores), backbone RMS after "
            f"{1000 * bench['rms_after_m']:.4f} mm, worst parameter error {100 * bench['max_rel_error']:.2f} %.",
            "",
            f"Machine at the start: {bench['machine_before']}. At the end: {bench['machine_after']}. The machine is "
            "shared, so the load average says how much of it the run had.",
        ]
    else:
        out.append("Not run yet: `python -m experiments.trunk_calibration --benchmark`.")
    ref = sections.get("reference")
    out += ["", "## Against the reference", ""]
    if ref:
        out += [
            f"`{ref['command']}`: fitted on {ref['fit']} recordings of the training commands, judged on "
            f"{ref['evaluation']} recordings of the evaluation set (never fitted on). Mean backbone RMS: fitted "
            f"**{1000 * ref['fitted_rms_m']:.1f} mm**, hand-tuned {1000 * ref['hand_tuned_rms_m']:.1f} mm "
            f"(ratio {ref['fitted_rms_m'] / ref['hand_tuned_rms_m']:.2f}); on the fit set {1000 * ref['fit_rms_m']:.1f} "
            f"mm. Goals (<= {1000 * REF_GOAL_M:.0f} mm and <= 1/3 of the hand-tuned): "
            f"**{'met' if ref['met'] else 'not met'}**.",
            "",
            "| parameter | fitted |",
            "|---|---|",
            *[f"| {n} | {v:.5g}{' (at a bound)' if n in ref['at_bound'] else ''} |" for n, v in ref["fitted"].items()],
        ]
    else:
        out.append(
            "Not run yet: `python -m experiments.trunk_calibration --reference runs/trunk_reference` once the "
            "Cosserat-rod reference's recordings (train/ and evaluation/ folders) exist."
        )
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--trials", type=int, default=3, help="identifiability trials (default 3)")
    p.add_argument("--count", type=int, default=8, help="recordings per identifiability trial (default 8)")
    p.add_argument("--quick", action="store_true", help="one identifiability trial on 4 recordings")
    p.add_argument("--no-identifiability", action="store_true", help="keep the earlier identifiability section")
    p.add_argument("--known", help="identifiability with these parameters known (e.g. density: a weighed trunk)")
    p.add_argument("--benchmark", action="store_true", help="time 10 parameters on 64 recordings")
    p.add_argument("--reference", type=Path, help="the reference's recordings (train/ and evaluation/ inside)")
    p.add_argument("--fit-count", type=int, help="fit on this many of the reference's training recordings")
    p.add_argument("--max-iters", type=int, default=40)
    p.add_argument("--out", type=Path, default=OUT, help="results stem (writes .md and .json)")
    args = p.parse_args(argv)
    if args.reference is not None and not (args.reference / "train").is_dir():
        p.error(
            f"--reference {args.reference}: no train/ recordings folder inside (the reference's output folder holds train/ and evaluation/)"
        )
    store = args.out.with_suffix(".json")
    sections = json.loads(store.read_text()) if store.exists() else {}
    if not args.no_identifiability:
        trials, count = (1, 4) if args.quick else (args.trials, args.count)
        if args.known:
            known = tuple(n.strip() for n in args.known.split(",") if n.strip())
            sections["identifiability_known"] = identifiability(trials, count, known)
        else:
            sections["identifiability"] = identifiability(trials, count)
    if args.benchmark:
        sections["benchmark"] = benchmark()
    if args.reference is not None:
        sections["reference"] = against_reference(args.reference, args.fit_count, args.max_iters)
    write_atomic(store, json.dumps(sections, indent=1) + "\n")
    text = markdown(sections)
    write_atomic(args.out.with_suffix(".md"), text)
    print(text)
    print(f"wrote {args.out.with_suffix('.md')} and {store}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
