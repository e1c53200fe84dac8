"""Time the README's two commands on a fresh clone: ``python -m tools.time_commands test [ablation] [--avx2]``.

Each command runs in a new clone of this checkout's HEAD (``git clone``, so only committed work counts), with
``CI=true`` and empty caches (``XDG_CACHE_HOME`` and ``JGROUNDING_CACHE`` in a new temporary folder: nothing
compiled yet, as on a CI machine; pip's download cache is the machine's). ``--avx2`` sets
``XLA_FLAGS=--xla_cpu_max_isa=AVX2`` (XLA limited to AVX2, as on a machine without AVX-512). The wall time, the
pytest summary and the machine (CPU model, vector ISA, cores) are appended to ``results/timings.json``, and the
table between ``<!-- timings:start -->`` and ``<!-- timings:end -->`` in docs/testing.md is regenerated from it
(the latest record per command and flags), so the figures there are written by this script, never typed in.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from jgrounding.io import write_atomic

ROOT = Path(__file__).resolve().parent.parent
RECORDS = ROOT / "results" / "timings.json"
DOC = ROOT / "docs" / "testing.md"
START, END = "<!-- timings:start -->", "<!-- timings:end -->"
COMMANDS = {"test": ("make", "test"), "ablation": ("make", "ablation")}
GOALS_S = {"test": 6 * 60, "ablation": 12 * 60}  # the goals on a 2-core AVX2 machine
AVX2 = "--xla_cpu_max_isa=AVX2"


def machine() -> dict:
    """CPU model, widest vector ISA and cores of this machine (what every timing is printed with)."""
    from experiments.bench_sample import cpu_isa, cpu_model

    return {"cpu": cpu_model(), "isa": cpu_isa(), "cores": len(os.sched_getaffinity(0))}


def pytest_summary(output: str) -> str:
    """The last pytest result line of ``output`` ("565 passed, 1 xfailed ... in 105.36s"), or ""."""
    lines = [x.strip("= ") for x in output.splitlines() if re.search(r"\b(passed|failed|error)\b.* in [0-9.]+s", x)]
    return lines[-1] if lines else ""


def run(command: str, avx2: bool, repo: Path = ROOT, keep_results: bool = False) -> dict:
    """Clone ``repo``'s HEAD into a temporary folder and time ``COMMANDS[command]`` there; the record.
    ``keep_results``: after a successful run, copy what the command wrote under the clone's ``results/`` back
    into ``repo``'s (the timed ``make ablation`` is then also the run the results come from)."""
    with tempfile.TemporaryDirectory(prefix="jg-time-") as tmp:
        clone, cache = Path(tmp) / "clone", Path(tmp) / "cache"
        subprocess.run(["git", "clone", "--quiet", str(repo), str(clone)], check=True)
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=clone, capture_output=True, text=True)
        env = {**os.environ, "CI": "true", "XDG_CACHE_HOME": str(cache / "xdg"), "JGROUNDING_CACHE": str(cache / "jg")}
        env.pop("XLA_FLAGS", None)
        if avx2:
            env["XLA_FLAGS"] = AVX2
        print(f"{' '.join(COMMANDS[command])} in a fresh clone at {head.stdout.strip()} ...", flush=True)
        t0 = time.perf_counter()
        proc = subprocess.run(COMMANDS[command], cwd=clone, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if keep_results and not proc.returncode:
            for path in sorted((clone / "results").rglob("*")):
                rel = path.relative_to(clone)
                if path.is_file() and (not (repo / rel).exists() or (repo / rel).read_bytes() != path.read_bytes()):
                    write_atomic(repo / rel, path.read_bytes())
                    print(f"kept {rel}", flush=True)
    out = proc.stdout + proc.stderr
    if proc.returncode:
        print(out[-4000:], file=sys.stderr)
    return {
        "command": " ".join(COMMANDS[command]),
        "name": command,
        "rc": proc.returncode,
        "wall_s": round(wall, 1),
        "pytest": pytest_summary(out),
        "xla_flags": env.get("XLA_FLAGS", ""),
        "commit": head.stdout.strip(),
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        **machine(),
    }


def _minutes(s: float) -> str:
    return f"{int(s // 60)} min {int(round(s % 60)):02d} s"


def table(records: list[dict]) -> str:
    """The docs table: the latest record per (command, XLA flags, CPU), oldest first."""
    latest = {}
    for r in records:
        latest[(r["name"], r["xla_flags"], r["cpu"], r["isa"])] = r
    lines = [
        "| command (fresh clone, `CI=true`, empty caches) | wall time | goal | rc | pytest | machine | XLA_FLAGS | commit, date |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in sorted(latest.values(), key=lambda r: r["date"]):
        goal = GOALS_S.get(r["name"])
        met = (
            ""
            if goal is None
            else f"<= {goal // 60} min: {'met' if r['wall_s'] <= goal and not r['rc'] else 'not met'}"
        )
        lines.append(
            f"| `{r['command']}` | {_minutes(r['wall_s'])} | {met} | {r['rc']} | {r['pytest'] or '–'} | "
            f"{r['cores']}-core {r['cpu']} ({r['isa']}) | {r['xla_flags'] or '(none)'} | {r['commit']}, {r['date'][:10]} |"
        )
    return "\n".join(lines)


def update_doc(records: list[dict], doc: Path = DOC) -> None:
    """Regenerate the block between the markers of ``doc`` from ``records``."""
    text = doc.read_text()
    if START not in text or END not in text:
        raise ValueError(f"{doc} has no {START} ... {END} block to regenerate")
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    write_atomic(doc, f"{head}{START}\n{table(records)}\n{END}{tail}")


def load_records(path: Path = RECORDS) -> list[dict]:
    return json.loads(path.read_text()) if path.exists() else []


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("commands", nargs="*", help=f"what to time: {', '.join(COMMANDS)} (none: only regenerate the doc)")
    p.add_argument("--avx2", action="store_true", help=f"XLA_FLAGS={AVX2} (no AVX-512 code, as on an AVX2 machine)")
    p.add_argument(
        "--keep-results",
        action="store_true",
        help="copy what each command wrote under the clone's results/ back here (the timed run's own results)",
    )
    args = p.parse_args(argv)
    unknown = [c for c in args.commands if c not in COMMANDS]
    if unknown:
        p.error(f"unknown command(s) {', '.join(unknown)}; valid: {', '.join(COMMANDS)}")
    records = load_records()
    m = machine()
    print(f"machine: {m['cores']}-core {m['cpu']} ({m['isa']}); XLA_FLAGS {AVX2 if args.avx2 else '(none)'}")
    rc = 0
    for command in args.commands:
        rec = run(command, args.avx2, keep_results=args.keep_results)
        print(f"{rec['command']}: {_minutes(rec['wall_s'])}, rc {rec['rc']}, {rec['pytest'] or 'no pytest summary'}")
        records.append(rec)
        write_atomic(RECORDS, json.dumps(records, indent=1) + "\n")
        rc = rc or rec["rc"]
    update_doc(records)
    print(f"updated {DOC.relative_to(ROOT)} from {RECORDS.relative_to(ROOT)}")
    return rc


if __name__ == "__main__":
    raise SystemExit(main())
