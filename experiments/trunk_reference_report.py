"""``results/trunk_reference.md``: the reference's parameters, its cost, the library's kinematic signatures on
the rod, and how far the hand-tuned MuJoCo trunk is from the rod (the last step of
``python -m experiments.trunk_reference``)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from experiments import trunk_reference_checks as checks
from jgrounding import sim
from jgrounding.io import write_atomic
from jgrounding.sim import reference
from jgrounding.sim.measures import finish_rollout
from jgrounding.vocabulary import INTENSITIES, INTENTS

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "results" / "trunk_reference.md"
EXAMPLE = ROOT / "assets" / "trunk_reference" / "example"
GOAL = 0.90  # the share of realizations whose signature holds on the rod


def first_mode_hz(n_elements: int = reference.N_ELEMENTS) -> float:
    """The rod's first bending mode (Hz): the peak of the tip's spectrum over 4 s of free decay (damping 0.02/s)
    after tendon 0 held at 0.15 for 1 s."""
    u = np.zeros((150, 4))
    u[:30, 0] = 0.15
    rod = reference.Rod(n_elements, damping=0.02)
    rod.set_state(reference.rest_state(u[0], n_elements))
    x = rod.run(u)[reference.RECORD_HZ : -1, -1, 0]
    x = (x - x.mean()) * np.hanning(len(x))
    pad = 16 * len(x)
    freq = np.fft.rfftfreq(pad, 1.0 / reference.RECORD_HZ)
    return float(freq[1 + np.argmax(np.abs(np.fft.rfft(x, pad))[1:])])


def _fmt(x) -> str:
    if isinstance(x, (tuple, list)):
        return ", ".join(f"{v:g}" for v in x)
    return f"{x:g}" if isinstance(x, float) else str(x)


def _parameters(measured_hz: float) -> list[str]:
    p = reference.PARAMETERS
    lines = ["| parameter | value | source |", "|---|---|---|"]
    for f in dataclasses.fields(p):
        lines.append(f"| {f.name} | {_fmt(getattr(p, f.name))} | {reference.SOURCES[f.name]} |")
    lines += [
        "",
        f"Derived: shear modulus {p.shear_modulus / 1e3:.0f} kPa (E / (2 (1 + nu))); PyElastica's uniform damping "
        f"rate 2 zeta omega_1 = {p.damping_constant:.3f} 1/s. The first bending mode measured again in this run: "
        f"{measured_hz:.3f} Hz (the parameter: {p.first_mode_hz:g} Hz).",
    ]
    return lines


def _failing(rod: dict, rod_f: dict, ours_f: dict, names: list[str]) -> list[str]:
    """One line per realization whose signature fails on the rod: the features it reads, rod and MuJoCo."""
    lines = []
    for intent, r in rod.items():
        for i in r["failing"]:
            vals = ", ".join(
                f"{k} {rod_f[k][i]:.3g} (MuJoCo {ours_f[k][i]:.3g})" for k in checks.FEATURES.get(intent, ())
            )
            lines.append(f"- {names[i]}: {vals}")
    if lines:
        return ["", "The realizations whose signature fails on the rod (features in metres or counts):", "", *lines]
    return []


def _signature_rows(rod: dict, ours: dict) -> list[str]:
    lines = [
        "| intent | realizations | signature (per realization) | holds on the rod | holds on the MuJoCo trunk |",
        "|---|---|---|---|---|",
    ]
    shares = []
    for name in INTENTS:
        if name not in rod:
            continue
        r, o = rod[name], ours[name]
        if r["hold"] is None:
            lines.append(f"| {name} | {r['n']} | none (group checks only) | - | - |")
            continue
        share = r["hold"] / r["n"]
        shares.append(share)
        each = "; ".join(f"{s} ({r['each'][s]}/{r['n']})" for s in r["each"])
        mark = "" if share >= GOAL else " (below 90 %)"
        lines.append(
            f"| {name} | {r['n']} | {each} | {r['hold']}/{r['n']} = {100 * share:.0f} %{mark} | "
            f"{o['hold']}/{o['n']} = {100 * o['hold'] / o['n']:.0f} % |"
        )
    lines += ["", "Group checks (a mean or a median over the intent's realizations):", ""]
    lines += ["| intent | check | rod | MuJoCo trunk |", "|---|---|---|---|"]
    for name in INTENTS:
        if name in rod:
            for (sig, ok), (_, ok_ours) in zip(rod[name]["groups"], ours[name]["groups"]):
                lines.append(f"| {name} | {sig} | {'holds' if ok else 'fails'} | {'holds' if ok_ours else 'fails'} |")
    met = sum(s >= GOAL for s in shares)
    lines += ["", f"{met} of {len(shares)} intents with a per-realization signature hold it for >= 90 % on the rod."]
    return lines


def _distance(out: Path, jobs) -> tuple[list[str], dict]:
    from jgrounding.sim.recordings import load_recordings

    lines = [
        "| commands | recordings | backbone RMS (mm), mean | median | max | tip RMS (mm), mean | max |",
        "|---|---|---|---|---|---|---|",
    ]
    summary, per_intent = {}, {}
    for split in ("train", "heldout", "evaluation"):
        own = [j for j in jobs if j.split == split]
        if not own:
            continue
        recs = {r.name: r for r in load_recordings(out / split)}
        rec = np.stack([recs[j.name].markers for j in own])
        ours = checks.mujoco_markers(np.stack([j.u for j in own]), reference.MARKER_S)
        bb, tip = checks.rms(ours, rec)
        summary[split] = (float(bb.mean()), float(tip.mean()))
        lines.append(
            f"| {split} | {len(own)} | {1e3 * bb.mean():.1f} | {1e3 * np.median(bb):.1f} | {1e3 * bb.max():.1f} | "
            f"{1e3 * tip.mean():.1f} | {1e3 * tip.max():.1f} |"
        )
        for j, b in zip(own, bb):
            per_intent.setdefault(j.intent, []).append(b)
        print(
            f"  {split}: MuJoCo trunk vs rod, backbone RMS {1e3 * bb.mean():.1f} mm, tip RMS {1e3 * tip.mean():.1f} mm"
        )
    lines += ["", "Per intent (every split), mean backbone RMS (mm):", ""]
    lines += ["| " + " | ".join(per_intent) + " |", "|" + "---|" * len(per_intent)]
    lines.append("| " + " | ".join(f"{1e3 * np.mean(v):.0f}" for v in per_intent.values()) + " |")
    return lines, summary


def report(out: Path, jobs, prov: dict) -> Path:
    """Measure everything on the recordings under ``out`` and write :data:`RESULTS`."""
    print("measuring: the first bending mode, the signatures on the rod, the MuJoCo trunk against the rod", flush=True)
    n_el = prov["n_elements"]
    hz = first_mode_hz(n_el)
    print(f"  first bending mode {hz:.3f} Hz")
    bb = np.load(out / "backbone.npz")
    lib_jobs = [j for j in jobs if j.split in ("train", "heldout")]
    backbone = np.concatenate([bb[s] for s in ("train", "heldout") if s in bb.files]).astype(np.float64)
    steps = backbone.shape[1]
    rod_f = sim.features(
        finish_rollout(backbone, np.zeros((len(backbone), steps, 4)), np.zeros((len(backbone), steps)))
    )
    m = np.array([INTENTS.index(j.intent) for j in lib_jobs])
    z = np.array([INTENSITIES.index(j.intensity) for j in lib_jobs])
    ours_f = sim.features(sim.rollout(np.stack([j.u for j in lib_jobs]), engine="native"))
    rod_sig, ours_sig = checks.signatures(rod_f, m, z), checks.signatures(ours_f, m, z)
    for name, r in rod_sig.items():
        if r["hold"] is not None:
            print(f"  {name}: signature holds on the rod for {r['hold']}/{r['n']} ({100 * r['hold'] / r['n']:.0f} %)")
    dist, _ = _distance(out, jobs)
    timing = prov.get("timing", {})
    counts = prov["counts"]
    lines = [
        "# The physical reference: a Cosserat rod of the trunk",
        "",
        "Written by `python -m experiments.trunk_reference` from the recordings it made (`runs/trunk_reference`, "
        f"{counts['train']} training, {counts['heldout']} held-out and {counts['evaluation']} evaluation commands of "
        "the built-in library). The rod (`jgrounding/sim/reference.py`) is PyElastica's Cosserat rod with the "
        "trunk's geometry and tendons and a silicone from its datasheet; it is never tuned toward the MuJoCo trunk.",
        "",
        "## Parameters",
        "",
        *_parameters(hz),
        "",
        "## Recordings and cost",
        "",
        f"{n_el} elements, time step {1e6 * reference.time_step(n_el)[0]:.0f} us ({reference.time_step(n_el)[1]} per "
        f"recorded sample; CFL {reference.CFL} of the axial wave speed); markers {', '.join(f'{n} at {s:g} m' for n, s in zip(reference.MARKER_NAMES, reference.MARKER_S))} "
        f"at {reference.RECORD_HZ} Hz with Gaussian noise of {1e3 * reference.MARKER_NOISE_M:g} mm per axis; "
        f"each recording starts from the rod at rest under gravity (settled {reference.SETTLE_S:g} s, heavily damped).",
        "",
        f"The recordings take {sum(f.stat().st_size for f in out.rglob('*.csv')) / 1e6:.0f} MB of CSV "
        f"(the shipped example: {sum(f.stat().st_size for f in EXAMPLE.rglob('*.csv')) / 1e6:.1f} MB).",
        "",
        f"Time per 5 s trajectory: {timing.get('seconds_per_trajectory_mean', float('nan')):.2f} s mean, "
        f"{timing.get('seconds_per_trajectory_max', float('nan')):.2f} s max per process; the whole set "
        f"{timing.get('wall_seconds', float('nan')) / 60:.1f} min with {timing.get('workers', '?')} worker(s) on "
        f"{timing.get('machine', '?')} (a shared machine, 1-min load average {timing.get('load_average_1min_at_end', float('nan')):.1f} "
        "at the end: on an idle machine it is faster).",
        "",
        "## The library on the physical rod",
        "",
        f"Each intent's kinematic signature (`tests/library/test_signatures.py`) on the rod's motion for the "
        f"library's {len(lib_jobs)} demonstrations (training and held-out realizations), beside the MuJoCo trunk's "
        "on the same commands. The rod's backbone is read at the MuJoCo trunk's points (segment origins and tip, at "
        "their undeformed arc lengths) at the end of each control step.",
        "",
        *_signature_rows(rod_sig, ours_sig),
        *_failing(rod_sig, rod_f, ours_f, [j.name for j in lib_jobs]),
        "",
        "## The hand-tuned MuJoCo trunk against the rod",
        "",
        "The MuJoCo trunk (`jgrounding/assets/trunk.xml`, without the user's body, like the rod) driven by the same "
        f"commands, its markers read at the same arc lengths at {reference.RECORD_HZ} Hz; RMS over markers and "
        "time (backbone) and over time (tip) against the recorded markers (with their noise).",
        "",
        *dist,
        "",
    ]
    write_atomic(RESULTS, "\n".join(lines))
    print(f"wrote {RESULTS}")
    return RESULTS
