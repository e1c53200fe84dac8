"""Bring your own demonstrations: a folder of recorded trunk motions -> a library npz (issue #18).

``python -m jgrounding.library import DIR --out my_library.npz [--controls P] [--simulate]``

Input: one file per demonstration in ``DIR`` and a manifest (``manifest.csv`` or ``manifest.json``).

- A demonstration is a CSV with a header row: a time column (``time``, ``time_s``, ``t`` or
  ``timestamp``; or ``--time-column``) and one column per tendon in the lab's own units; a ``step`` or
  ``frame`` column is ignored, and ``#`` lines are comments. The command streams that
  :mod:`jgrounding.export` writes (``commands.csv`` / ``commands.json``) are demonstrations too.
- The manifest names, per file, its ``intent`` and ``intensity`` (names of :mod:`jgrounding.vocabulary`),
  optionally its response ``texts`` (a JSON list, or ``|``-separated in a CSV) and a ``realization`` id.
  A JSON manifest may also declare the tendons' ``limits``: one ``[slack, full_pull]`` pair per tendon in
  the lab's units (else ``--limits``); their number is the number of tendons N_u.

What it does, in order: reads and validates every file (:class:`DemonstrationError` names the file,
the line and the column of the first problem; nothing is repaired), maps each tendon from its declared
limits to [0, 1] (slack -> 0, full pull -> 1), resamples linearly to T = 150 steps over the motion's own
duration, optionally reduces by Eq. (ci) (``--controls P``: ``u = make_safe(R(fit(u)))``, exactly like
the built-in library), screens with :func:`jgrounding.library.screening.screen` (bounds, slew, smoothness; and
simulation on the 4-tendon trunk with ``--simulate`` when the data are for our trunk model), splits
every (intent, intensity) tuple into train / held-out realizations, and writes the npz and its card
(:func:`jgrounding.library.save`, atomically). ``--drop-invalid`` drops bad files instead of stopping,
and lists every one in the card and on the terminal.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from jgrounding.vocabulary import INTENSITIES, INTENTS, describe, intensity_index, intent_index

NUM_STEPS = 150  # T of Table I
MIN_ROWS = 10  # fewer recorded samples than this cannot be resampled to T = 150 meaningfully
TIME_COLUMNS = ("time", "time_s", "t", "timestamp")
IGNORED_COLUMNS = ("step", "frame")
MANIFEST_NAMES = ("manifest.json", "manifest.csv")
TRUNK_TENDONS = 4  # the built-in simulator's trunk
LIBRARY_VERSION = "imported-1"  # an imported library's content version (the built-in one has its own)


class DemonstrationError(ValueError):
    """Bad input data; the message names the file, the line (1-based, as an editor shows it) and the column."""

    def __init__(self, file, reason: str, line: int | None = None, column: str | None = None, unit: str = "line"):
        self.file, self.line, self.column, self.reason, self.unit = str(file), line, column, reason, unit
        super().__init__(f"{self.where}: {reason}")

    @property
    def where(self) -> str:
        """``file line N, column 'c'`` (``entry N`` in a JSON manifest, ``command N`` in a command stream)."""
        return (
            self.file
            + (f" {self.unit} {self.line}" if self.line is not None else "")
            + (f", column {self.column!r}" if self.column else "")
        )

    def as_dict(self) -> dict:
        return {
            "file": self.file,
            self.unit: self.line,
            "column": self.column,
            "reason": self.reason,
            "where": self.where,
        }


@dataclasses.dataclass(frozen=True)
class ImportConfig:
    limits: tuple[tuple[float, float], ...]  # per tendon (slack, full pull) in the lab's units; len = N_u
    num_controls: int | None = None  # --controls P: reduce by Eq. (ci); None keeps the resampled recording
    simulate: bool = False  # screen on the built-in 4-tendon trunk too (data recorded for our trunk model)
    heldout_per_tuple: int = 1  # held-out realizations per tuple (the rest train)
    seed: int = 0  # which realizations are held out
    time_column: str | None = None  # None: the first of TIME_COLUMNS in the header
    drop_invalid: bool = False  # drop bad files (listed) instead of stopping at the first

    @property
    def num_tendons(self) -> int:
        return len(self.limits)


@dataclasses.dataclass(frozen=True)
class Entry:
    """One manifest row."""

    file: str
    intent: int
    intensity: int
    texts: tuple[str, ...]
    realization: int | None
    line: int


@dataclasses.dataclass(frozen=True)
class Recording:
    time: np.ndarray  # (n,) float64, strictly increasing
    values: np.ndarray  # (n, N_u) float64 in the lab's units
    columns: tuple[str, ...]  # tendon column names


# ---------------------------------------------------------------- reading and validating


def _number(text: str, path, line: int, column: str, unit: str = "line") -> float:
    cell = text.strip()
    if not cell:
        raise DemonstrationError(
            path, "empty value (a dropped sensor frame?); fill or remove the row", line, column, unit
        )
    try:
        x = float(cell)
    except ValueError:
        raise DemonstrationError(path, f"not a number: {cell!r}", line, column, unit) from None
    if not np.isfinite(x):
        raise DemonstrationError(
            path, f"{'NaN' if np.isnan(x) else 'Inf'} value (a dropped sensor frame?)", line, column, unit
        )
    return x


def _read_csv(path: Path, time_column: str | None, num_tendons: int) -> tuple[np.ndarray, list[int], tuple[str, ...]]:
    """(time + tendon values ``(n, 1 + N_u)``, file line of each row, tendon column names)."""
    with open(path, newline="") as f:
        lines = [
            (i + 1, ln) for i, ln in enumerate(f.read().splitlines()) if ln.strip() and not ln.lstrip().startswith("#")
        ]
    if not lines:
        raise DemonstrationError(path, "no header row and no data")
    header_line, header = lines[0][0], [h.strip() for h in next(csv.reader([lines[0][1]]))]
    names = (time_column,) if time_column else TIME_COLUMNS
    tcol = next((h for h in header if h in names), None)
    if tcol is None:
        raise DemonstrationError(
            path,
            f"no time column: the header is {header}; name it one of {', '.join(names)} (or pass --time-column)",
            header_line,
        )
    tendons = tuple(h for h in header if h != tcol and h not in IGNORED_COLUMNS)
    if len(tendons) != num_tendons:
        raise DemonstrationError(
            path,
            f"{len(tendons)} tendon column(s) {list(tendons)}, but {num_tendons} "
            f"tendon limits are declared (one column per tendon besides "
            f"{tcol!r}{' and ' + '/'.join(IGNORED_COLUMNS) if IGNORED_COLUMNS else ''})",
            header_line,
        )
    order = [header.index(tcol)] + [header.index(c) for c in tendons]
    rows, row_lines = [], []
    for number, text in lines[1:]:
        cells = next(csv.reader([text]))
        if len(cells) != len(header):
            raise DemonstrationError(path, f"{len(cells)} cells, but the header has {len(header)}", number)
        rows.append([_number(cells[i], path, number, header[i]) for i in order])
        row_lines.append(number)
    return np.asarray(rows, np.float64).reshape(-1, 1 + num_tendons), row_lines, tendons


def _read_command_json(path: Path, num_tendons: int) -> tuple[np.ndarray, list[int], tuple[str, ...]]:
    """A ``commands.json`` of :func:`jgrounding.export.command_stream_json`; 'line' = 1 + command index."""
    try:
        doc = json.loads(path.read_text())
        header, commands = doc["header"], doc["commands"]
        dt = float(header["control_dt_s"])
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise DemonstrationError(
            path, f"not a command stream JSON ({{'header': {{'control_dt_s': ...}}, 'commands': [[...], ...]}}): {e}"
        ) from None
    names = tuple(header.get("channels") or [f"tendon_{j}" for j in range(num_tendons)])
    rows = []
    for i, cmd in enumerate(commands):
        if not isinstance(cmd, list) or len(cmd) != num_tendons:
            got = len(cmd) if isinstance(cmd, list) else type(cmd).__name__
            raise DemonstrationError(
                path,
                f"command has {got} tendon values, but {num_tendons} tendon limits are declared",
                i + 1,
                unit="command",
            )
        rows.append(
            [i * dt]
            + [
                _number(str(x), path, i + 1, names[j] if j < len(names) else str(j), "command")
                for j, x in enumerate(cmd)
            ]
        )
    return np.asarray(rows, np.float64).reshape(-1, 1 + num_tendons), list(range(1, len(rows) + 1)), names


def read_recording(path, limits, time_column: str | None = None) -> Recording:
    """Read and validate one demonstration file against per-tendon ``limits`` ``[(slack, full), ...]``.

    Raises :class:`DemonstrationError` (file, line, column) for: a wrong number of tendon columns,
    empty / non-numeric / NaN / Inf values, time that does not strictly increase (duplicates
    included), fewer than :data:`MIN_ROWS` rows, and a value outside its tendon's declared limits.
    """
    path = Path(path)
    if not path.is_file():
        raise DemonstrationError(path, "file not found")
    reader = _read_command_json if path.suffix.lower() == ".json" else None
    unit = "command" if reader else "line"
    data, line_of, columns = reader(path, len(limits)) if reader else _read_csv(path, time_column, len(limits))
    if len(data) < MIN_ROWS:
        raise DemonstrationError(
            path, f"only {len(data)} data row(s); at least {MIN_ROWS} are needed to resample to T = {NUM_STEPS} steps"
        )
    time = data[:, 0]
    step = np.diff(time)
    if np.any(step <= 0):
        i = int(np.argmax(step <= 0))
        what = "duplicate time stamp" if step[i] == 0 else "time goes backwards"
        raise DemonstrationError(
            path,
            f"{what}: {time[i]:g} at {unit} {line_of[i]}, then {time[i + 1]:g}; time must strictly increase",
            line_of[i + 1],
            "time",
            unit,
        )
    values = data[:, 1:]
    for j, (slack, full) in enumerate(limits):
        lo, hi = min(slack, full), max(slack, full)
        bad = np.flatnonzero((values[:, j] < lo) | (values[:, j] > hi))
        if bad.size:
            i = int(bad[0])
            raise DemonstrationError(
                path,
                f"value {values[i, j]:g} is outside the declared limits "
                f"[{lo:g}, {hi:g}] of tendon {j} ({bad.size} row(s) in all)",
                line_of[i],
                columns[j],
                unit,
            )
    return Recording(time=time, values=values, columns=columns)


def normalize(values: np.ndarray, limits) -> np.ndarray:
    """Lab units ``(..., N_u)`` -> [0, 1] per tendon: slack -> 0, full pull -> 1 (either order)."""
    lim = np.asarray(limits, np.float64)
    return (values - lim[:, 0]) / (lim[:, 1] - lim[:, 0])


def resample(time: np.ndarray, values: np.ndarray, num_steps: int = NUM_STEPS) -> np.ndarray:
    """Linear interpolation of ``(n, N_u)`` onto ``num_steps`` uniform times over [time[0], time[-1]]."""
    grid = np.linspace(time[0], time[-1], num_steps)
    return np.stack([np.interp(grid, time, values[:, j]) for j in range(values.shape[1])], axis=-1)


# ---------------------------------------------------------------- manifest


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


def _check_limits(limits, where) -> tuple[tuple[float, float], ...]:
    try:
        limits = tuple((float(a), float(b)) for a, b in limits)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: limits must be a list of [slack, full_pull] pairs, one per tendon") from None
    if not limits:
        raise ValueError(f"{where}: no tendon limits declared")
    for j, (a, b) in enumerate(limits):
        if not (np.isfinite(a) and np.isfinite(b)) or a == b:
            raise ValueError(f"{where}: tendon {j} limits [{a}, {b}] must be two different finite numbers")
    return limits


def _entry(row: dict, where: Path, line: int, unit: str) -> Entry:
    file = str(row.get("file") or "").strip()
    if not file:
        raise DemonstrationError(where, "no 'file' given", line, "file", unit)
    try:
        m = intent_index(str(row.get("intent", "")).strip())
    except ValueError as e:
        raise DemonstrationError(where, f"{file}: {e}", line, "intent", unit) from None
    try:
        z = intensity_index(str(row.get("intensity", "")).strip())
    except ValueError as e:
        raise DemonstrationError(where, f"{file}: {e}", line, "intensity", unit) from None
    texts = row.get("texts", row.get("text", ())) or ()
    if isinstance(texts, str):
        texts = texts.split("|")
    texts = tuple(str(t).strip() for t in texts if str(t).strip())
    real = row.get("realization")
    if real in (None, ""):
        real = None
    else:
        try:
            real = int(str(real).strip())
        except ValueError:
            raise DemonstrationError(
                where, f"{file}: realization must be an integer, got {real!r}", line, "realization", unit
            ) from None
    return Entry(file, m, z, texts, real, line)


def read_manifest(path) -> tuple[list, dict]:
    """Manifest rows (each an :class:`Entry` or, for a bad row, its :class:`DemonstrationError`) and the
    JSON manifest's global fields (``limits``, ``time_column``, ``simulate``)."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        try:
            doc = json.loads(path.read_text())
        except ValueError as e:
            raise DemonstrationError(path, f"not valid JSON: {e}") from None
        rows = doc.get("demonstrations") if isinstance(doc, dict) else doc
        if not isinstance(rows, list):
            raise DemonstrationError(path, "expected {'demonstrations': [{'file', 'intent', 'intensity', ...}]}")
        fields = {k: doc[k] for k in ("limits", "time_column", "simulate") if isinstance(doc, dict) and k in doc}
        numbered = [(i + 1, r) for i, r in enumerate(rows)]  # 'line' = 1-based entry number
    else:
        with open(path, newline="") as f:
            lines = [(i + 1, ln) for i, ln in enumerate(f.read().splitlines()) if ln.strip() and not ln.startswith("#")]
        if not lines:
            raise DemonstrationError(path, "empty manifest")
        header = [h.strip() for h in next(csv.reader([lines[0][1]]))]
        missing = {"file", "intent", "intensity"} - set(header)
        if missing:
            raise DemonstrationError(
                path,
                f"manifest header {header} lacks {sorted(missing)}; columns: file, "
                "intent, intensity[, texts][, realization]",
                lines[0][0],
            )
        numbered = [(n, dict(zip(header, next(csv.reader([ln]))))) for n, ln in lines[1:]]
        fields = {}
    out, unit = [], manifest_unit(path)
    for line, row in numbered:
        try:
            if not isinstance(row, dict):
                raise DemonstrationError(path, f"entry is {type(row).__name__}, expected an object", line, unit=unit)
            out.append(_entry(row, path, line, unit))
        except DemonstrationError as e:
            out.append(e)
    return out, fields


