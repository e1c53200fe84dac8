"""``python -m jgrounding.library import DIR --out my_library.npz [--controls P] [--simulate]``: the command
line of the importer (flags -> :class:`ImportConfig`, the run, what it prints)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from jgrounding.config import NUM_STEPS  # T of Table I
from jgrounding.library.importer.checks import TOLERANCE
from jgrounding.library.importer.errors import DemonstrationError
from jgrounding.library.importer.manifest import check_limits, find_manifest, read_manifest
from jgrounding.library.importer.parse import TIME_COLUMNS
from jgrounding.library.importer.pipeline import MAX_DROPPED, ImportConfig, import_folder


def parse_limits(text: str, num_tendons: int | None = None) -> tuple[tuple[float, float], ...]:
    """``"0:12.5,0:12.5,0:12.5"`` -> ((0, 12.5), ...); one pair with ``num_tendons`` applies to all."""
    try:
        pairs = tuple(tuple(float(x) for x in p.split(":")) for p in text.split(","))
    except ValueError:
        pairs = ((),)
    if not pairs or any(len(p) != 2 or not all(np.isfinite(p)) for p in pairs):
        raise ValueError(
            f"limits must be 'slack:full' pairs separated by commas, one per tendon "
            f"(e.g. 0:12.5,0:12.5,0:12.5,0:12.5), got {text!r}"
        )
    if num_tendons is not None:
        if len(pairs) == 1:
            pairs = pairs * num_tendons
        elif len(pairs) != num_tendons:
            raise ValueError(f"{len(pairs)} limit pairs given for {num_tendons} tendons")
    return pairs


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m jgrounding.library", description="Demonstration libraries: import a folder of recorded motions."
    )
    sub = p.add_subparsers(dest="command", required=True)
    q = sub.add_parser(
        "import",
        help="import a folder of recorded demonstrations into a library npz",
        description="Bring your own demonstrations: a folder of recorded trunk motions -> a library npz.",
    )
    q.add_argument("folder", help="folder with one CSV per demonstration and manifest.csv / manifest.json")
    q.add_argument("--out", required=True, help="library file to write (.npz; its card goes beside it as .json)")
    q.add_argument("--manifest", help="manifest path (default: DIR/manifest.json or DIR/manifest.csv)")
    q.add_argument(
        "--limits",
        help="per-tendon 'slack:full' in the lab's units, comma-separated (one per tendon, or "
        "one pair for all with --tendons); overrides none: the manifest's limits must agree",
    )
    q.add_argument("--tendons", type=int, help="number of tendons N_u when --limits gives one pair for all")
    q.add_argument("--controls", type=int, metavar="P", help="reduce by Eq. (ci) to P Catmull-Rom controls per tendon")
    q.add_argument(
        "--simulate",
        action="store_true",
        help="also screen in simulation on the built-in 4-tendon trunk (for recordings of our trunk model)",
    )
    q.add_argument("--heldout", type=int, default=1, help="held-out realizations per tuple (default 1)")
    q.add_argument("--seed", type=int, default=0, help="seed of the train/held-out split (default 0)")
    q.add_argument("--time-column", help=f"name of the time column (default: one of {', '.join(TIME_COLUMNS)})")
    q.add_argument(
        "--drop-invalid",
        action="store_true",
        help="drop bad files and tuples (all listed) and import the rest; fails (exit 1, nothing written) when "
        "more than --max-dropped of the files are left out",
    )
    q.add_argument(
        "--max-dropped",
        type=float,
        default=MAX_DROPPED,
        metavar="F",
        help=f"with --drop-invalid: the largest fraction of the manifest's files that may be left out "
        f"(default {MAX_DROPPED:g})",
    )
    q.add_argument(
        "--tolerance",
        type=float,
        default=TOLERANCE,
        metavar="F",
        help=f"readings up to this fraction of a tendon's travel outside its limits are clipped and counted "
        f"(sensor noise; default {TOLERANCE:g} = {100 * TOLERANCE:g}%%); further out is an error",
    )
    return p


def config_from_args(args, parser) -> tuple[ImportConfig, Path]:
    folder = Path(args.folder)
    try:
        manifest = Path(args.manifest) if args.manifest else find_manifest(folder)
        fields = read_manifest(manifest).fields
    except DemonstrationError as e:
        parser.error(str(e))
    try:
        flag = parse_limits(args.limits, args.tendons) if args.limits else None
        declared = check_limits(fields["limits"], manifest) if "limits" in fields else None
    except ValueError as e:
        parser.error(str(e))
    if flag and declared and flag != declared:
        parser.error(f"--limits {flag} disagree with the limits in {manifest} {declared}; give them once")
    limits = flag or declared
    if not limits:
        parser.error(
            f'declare each tendon\'s limits: --limits slack:full,... or "limits" in a JSON manifest ({manifest})'
        )
    limits = check_limits(limits, "--limits")
    if args.controls is not None and not 2 <= args.controls <= NUM_STEPS:
        parser.error(f"--controls must be in 2..{NUM_STEPS}, got {args.controls}")
    if args.heldout < 1:
        parser.error(f"--heldout must be >= 1, got {args.heldout}")
    if not 0.0 <= args.tolerance <= 0.5:
        parser.error(f"--tolerance is a fraction of each tendon's travel in 0..0.5 (e.g. 0.01), got {args.tolerance:g}")
    if not 0.0 <= args.max_dropped <= 1.0:
        parser.error(f"--max-dropped is a fraction of the files in 0..1 (e.g. 0.2), got {args.max_dropped:g}")
    simulate = bool(args.simulate or fields.get("simulate", False))
    return ImportConfig(
        limits=limits,
        num_controls=args.controls,
        simulate=simulate,
        heldout_per_tuple=args.heldout,
        seed=args.seed,
        time_column=args.time_column or fields.get("time_column"),
        drop_invalid=args.drop_invalid,
        tolerance=args.tolerance,
        max_dropped=args.max_dropped,
    ), manifest


def _report(card: dict) -> None:
    """The notes, the dropped problems, the rejections and the physics note of a finished import."""
    for file, notes in card["notes"].items():
        for note in notes:
            print(f"note: {file}: {note}")
    for d in card["dropped"]:
        print(f"dropped: {d['where']}: {d['reason']}" + (f". Fix: {d['fix']}" if d.get("fix") else ""))
    for r in card["rejected"]:
        print(f"rejected by screening: {r['file']} (failed: {', '.join(r['failed'])})")
    for note in card["screening"]:
        if note.startswith("physics skipped"):
            print(f"note: {note}")


def main(argv=None) -> int:
    from jgrounding import library

    parser = build_parser()
    args = parser.parse_args(argv)
    config, manifest = config_from_args(args, parser)
    try:
        arrays, card = import_folder(args.folder, config, manifest)
    except ValueError as e:  # DemonstrationError included: file, line, column and fix are in the message
        for line in str(e).splitlines():
            print(f"error: {line}", file=sys.stderr)
        return 1
    _report(card)
    card["regenerate"] = "python -m jgrounding.library " + " ".join(argv if argv is not None else sys.argv[1:])
    path = library.save(arrays, card, args.out)
    print(
        f"wrote {path} and {path.with_suffix('.json')}: {card['num_records']} demonstrations "
        f"({card['num_train']} train / {card['num_heldout']} held out) of {len(card['counts_per_tuple'])} tuples, "
        f"N_u = {card['num_tendons']}, {len(card['rejected'])} rejected, {card['num_dropped']} file(s) dropped; "
        f"{sum(sum(c.values()) for c in card['clipped'].values())} reading(s) in {len(card['clipped'])} file(s) "
        f"clipped into the limits (tolerance {100 * card['tolerance']:g}% of the travel)"
    )
    return 0
