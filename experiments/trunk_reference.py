"""Recordings of the physical reference (a Cosserat rod in PyElastica, :mod:`jgrounding.sim.reference`) for the
library's commands: ``python -m experiments.trunk_reference``.

It drives the rod with the built-in library's commands and records what a lab's motion capture records
(markers on the backbone and the tip at 120 Hz, with noise), in the recording format of
:mod:`jgrounding.sim.recordings`:

- ``train/``: the library's 192 training commands; ``heldout/``: its 64 held-out realizations (with train,
  the 256 demonstrations); ``evaluation/``: ``--eval-per-tuple`` realizations of every tuple of its evaluation
  set (never fitted on).
- Written once under ``--out`` (default ``runs/trunk_reference``), with ``provenance.json`` (parameters,
  library hash, versions), ``trunk_reference.sha256`` (every file's hash but ``timing.json``, this machine's
  time per trajectory) and ``backbone.npz`` (the rod's backbone per control step); a later run with the
  same provenance reuses them (``--force`` regenerates, ``--verify`` checks the hashes). The full set is
  over 30 MB, so the repository ships a 16-recording example instead, ``assets/trunk_reference/example``
  (two training recordings of one tuple for every other intent), with its own hash file.
- Then it measures, and writes ``results/trunk_reference.md``: each intent's kinematic signatures on the
  rod's motion for the 256 demonstrations (beside the MuJoCo trunk's), and the backbone / tip RMS of the
  hand-tuned MuJoCo trunk against the rod on the same commands.

``--quick`` is a short, coarse case for CI (2 recordings of 1.2 s on a 12-element rod, seconds).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "runs" / "trunk_reference"
EXAMPLE = ROOT / "assets" / "trunk_reference" / "example"
RESULTS = ROOT / "results" / "trunk_reference.md"
HASH_FILE = "trunk_reference.sha256"
TIMING_FILE = "timing.json"  # how long this machine took: not part of the content, not hashed
SEED = 56
SPLITS = ("train", "heldout", "evaluation")
EVAL_PER_TUPLE = 2  # evaluation realizations per tuple: 128 of the 1024, to stay under ~20 min on 2 cores
QUICK_STEPS, QUICK_ELEMENTS = 36, 12


@dataclasses.dataclass(frozen=True)
class Job:
    split: str
    index: int  # within the split's selection
    name: str
    intent: str
    intensity: str
    u: np.ndarray  # (T_c, 4)


def select(lib, eval_per_tuple: int) -> list[Job]:
    """The commands to record: every train and held-out record, and the first ``eval_per_tuple`` evaluation
    realizations of every tuple."""
    from jgrounding.vocabulary import INTENSITIES, INTENTS

    jobs = []
    for split, part in (("train", lib.train), ("heldout", lib.heldout)):
        for i in range(len(part)):
            m, z = INTENTS[part.intent[i]], INTENSITIES[part.intensity[i]]
            jobs.append(Job(split, i, f"{split}_{i:04d}_{m}_{z}", m, z, np.asarray(part.u[i], np.float64)))
    ev, seen = lib.evaluation, {}
    for i in range(len(ev)):
        key = (int(ev.intent[i]), int(ev.intensity[i]))
        seen[key] = seen.get(key, 0) + 1
        if seen[key] <= eval_per_tuple:
            m, z = INTENTS[key[0]], INTENSITIES[key[1]]
            k = sum(j.split == "evaluation" for j in jobs)
            jobs.append(Job("evaluation", k, f"evaluation_{i:04d}_{m}_{z}", m, z, np.asarray(ev.u[i], np.float64)))
    return jobs


def _simulate(args) -> tuple[np.ndarray, np.ndarray, float]:
    """(markers (T, M, 3) with noise, backbone at the MuJoCo trunk's points per control step, seconds) of one
    job; run in a worker process."""
    from experiments.trunk_reference_checks import rod_rollout
    from jgrounding.sim import reference

    job, n_elements, seed = args
    t0 = time.perf_counter()
    nodes = reference.simulate(job.u, n_elements=n_elements)
    rng = np.random.default_rng([seed, SPLITS.index(job.split), job.index])
    markers = reference.markers(nodes[:-1], rng=rng)
    backbone = rod_rollout(nodes[None]).backbone[0]
    return markers, backbone.astype(np.float32), time.perf_counter() - t0


def run_jobs(jobs: list[Job], n_elements: int, workers: int, seed: int = SEED) -> list:
    """Every job's result, in order, with progress on stdout."""
    args = [(j, n_elements, seed) for j in jobs]
    out, t0 = [], time.perf_counter()

    def progress(k):
        el = time.perf_counter() - t0
        print(f"  {k}/{len(jobs)} recordings, {el:.0f} s, ~{el / k * (len(jobs) - k):.0f} s left", flush=True)

    if workers > 1 and len(jobs) > 1:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(workers) as pool:
            for k, r in enumerate(pool.imap(_simulate, args, chunksize=1), 1):
                out.append(r)
                if k % 8 == 0 or k == len(jobs):
                    progress(k)
    else:
        for k, a in enumerate(args, 1):
            out.append(_simulate(a))
            if k % 8 == 0 or k == len(jobs):
                progress(k)
    return out


def recordings_of(jobs, results) -> list:
    from jgrounding.sim import reference
    from jgrounding.sim.recordings import Recording

    out = []
    for job, (markers, _, _) in zip(jobs, results):
        per = len(markers) // len(job.u)
        out.append(
            Recording(
                name=job.name,
                t=np.arange(len(markers)) / reference.RECORD_HZ,
                u=np.repeat(job.u, per, axis=0),
                markers=markers,
                marker_names=reference.MARKER_NAMES,
                marker_s=np.asarray(reference.MARKER_S),
                intent=job.intent,
                intensity=job.intensity,
            )
        )
    return out


def hash_tree(folder: Path) -> list[str]:
    """``sha256  relative/path`` of every file under ``folder`` but the hash file, sorted."""
    lines = []
    for p in sorted(folder.rglob("*")):
        if p.is_file() and p.name not in (HASH_FILE, TIMING_FILE) and not p.name.startswith("."):
            lines.append(f"{hashlib.sha256(p.read_bytes()).hexdigest()}  {p.relative_to(folder).as_posix()}")
    return lines


def write_hashes(folder: Path) -> str:
    from jgrounding.io import write_atomic

    lines = hash_tree(folder)
    write_atomic(folder / HASH_FILE, "\n".join(lines) + "\n")
    return hashlib.sha256("\n".join(lines).encode()).hexdigest()


def verify(folder: Path) -> list[str]:
    """The differences between ``folder``'s files and its hash file (none: it holds what was written)."""
    path = folder / HASH_FILE
    if not path.is_file():
        return [f"{path}: no hash file (generate with python -m experiments.trunk_reference)"]
    want = set(path.read_text().splitlines())
    have = set(hash_tree(folder))
    return [f"changed or missing: {w.split('  ', 1)[1]}" for w in sorted(want - have)] + [
        f"not in the hash file: {h.split('  ', 1)[1]}" for h in sorted(have - want)
    ]


def provenance(lib, jobs, n_elements: int, eval_per_tuple: int, quick: bool) -> dict:
    import importlib.metadata

    import numba

    from jgrounding.sim import reference

    return {
        "generator": "python -m experiments.trunk_reference" + (" --quick" if quick else ""),
        "parameters": dataclasses.asdict(reference.PARAMETERS),
        "damping_constant_per_s": reference.PARAMETERS.damping_constant,
        "n_elements": n_elements,
        "record_hz": reference.RECORD_HZ,
        "markers": dict(zip(reference.MARKER_NAMES, reference.MARKER_S)),
        "marker_noise_m": reference.MARKER_NOISE_M,
        "seed": SEED,
        "eval_per_tuple": eval_per_tuple,
        "library_sha256": str(lib.meta.get("content_sha256", "")),
        "counts": {s: sum(j.split == s for j in jobs) for s in SPLITS},
        "pyelastica": importlib.metadata.version("pyelastica"),
        "numba": numba.__version__,
        "numpy": np.__version__,
    }


def generate(out: Path, *, n_elements: int, eval_per_tuple: int, workers: int, quick: bool, force: bool):
    """Write (or reuse) the recordings under ``out``; returns (jobs, results or None when reused, provenance)."""
    import jgrounding as jg
    from jgrounding.io import write_atomic
    from jgrounding.sim.recordings import write_recordings

    lib = jg.load_library()
    jobs = select(lib, eval_per_tuple)
    if quick:
        jobs = [dataclasses.replace(j, u=j.u[:QUICK_STEPS]) for j in (jobs[0], jobs[-1])]
    prov = provenance(lib, jobs, n_elements, eval_per_tuple, quick)
    old = out / "provenance.json"
    if not force and old.is_file() and not verify(out):
        stored = json.loads(old.read_text())
        if stored == json.loads(json.dumps(prov)):  # as stored: tuples are lists
            print(f"{out}: recordings already there (hashes match); --force regenerates them")
            timing = out / TIMING_FILE
            return jobs, None, {**stored, "timing": json.loads(timing.read_text()) if timing.is_file() else {}}
    print(f"simulating {len(jobs)} recordings on a {n_elements}-element rod with {workers} worker(s)", flush=True)
    t0 = time.perf_counter()
    results = run_jobs(jobs, n_elements, workers)
    wall = time.perf_counter() - t0
    recs = recordings_of(jobs, results)
    out.mkdir(parents=True, exist_ok=True)
    source = {"source": "the physical reference (python -m experiments.trunk_reference)"}
    for split in SPLITS:
        part = [r for r, j in zip(recs, jobs) if j.split == split]
        if part:
            write_recordings(out / split, part, extra=source)
    bb = {
        s: np.stack([r[1] for r, j in zip(results, jobs) if j.split == s])
        for s in SPLITS
        if any(j.split == s for j in jobs)
    }
    with tempfile.NamedTemporaryFile(dir=out, suffix=".npz", delete=False) as f:
        np.savez_compressed(f, **bb)
    os.replace(f.name, out / "backbone.npz")
    per = [r[2] for r in results]
    timing = {
        "seconds_per_trajectory_mean": float(np.mean(per)),
        "seconds_per_trajectory_max": float(np.max(per)),
        "wall_seconds": wall,
        "workers": workers,
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs",
        "load_average_1min_at_end": os.getloadavg()[0],
    }
    write_atomic(out / "provenance.json", json.dumps(prov, indent=1) + "\n")
    write_atomic(out / TIMING_FILE, json.dumps(timing, indent=1) + "\n")
    prov = {**prov, "timing": timing}
    digest = write_hashes(out)
    print(
        f"wrote {len(recs)} recordings to {out} in {wall:.0f} s ({np.mean(per):.2f} s per trajectory); sha256 {digest[:16]}"
    )
    return jobs, results, prov


def write_example(out: Path, jobs) -> Path:
    """The shipped example: two training recordings of one tuple for every other intent (intensities in turn), 16
    in all, copied from ``out/train``: varied enough to calibrate on, and a library import's split works on it."""
    from jgrounding.sim.recordings import load_recordings, write_recordings
    from jgrounding.vocabulary import INTENSITIES, INTENTS

    recs = {r.name: r for r in load_recordings(out / "train")}
    pick = []
    for k, name in enumerate(INTENTS[::2]):
        level = INTENSITIES[k % len(INTENSITIES)]
        own = [j for j in jobs if j.split == "train" and (j.intent, j.intensity) == (name, level)]
        pick += [recs[j.name] for j in own[:2]]
    source = {"source": "the physical reference (python -m experiments.trunk_reference); full set in runs/"}
    write_recordings(EXAMPLE, pick, extra=source)
    write_hashes(EXAMPLE)
    print(f"wrote the example folder {EXAMPLE.relative_to(ROOT)} ({len(pick)} recordings)")
    return EXAMPLE


def main(argv: list[str] | None = None) -> int:
    from jgrounding.sim import reference

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", type=Path, default=OUT, help=f"where the recordings go (default {OUT.relative_to(ROOT)})")
    p.add_argument("--elements", type=int, default=None, help=f"rod elements (default {reference.N_ELEMENTS})")
    p.add_argument("--eval-per-tuple", type=int, default=EVAL_PER_TUPLE, help="evaluation realizations per tuple")
    p.add_argument("--workers", type=int, default=None, help="processes (default 2; 1 with --quick)")
    p.add_argument("--force", action="store_true", help="regenerate even when the recordings are there")
    p.add_argument("--verify", action="store_true", help="only check --out and the example against their hash files")
    p.add_argument("--no-report", action="store_true", help="write the recordings only, not results/trunk_reference.md")
    p.add_argument("--quick", action="store_true", help="CI: 2 short recordings on a coarse rod; no example, no report")
    args = p.parse_args(argv)
    if args.verify:
        bad = [f"{args.out}: {b}" for b in verify(args.out)] + [f"{EXAMPLE}: {b}" for b in verify(EXAMPLE)]
        print("\n".join(bad) or "hashes match")
        return 1 if bad else 0
    if not 1 <= args.eval_per_tuple <= 16:
        p.error(f"--eval-per-tuple must be in 1..16 (the evaluation set has 16 per tuple), got {args.eval_per_tuple}")
    n = args.elements or (QUICK_ELEMENTS if args.quick else reference.N_ELEMENTS)
    out = args.out.parent / f"{args.out.name}_quick" if args.quick and args.out == OUT else args.out
    if n < 8:
        p.error(f"--elements must be >= 8, got {n}")
    workers = args.workers or (1 if args.quick else min(2, os.cpu_count() or 1))
    jobs, results, prov = generate(
        out, n_elements=n, eval_per_tuple=args.eval_per_tuple, workers=workers, quick=args.quick, force=args.force
    )
    if args.quick:
        from jgrounding.sim.recordings import load_recordings

        back = load_recordings(out / "train")
        print(f"quick: {len(back)} recording(s) read back, markers {back[0].markers.shape}")
        return 0
    write_example(out, jobs)
    if not args.no_report:
        from experiments.trunk_reference_report import report

        report(out, jobs, prov)
    return 0


if __name__ == "__main__":
    sys.exit(main())