def manifest_unit(path: Path) -> str:
    """How a manifest's rows are counted in messages: ``line`` of a CSV, ``entry`` of a JSON list."""
    return "entry" if Path(path).suffix.lower() == ".json" else "line"


def find_manifest(folder: Path) -> Path:
    found = [folder / n for n in MANIFEST_NAMES if (folder / n).is_file()]
    if len(found) != 1:
        what = "no manifest" if not found else "two manifests"
        raise DemonstrationError(
            folder, f"{what}: put exactly one of {' or '.join(MANIFEST_NAMES)} in the folder (or pass --manifest)"
        )
    return found[0]


# ---------------------------------------------------------------- the import


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _tuple_name(m: int, z: int) -> str:
    return f"{INTENTS[m]}/{INTENSITIES[z]}"


def _reduce(x: np.ndarray, num_controls: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(controls ``(B, N_u, P)``, raw ``(B, T, N_u)``, u ``(B, T, N_u)``) of resampled recordings ``x``.

    With ``num_controls`` the expert trajectory is ``u = make_safe(R(c))``, ``c`` by Eq. (ci), as in the
    built-in library; without it ``u`` is the recording itself (screened, never clamped) and ``c`` its
    Eq. (ci) controls at P = 4 for the spline methods.
    """
    from jgrounding import safety
    from jgrounding.actuation import splines

    c = np.asarray(splines.fit(x.astype(np.float32), num_controls=num_controls or splines.NUM_CONTROLS))
    if num_controls is None:
        u = x.astype(np.float32)
        return c, u, u
    raw = np.asarray(splines.reconstruct(c, num_steps=x.shape[1]))
    return c, raw, np.asarray(safety.make_safe(raw), np.float32)


def _fail(error: DemonstrationError, config: ImportConfig, dropped: list) -> None:
    if not config.drop_invalid:
        raise error
    dropped.append(error.as_dict())


def import_folder(folder, config: ImportConfig, manifest=None) -> tuple[dict, dict]:
    """Read, validate, normalize, resample, (reduce,) screen and split a folder of demonstrations.

    Returns ``(arrays, card)`` for :func:`jgrounding.library.save`: arrays ``u (N, 150, N_u)``,
    ``controls (N, N_u, P)``, ``intent``, ``intensity``, ``realization``, ``heldout``, ``texts``, ``source``.
    Raises :class:`DemonstrationError` on the first bad file (or, with ``config.drop_invalid``, lists it in
    ``card["dropped"]`` and goes on) and ``ValueError`` for an impossible configuration.
    """
    from jgrounding.library import screening

    folder = Path(folder)
    if not folder.is_dir():
        raise DemonstrationError(folder, "not a folder")
    manifest = Path(manifest) if manifest else find_manifest(folder)
    if config.simulate and config.num_tendons != TRUNK_TENDONS:
        raise ValueError(
            f"--simulate screens on the built-in {TRUNK_TENDONS}-tendon trunk; these data declare "
            f"{config.num_tendons} tendons (physics screening is only for data recorded on our trunk model)"
        )
    entries, _ = read_manifest(manifest)
    unit = manifest_unit(manifest)
    dropped: list[dict] = []
    kept, recs = [], []
    seen: dict[str, int] = {}
    for e in entries:
        if isinstance(e, DemonstrationError):
            _fail(e, config, dropped)
            continue
        if e.file in seen:
            _fail(
                DemonstrationError(
                    manifest, f"{e.file} is listed twice (also {unit} {seen[e.file]})", e.line, "file", unit
                ),
                config,
                dropped,
            )
            continue
        seen[e.file] = e.line
        try:
            rec = read_recording(folder / e.file, config.limits, config.time_column)
        except DemonstrationError as err:
            _fail(err, config, dropped)
            continue
        kept.append(e)
        recs.append(rec)
    if not kept:
        raise DemonstrationError(
            manifest, "no valid demonstration to import" + (f" ({len(dropped)} dropped)" if dropped else "")
        )
    x = np.stack([resample(r.time, normalize(r.values, config.limits)) for r in recs])  # (B, T, N_u)
    controls, raw, u = _reduce(x, config.num_controls)
    intent = np.array([e.intent for e in kept], np.int32)
    checks = screening.screen(
        raw, u, intent, simulate=config.simulate, intensity=np.array([e.intensity for e in kept], np.int32)
    )
    names = [c for c in screening.CHECKS if c in checks]
    rejected = [
        {"file": e.file, "failed": [c for c in names if not checks[c][i]]}
        for i, e in enumerate(kept)
        if not checks["accepted"][i]
    ]
    ok = [i for i in range(len(kept)) if checks["accepted"][i]]

    by_tuple: dict[tuple[int, int], list[int]] = {}
    for i in ok:
        by_tuple.setdefault((kept[i].intent, kept[i].intensity), []).append(i)
    realization = {}
    for key, idx in by_tuple.items():
        given = [kept[i].realization for i in idx if kept[i].realization is not None]
        dup = sorted({r for r in given if given.count(r) > 1})
        if dup:
            lines = [kept[i].line for i in idx if kept[i].realization in dup]
            raise DemonstrationError(
                manifest,
                f"tuple {_tuple_name(*key)}: realization id(s) {dup} used more "
                f"than once ({unit}s {', '.join(map(str, lines))})",
                lines[-1],
                "realization",
                unit,
            )
        free = (r for r in range(len(idx) + len(given) + 1) if r not in given)
        for i in idx:
            realization[i] = kept[i].realization if kept[i].realization is not None else next(free)
    need = config.heldout_per_tuple + 1
    tuple_of = {e.file: (e.intent, e.intensity) for e in kept}
    short_tuples = []
    for key in sorted(by_tuple):
        idx = by_tuple[key]
        if len(idx) < need:
            rej = [f"{r['file']} ({', '.join(r['failed'])})" for r in rejected if tuple_of[r["file"]] == key]
            err = DemonstrationError(
                manifest,
                f"tuple {_tuple_name(*key)} has {len(idx)} valid realization(s) "
                f"({', '.join(kept[i].file for i in idx)}{'; rejected by screening: ' + ', '.join(rej) if rej else ''}); "
                f"the train/held-out split needs at least {need} ({config.heldout_per_tuple} held out + 1 to train)",
                kept[idx[0]].line,
                unit=unit,
            )
            _fail(err, config, dropped)
            short_tuples.append(key)
    for key in short_tuples:
        del by_tuple[key]
    if not by_tuple:
        raise DemonstrationError(manifest, "no tuple has enough valid realizations for the split")

    order, heldout = [], []
    for key in sorted(by_tuple):
        idx = sorted(by_tuple[key], key=lambda i: realization[i])
        held = np.random.default_rng([config.seed, *key]).choice(len(idx), config.heldout_per_tuple, replace=False)
        order += idx
        heldout += [k in set(held.tolist()) for k in range(len(idx))]
    n_texts = max([len(kept[i].texts) for i in order] + [1])
    texts, described = [], []
    for i in order:
        t = kept[i].texts or (describe(kept[i].intent, kept[i].intensity),)
        if not kept[i].texts:
            described.append(kept[i].file)
        texts.append([t[k % len(t)] for k in range(n_texts)])
    arrays = {
        "u": u[order].astype(np.float32),
        "controls": controls[order].astype(np.float32),
        "intent": intent[order],
        "intensity": np.array([kept[i].intensity for i in order], np.int32),
        "realization": np.array([realization[i] for i in order], np.int32),
        "heldout": np.array(heldout, bool),
        "texts": np.asarray(texts, dtype=np.str_),
        "source": np.asarray([kept[i].file for i in order], dtype=np.str_),
    }
    counts = {}
    for k, i in enumerate(order):
        c = counts.setdefault(_tuple_name(kept[i].intent, kept[i].intensity), {"train": 0, "heldout": 0})
        c["heldout" if heldout[k] else "train"] += 1
    from jgrounding import library

    arrays["library_version"] = np.asarray(LIBRARY_VERSION)
    arrays["content_sha256"] = np.asarray(library.content_hash(arrays))
    card = {
        "format_version": library.FORMAT_VERSION,
        "library_version": LIBRARY_VERSION,
        "content_sha256": str(arrays["content_sha256"]),
        "source": "import",
        "config": {**dataclasses.asdict(config), "limits": [list(p) for p in config.limits]},
        "num_tendons": config.num_tendons,
        "channels": list(recs[0].columns),  # the tendon columns' names, in the order of the limits
        "num_steps": NUM_STEPS,
        "num_controls": int(controls.shape[-1]),
        "reduced": config.num_controls is not None,
        "screening": names
        + (
            []
            if config.simulate
            else [
                f"physics skipped: {'pass --simulate if these are recordings of the built-in trunk model' if config.num_tendons == TRUNK_TENDONS else f'the built-in simulator is the {TRUNK_TENDONS}-tendon trunk, these data have N_u = {config.num_tendons}'}"
            ]
        ),
        "num_records": len(order),
        "num_train": int((~arrays["heldout"]).sum()),
        "num_heldout": int(arrays["heldout"].sum()),
        "counts_per_tuple": counts,
        "rejected": rejected,
        "dropped": dropped,
        "texts_default_description": described,
        "durations_s": {kept[i].file: round(float(recs[i].time[-1] - recs[i].time[0]), 6) for i in range(len(kept))},
        "manifest": {"file": manifest.name, "sha256": _sha256(manifest)},
        "sources_sha256": {e.file: _sha256(folder / e.file) for e in kept},
    }
    return arrays, card


# ---------------------------------------------------------------- command line


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m jgrounding.library", description="Demonstration libraries: import a folder of recorded motions."
    )
    sub = p.add_subparsers(dest="command", required=True)
    q = sub.add_parser(
        "import",
        help="import a folder of recorded demonstrations into a library npz",
        description=__doc__.split("\n\n")[0],
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
        "--drop-invalid", action="store_true", help="drop bad files and tuples (all listed) instead of stopping"
    )
    return p


def config_from_args(args, parser) -> tuple[ImportConfig, Path]:
    folder = Path(args.folder)
    try:
        manifest = Path(args.manifest) if args.manifest else find_manifest(folder)
        fields = read_manifest(manifest)[1]
    except DemonstrationError as e:
        parser.error(str(e))
    try:
        flag = parse_limits(args.limits, args.tendons) if args.limits else None
        declared = _check_limits(fields["limits"], manifest) if "limits" in fields else None
    except ValueError as e:
        parser.error(str(e))
    if flag and declared and flag != declared:
        parser.error(f"--limits {flag} disagree with the limits in {manifest} {declared}; give them once")
    limits = flag or declared
    if not limits:
        parser.error(
            f'declare each tendon\'s limits: --limits slack:full,... or "limits" in a JSON manifest ({manifest})'
        )
    limits = _check_limits(limits, "--limits")
    if args.controls is not None and not 2 <= args.controls <= NUM_STEPS:
        parser.error(f"--controls must be in 2..{NUM_STEPS}, got {args.controls}")
    if args.heldout < 1:
        parser.error(f"--heldout must be >= 1, got {args.heldout}")
    simulate = bool(args.simulate or fields.get("simulate", False))
    return ImportConfig(
        limits=limits,
        num_controls=args.controls,
        simulate=simulate,
        heldout_per_tuple=args.heldout,
        seed=args.seed,
        time_column=args.time_column or fields.get("time_column"),
        drop_invalid=args.drop_invalid,
    ), manifest


def main(argv=None) -> int:
    from jgrounding import library

    parser = build_parser()
    args = parser.parse_args(argv)
    config, manifest = config_from_args(args, parser)
    try:
        arrays, card = import_folder(args.folder, config, manifest)
    except ValueError as e:  # DemonstrationError included: file, line and column are in the message
        print(f"error: {e}", file=sys.stderr)
        return 1
    for d in card["dropped"]:
        print(f"dropped: {d['where']}: {d['reason']}")
    for r in card["rejected"]:
        print(f"rejected by screening: {r['file']} (failed: {', '.join(r['failed'])})")
    for note in card["screening"]:
        if note.startswith("physics skipped"):
            print(f"note: {note}")
    card["regenerate"] = "python -m jgrounding.library " + " ".join(argv if argv is not None else sys.argv[1:])
    path = library.save(arrays, card, args.out)
    print(
        f"wrote {path} and {path.with_suffix('.json')}: {card['num_records']} demonstrations "
        f"({card['num_train']} train / {card['num_heldout']} held out) of {len(card['counts_per_tuple'])} tuples, "
        f"N_u = {card['num_tendons']}, {len(card['rejected'])} rejected, {len(card['dropped'])} dropped"
    )
    return 0
