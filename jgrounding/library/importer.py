"""Bring your own demonstrations: a folder of recorded trunk motions -> a library npz (issue #18).

``python -m jgrounding.library import DIR --out my_library.npz [--controls P] [--simulate]``

Input: one file per demonstration in ``DIR`` and a manifest (``manifest.csv`` or ``manifest.json``).

- A demonstration is a CSV with a header row: a time column (``time``, ``time_s``, ``t``, ``timestamp``,
  ``elapsed`` or ``elapsed_s`` in seconds, ``time_ms``, ``t_ms``, ``timestamp_ms`` or ``elapsed_ms`` in
  milliseconds, any case; or ``--time-column``) and one column per tendon in the lab's own units; a ``step``
  or ``frame`` column is ignored, and ``#`` lines are comments. ``,``, ``;`` or a tab between cells and a
  UTF-8 byte-order mark are detected; with ``;`` or a tab, a decimal comma is read. Tendon columns are
  matched by name (any case) to the first file's, so another column order is mapped, never swapped. The
  command streams that :mod:`jgrounding.apps.export` writes (``commands.csv`` / ``commands.json``) are
  demonstrations too.
- The manifest names, per file, its ``intent`` and ``intensity`` (names of :mod:`jgrounding.vocabulary`),
  optionally its response ``texts`` (a JSON list, or ``|``-separated in a CSV) and a ``realization`` id.
  A CSV manifest row with more cells than its header (a text with an unquoted comma) is an error that
  shows the row quoted. A JSON manifest may also declare the tendons' ``limits``: one ``[slack, full_pull]``
  pair per tendon in the lab's units (else ``--limits``), in the order of the first file's tendon columns
  (or of its ``columns``); their number is the number of tendons N_u.

What it does, in order: reads and checks every file, and reports every problem of the run together, each
with its file, line, column and a fix (the manifest line to delete included): bad cells, time that does not
increase, gaps in time (over :data:`GAP_FACTOR` x the median step), readings outside the limits by more than
``--tolerance`` (default :data:`TOLERANCE` = 1% of the travel; readings within it are sensor noise, clipped
to the limits, counted in the card and on the terminal), a stuck channel, a flat recording, and a file whose
time is in another unit than the others (milliseconds among seconds). It maps each tendon from its declared
limits to [0, 1] (slack -> 0, full pull -> 1), resamples linearly to T = 150 steps over the motion's own
duration, optionally reduces by Eq. (ci) (``--controls P``: ``u = make_safe(R(fit(u)))``, exactly like
the built-in library), screens with :func:`jgrounding.library.screening.screen` (bounds, slew, smoothness; and
simulation on the 4-tendon trunk with ``--simulate`` when the data are for our trunk model), splits
every (intent, intensity) tuple into train / held-out realizations, and writes the npz and its card
(:func:`jgrounding.library.save`, atomically). ``--drop-invalid`` drops bad files instead of stopping,
lists every one in the card and on the terminal, and fails (exit 1, nothing written) when more than
``--max-dropped`` (default :data:`MAX_DROPPED` = 20%) of the manifest's files are left out.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import io
import json
import sys
from pathlib import Path

import numpy as np

from jgrounding.config import NUM_STEPS  # noqa: E402  (T of Table I)
from jgrounding.vocabulary import INTENSITIES, INTENTS, describe, intensity_index, intent_index

MIN_ROWS = 10  # fewer recorded samples than this cannot be resampled to T = 150 meaningfully
TIME_COLUMNS = ("time", "time_s", "t", "timestamp", "elapsed", "elapsed_s")  # seconds; matched in any case
TIME_COLUMNS_MS = ("time_ms", "t_ms", "timestamp_ms", "elapsed_ms")  # milliseconds, converted
IGNORED_COLUMNS = ("step", "frame")
TOLERANCE = 0.01  # readings up to 1% of a tendon's travel outside its limits are sensor noise: clipped, counted
MAX_DROPPED = 0.2  # --drop-invalid fails (exit 1, nothing written) when more than 20% of the files are dropped
GAP_FACTOR = 5.0  # a time step over 5 x the recording's median step is a gap (lost frames): an error
STUCK_SECONDS = 1.0  # one exact reading held this long, away from the limits, while another tendon moves: stuck
STUCK_MOVING = 0.05  # "moves": a range over 5% of that tendon's travel during the run
FLAT_FRACTION = 0.02  # every tendon within 2% of its travel: a flat recording (the robot was off)
UNITS_RATIO = 100.0  # a median time step 100 x off the folder's median: another time unit (ms vs s)
MANIFEST_NAMES = ("manifest.json", "manifest.csv")
TRUNK_TENDONS = 4  # the built-in simulator's trunk
LIBRARY_VERSION = "imported-1"  # an imported library's content version (the built-in one has its own)


class DemonstrationError(ValueError):
    """Bad input data; the message names the file, the line (1-based, as an editor shows it), the column,
    and how to fix it."""

    def __init__(
        self,
        file,
        reason: str,
        line: int | None = None,
        column: str | None = None,
        unit: str = "line",
        fix: str | None = None,
    ):
        self.file, self.line, self.column, self.reason, self.unit, self.fix = str(file), line, column, reason, unit, fix
        super().__init__(f"{self.where}: {reason}" + (f". Fix: {fix}" if fix else ""))

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
            "fix": self.fix,
            "where": self.where,
        }


class ImportProblems(DemonstrationError):
    """Every problem of one import run (strict mode): ``problems`` is the list, the message has one per line."""

    def __init__(self, problems: list[DemonstrationError], files: int | None = None):
        self.problems = list(problems)
        first = self.problems[0]
        super().__init__(first.file, first.reason, first.line, first.column, first.unit, first.fix)
        bad = len({p.file for p in self.problems})
        self.args = (
            "\n".join(str(p) for p in self.problems)
            + (
                f"\n{len(self.problems)} problem(s) in {bad} file(s) ({files} listed in the manifest); nothing was "
                "written (fix them, or pass --drop-invalid to import the rest)"
                if files is not None
                else ""
            ),
        )

    def __str__(self) -> str:
        return self.args[0]


class TooManyDropped(DemonstrationError):
    """``--drop-invalid`` past ``--max-dropped``: the problems and rejections are listed, nothing is written."""

    def __init__(self, problems: list, rejected: list, summary: str, manifest: Path):
        self.problems, self.rejected = list(problems), list(rejected)
        super().__init__(
            manifest,
            summary,
            fix="fix the files listed above, or pass a larger --max-dropped to accept the rest anyway",
        )
        self.args = (
            "\n".join(
                [str(p) for p in self.problems]
                + [f"rejected by screening: {r['file']} (failed: {', '.join(r['failed'])})" for r in self.rejected]
                + [f"{self.where}: {summary}. Fix: {self.fix}"]
            ),
        )

    def __str__(self) -> str:
        return self.args[0]


@dataclasses.dataclass(frozen=True)
class ImportConfig:
    limits: tuple[tuple[float, float], ...]  # per tendon (slack, full pull) in the lab's units; len = N_u
    num_controls: int | None = None  # --controls P: reduce by Eq. (ci); None keeps the resampled recording
    simulate: bool = False  # screen on the built-in 4-tendon trunk too (data recorded for our trunk model)
    heldout_per_tuple: int = 1  # held-out realizations per tuple (the rest train)
    seed: int = 0  # which realizations are held out
    time_column: str | None = None  # None: the first of TIME_COLUMNS in the header
    drop_invalid: bool = False  # drop bad files (listed) instead of stopping
    tolerance: float = TOLERANCE  # readings this fraction of the travel outside the limits are clipped (counted)
    max_dropped: float = MAX_DROPPED  # --drop-invalid fails when more than this fraction of files is dropped
    columns: tuple[str, ...] | None = None  # tendon column names in the order of the limits (None: the first file's)

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
    time: np.ndarray  # (n,) float64 in seconds, strictly increasing
    values: np.ndarray  # (n, N_u) float64 in the lab's units, clipped to the limits within the tolerance
    columns: tuple[str, ...]  # tendon column names, in the order of the limits
    notes: tuple[str, ...] = ()  # what was accepted but worth knowing (clipping, mapping by name, ms, ...)
    clipped: dict = dataclasses.field(default_factory=dict)  # column -> readings clipped into the limits
    median_dt: float = float("nan")  # the recording's median time step (s), for the mixed-units check
    lines: tuple[int, ...] = ()  # the file line (command) of each row
    time_column: str = "time"


# ---------------------------------------------------------------- reading and validating


def _number(text: str, path, line: int, column: str, unit: str = "line", decimal_comma: bool = False) -> float:
    cell = text.strip()
    if not cell:
        raise DemonstrationError(
            path,
            "empty value (a dropped sensor frame?)",
            line,
            column,
            unit,
            fix="fill the value or delete the row (time must still increase)",
        )
    try:
        x = float(cell.replace(",", ".") if decimal_comma else cell)
    except ValueError:
        comma = "," in cell and not decimal_comma
        raise DemonstrationError(
            path,
            f"not a number: {cell!r}" + (" (a decimal comma?)" if comma else ""),
            line,
            column,
            unit,
            fix="export with '.' as the decimal mark, or with ';' between cells (then a decimal comma is read)"
            if comma
            else "write a plain number such as 12.5",
        ) from None
    if not np.isfinite(x):
        raise DemonstrationError(
            path,
            f"{'NaN' if np.isnan(x) else 'Inf'} value (a dropped sensor frame?)",
            line,
            column,
            unit,
            fix="fill the value or delete the row",
        )
    return x


def _sniff(header: str) -> str:
    """The delimiter of a header line: ``;`` or a tab when it splits the header, else ``,``."""
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=counts.get)
    return best if counts[best] else ","


def _time_column(header: list[str], time_column: str | None) -> str | None:
    names = (time_column.lower(),) if time_column else TIME_COLUMNS + TIME_COLUMNS_MS
    return next((h for h in header if h.lower() in names), None)


def _read_csv(
    path: Path, time_column: str | None, limits, columns, notes: list
) -> tuple[np.ndarray, list[int], tuple[str, ...], str]:
    """(time + tendon values ``(n, 1 + N_u)`` in the limits' order, file line of each row, tendon column
    names, time column name); every cell problem of the file raised together as :class:`ImportProblems`."""
    num_tendons = len(limits)
    raw = path.read_bytes()
    if raw.startswith(b"\xef\xbb\xbf"):
        notes.append("UTF-8 byte-order mark skipped")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise DemonstrationError(path, f"not UTF-8 text ({e})", fix="save the file as UTF-8 (CSV UTF-8)") from None
    lines = [(i + 1, ln) for i, ln in enumerate(text.splitlines()) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise DemonstrationError(path, "no header row and no data", fix="export the recording with a header row")
    delimiter = _sniff(lines[0][1])
    decimal_comma = delimiter != "," and any("," in ln for _, ln in lines[1:6])
    if delimiter != ",":
        notes.append(f"cells separated by {delimiter!r}" + (", decimal comma read" if decimal_comma else ""))
    header_line, header = lines[0][0], [h.strip() for h in next(csv.reader([lines[0][1]], delimiter=delimiter))]
    tcol = _time_column(header, time_column)
    if tcol is None:
        names = (time_column,) if time_column else TIME_COLUMNS + TIME_COLUMNS_MS
        raise DemonstrationError(
            path,
            f"no time column: the header is {header} (read with {delimiter!r} between cells)",
            header_line,
            fix=f"name the time column one of {', '.join(names)} (any case; *_ms for milliseconds), "
            "or pass --time-column NAME",
        )
    tendons = tuple(h for h in header if h != tcol and h.lower() not in IGNORED_COLUMNS)
    if len(tendons) != num_tendons:
        raise DemonstrationError(
            path,
            f"{len(tendons)} tendon column(s) {list(tendons)}, but {num_tendons} "
            f"tendon limits are declared (one column per tendon besides "
            f"{tcol!r}{' and ' + '/'.join(IGNORED_COLUMNS) if IGNORED_COLUMNS else ''})",
            header_line,
            fix=f"declare one 'slack:full' pair per tendon column ({len(tendons)}) in the file's units"
            + (f", or one pair for all with --tendons {len(tendons)}" if num_tendons == 1 and tendons else ""),
        )
    if columns is not None:  # match the first file's (or the manifest's) columns by name, any case
        lower = {c.lower(): c for c in tendons}
        missing = [c for c in columns if c.lower() not in lower]
        if missing:
            raise DemonstrationError(
                path,
                f"tendon columns {list(tendons)} do not match {list(columns)} (the first file's, in the order of "
                f"the limits): {missing} missing",
                header_line,
                fix="rename this file's columns to the same names (case does not matter), or import it separately",
            )
        if [lower[c.lower()] for c in columns] != list(tendons):
            notes.append(f"columns in another order {list(tendons)}: mapped by name to {list(columns)}")
        tendons = tuple(lower[c.lower()] for c in columns)
    order = [header.index(tcol)] + [header.index(c) for c in tendons]
    rows, row_lines, problems, seen = [], [], [], {}
    for number, text_line in lines[1:]:
        cells = next(csv.reader([text_line], delimiter=delimiter))
        try:
            if len(cells) != len(header):
                raise DemonstrationError(
                    path,
                    f"{len(cells)} cells, but the header has {len(header)}"
                    + (" (decimal commas with ',' between cells?)" if len(cells) > len(header) else ""),
                    number,
                    fix="export with '.' as the decimal mark or ';' between cells"
                    if len(cells) > len(header)
                    else "complete or delete the row",
                )
            rows.append([_number(cells[i], path, number, header[i], decimal_comma=decimal_comma) for i in order])
            row_lines.append(number)
        except DemonstrationError as e:  # the first of each kind and column, with a count
            key = (e.reason.split(":")[0].split(" (")[0], e.column)
            if key in seen:
                seen[key][1] += 1
            else:
                seen[key] = [e, 1]
                problems.append(key)
    if problems:
        errs = []
        for key in problems:
            e, n = seen[key]
            errs.append(
                DemonstrationError(
                    e.file, e.reason + (f" ({n} rows in all)" if n > 1 else ""), e.line, e.column, fix=e.fix
                )
            )
        raise ImportProblems(errs)
    data = np.asarray(rows, np.float64).reshape(-1, 1 + num_tendons)
    if tcol.lower() in TIME_COLUMNS_MS:
        data[:, 0] /= 1000.0
        notes.append(f"time column {tcol!r} read as milliseconds")
    return data, row_lines, tendons, tcol


def _read_command_json(path: Path, num_tendons: int) -> tuple[np.ndarray, list[int], tuple[str, ...]]:
    """A ``commands.json`` of :func:`jgrounding.apps.export.command_stream_json`; 'line' = 1 + command index."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8-sig"))
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


def _runs(x: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of maximal runs of exactly equal consecutive values in ``x``."""
    change = np.flatnonzero(np.diff(x) != 0) + 1
    edges = np.concatenate([[0], change, [len(x)]])
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def inspect_recording(
    path, limits, time_column: str | None = None, *, tolerance: float = TOLERANCE, columns=None
) -> Recording:
    """Read and check one demonstration file against per-tendon ``limits`` ``[(slack, full), ...]``.

    Raises :class:`ImportProblems` (a :class:`DemonstrationError`) listing every problem of the file, each
    with its line, column and fix:
    a wrong number or names of tendon columns; empty / non-numeric / NaN / Inf values; time that does not
    strictly increase (duplicates included); a gap in time over :data:`GAP_FACTOR` x the median step; fewer
    than :data:`MIN_ROWS` rows; a reading more than ``tolerance`` x the travel outside its tendon's limits;
    a stuck channel (the exact same reading for :data:`STUCK_SECONDS` or longer, away from the limits,
    while another tendon moves); a flat recording (every tendon within :data:`FLAT_FRACTION` of its travel).
    Accepted but reported in ``notes``: readings clipped into the limits (counted in ``clipped``), columns
    mapped by name from another order, a BOM, another delimiter, a decimal comma, milliseconds.
    """
    path = Path(path)
    if not path.is_file():
        raise DemonstrationError(path, "file not found", fix="check the file name in the manifest")
    notes: list[str] = []
    if path.suffix.lower() == ".json":
        unit = "command"
        data, line_of, names = _read_command_json(path, len(limits))
        tcol = "time"
    else:
        unit = "line"
        data, line_of, names, tcol = _read_csv(path, time_column, limits, columns, notes)
    if len(data) < MIN_ROWS:
        raise DemonstrationError(
            path,
            f"only {len(data)} data row(s); at least {MIN_ROWS} are needed to resample to T = {NUM_STEPS} steps",
            fix="record a longer motion",
        )
    problems: list[DemonstrationError] = []
    time, values = data[:, 0], data[:, 1:]
    step = np.diff(time)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        i = int(bad[0])
        what = "duplicate time stamp" if step[i] == 0 else "time goes backwards"
        problems.append(
            DemonstrationError(
                path,
                f"{what}: {time[i]:g} at {unit} {line_of[i]}, then {time[i + 1]:g}; time must strictly increase"
                + (f" ({bad.size} places in all)" if bad.size > 1 else ""),
                line_of[i + 1],
                tcol,
                unit,
                fix="delete the repeated row(s), or sort the rows by time",
            )
        )
    median_dt = float(np.median(step)) if step.size else float("nan")
    if not bad.size and median_dt > 0:
        gaps = np.flatnonzero(step > GAP_FACTOR * median_dt)
        for i in gaps[:3]:
            problems.append(
                DemonstrationError(
                    path,
                    f"gap in time: {time[i]:g} s at {unit} {line_of[i]}, then {time[i + 1]:g} s "
                    f"({step[i]:.3g} s, {step[i] / median_dt:.0f} x the median step of {median_dt:.3g} s; "
                    f"frames lost?)" + (f" ({gaps.size} gaps in all)" if gaps.size > 3 and i == gaps[0] else ""),
                    line_of[i + 1],
                    tcol,
                    unit,
                    fix="re-record, or split the file at the gap into two recordings (the motion across a gap "
                    "would be made up by interpolation)",
                )
            )
    lim = np.asarray(limits, np.float64)
    lo, hi = lim.min(axis=1), lim.max(axis=1)
    travel = hi - lo
    clipped = {}
    for j in range(values.shape[1]):
        margin = tolerance * travel[j]
        over = np.flatnonzero((values[:, j] < lo[j] - margin) | (values[:, j] > hi[j] + margin))
        if over.size:
            i = int(over[0])
            excess = max(lo[j] - values[i, j], values[i, j] - hi[j])
            problems.append(
                DemonstrationError(
                    path,
                    f"value {values[i, j]:g} is outside the declared limits [{lo[j]:g}, {hi[j]:g}] of tendon {j} "
                    f"by {excess:.3g} ({100 * excess / travel[j]:.2g}% of the travel; up to "
                    f"{100 * tolerance:g}% is clipped) ({over.size} row(s) in all)",
                    line_of[i],
                    names[j],
                    unit,
                    fix="check the limits declared for this tendon (slack:full in the file's units), "
                    "or raise --tolerance if the sensor is that noisy",
                )
            )
            continue
        out = (values[:, j] < lo[j]) | (values[:, j] > hi[j])
        if out.any():
            clipped[names[j]] = int(out.sum())
            values[:, j] = np.clip(values[:, j], lo[j], hi[j])
    if clipped:
        notes.append(
            f"{sum(clipped.values())} reading(s) just outside the limits clipped (within the tolerance of "
            f"{100 * tolerance:g}% of the travel): " + ", ".join(f"{c} {n}" for c, n in clipped.items())
        )
    span = (values.max(axis=0) - values.min(axis=0)) / travel
    if np.all(span < FLAT_FRACTION):
        problems.append(
            DemonstrationError(
                path,
                f"flat recording: every tendon stays within {100 * span.max():.2g}% of its travel from {unit} "
                f"{line_of[0]} to {line_of[-1]} (the robot was off, or the wrong file?)",
                line_of[0],
                None,
                unit,
                fix="re-record",
            )
        )
    elif not bad.size and median_dt > 0:
        for j in range(values.shape[1]):
            for a, b in _runs(values[:, j]):
                if b - a < MIN_ROWS or time[b - 1] - time[a] < STUCK_SECONDS:
                    continue
                v = values[a, j]
                if min(abs(v - lo[j]), abs(v - hi[j])) <= FLAT_FRACTION * travel[j]:
                    continue  # resting at slack or full pull (or a sensor at the end of its range)
                others = [k for k in range(values.shape[1]) if k != j]
                moving = [k for k in others if np.ptp(values[a:b, k]) > STUCK_MOVING * travel[k]]
                if moving:
                    problems.append(
                        DemonstrationError(
                            path,
                            f"stuck channel: reads exactly {v:g} for {time[b - 1] - time[a]:.3g} s ({unit}s "
                            f"{line_of[a]}-{line_of[b - 1]}) while {names[moving[0]]!r} moves",
                            line_of[a],
                            names[j],
                            unit,
                            fix="check the sensor and re-record",
                        )
                    )
                    break
    if problems:
        raise ImportProblems(problems)
    return Recording(
        time=time,
        values=values,
        columns=tuple(names),
        notes=tuple(notes),
        clipped=clipped,
        median_dt=median_dt,
        lines=tuple(line_of),
        time_column=tcol,
    )


def read_recording(path, limits, time_column: str | None = None, tolerance: float = TOLERANCE) -> Recording:
    """:func:`inspect_recording` (kept for the first interface): raises a :class:`DemonstrationError`
    naming every problem of the file."""
    return inspect_recording(path, limits, time_column, tolerance=tolerance)


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


def _too_many_cells(path: Path, line: int, header: list[str], cells: list[str], delimiter: str) -> DemonstrationError:
    """A CSV manifest row with more cells than the header: a text with an unquoted delimiter (never cut)."""
    extra = len(cells) - len(header)
    fix = "quote the text that holds a comma"
    if "texts" in header:  # the extra cells belong to the texts (the columns after it keep their place)
        i = header.index("texts")
        merged = cells[:i] + [delimiter.join(cells[i : i + extra + 1])] + cells[i + extra + 1 :]
        buf = io.StringIO()
        csv.writer(buf, delimiter=delimiter, lineterminator="").writerow(merged)
        fix = f"quote the text, e.g. this line as: {buf.getvalue()}"
    return DemonstrationError(
        path,
        f"{len(cells)} cells, but the header has {len(header)} ({', '.join(header)}): a text with an unquoted "
        f"{delimiter!r}? (the row is not cut short silently)",
        line,
        fix=fix,
    )


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
        fields = {
            k: doc[k] for k in ("limits", "time_column", "simulate", "columns") if isinstance(doc, dict) and k in doc
        }
        numbered = [(i + 1, r) for i, r in enumerate(rows)]  # 'line' = 1-based entry number
    else:
        try:
            text = path.read_bytes().decode("utf-8-sig")
        except (OSError, UnicodeDecodeError) as e:
            raise DemonstrationError(path, f"cannot read the manifest ({e})", fix="save it as UTF-8 text") from None
        first = next((ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")), "")
        delimiter = ";" if first.count(";") > first.count(",") else ","
        reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
        rows = []
        for cells in reader:  # quoted cells may hold the delimiter (and even span lines)
            if cells and any(c.strip() for c in cells) and not cells[0].lstrip().startswith("#"):
                rows.append((reader.line_num, cells))
        if not rows:
            raise DemonstrationError(path, "empty manifest", fix="add a header row: file,intent,intensity,texts")
        header_line, header = rows[0][0], [h.strip().lower() for h in rows[0][1]]
        missing = {"file", "intent", "intensity"} - set(header)
        if missing:
            raise DemonstrationError(
                path,
                f"manifest header {header} lacks {sorted(missing)}",
                header_line,
                fix="the header is file,intent,intensity[,texts][,realization]",
            )
        numbered = []
        for n, cells in rows[1:]:
            if len(cells) > len(header):
                numbered.append((n, _too_many_cells(path, n, header, cells, delimiter)))
            else:
                numbered.append((n, dict(zip(header, cells))))
        fields = {}
    out, unit = [], manifest_unit(path)
    for line, row in numbered:
        try:
            if isinstance(row, DemonstrationError):
                raise row
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


def _fail(error: DemonstrationError, problems: list) -> None:
    problems.extend(error.problems if isinstance(error, ImportProblems) else [error])


def _leave_out(error: DemonstrationError, manifest: Path, entry: Entry, unit: str) -> DemonstrationError:
    """``error`` of a recording, its fix extended by the manifest line that lists the file."""
    errors = error.problems if isinstance(error, ImportProblems) else [error]
    out = [
        DemonstrationError(
            e.file,
            e.reason,
            e.line,
            e.column,
            e.unit,
            fix=(e.fix + "; " if e.fix else "") + f"or leave the file out: delete {manifest.name} {unit} {entry.line}",
        )
        for e in errors
    ]
    return ImportProblems(out)


def _mixed_units(recs: list, kept: list, manifest: Path, unit: str) -> list[int]:
    """Indices of recordings whose median time step is :data:`UNITS_RATIO` x off the folder's median
    (one file in milliseconds among files in seconds), each with its problem."""
    steps = np.array([r.median_dt for r in recs])
    if len(steps) < 3:
        return []
    typical = float(np.median(steps))
    return [i for i, dt in enumerate(steps) if not (typical / UNITS_RATIO <= dt <= typical * UNITS_RATIO)]


def _units_problem(rec: Recording, entry: Entry, folder: Path, typical: float, manifest: Path, unit: str):
    ratio = rec.median_dt / typical
    looks = "milliseconds" if ratio > 1 else "another unit"
    duration = float(rec.time[-1] - rec.time[0])
    return DemonstrationError(
        folder / entry.file,
        f"time looks like {looks}: median step {rec.median_dt:.4g} and duration {duration:.6g} (last time stamp "
        f"at line {rec.lines[-1] if rec.lines else '?'}), where the other files have a median step of "
        f"{typical:.4g} s ({ratio:.0f} x apart)",
        rec.lines[1] if len(rec.lines) > 1 else None,
        rec.time_column,
        fix=(
            "convert the time column to seconds, or name it time_ms so it is read as milliseconds"
            if ratio > 1
            else "convert the time column to seconds"
        )
        + f"; or leave the file out: delete {manifest.name} {unit} {entry.line}",
    )


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
    entries, fields = read_manifest(manifest)
    unit = manifest_unit(manifest)
    problems: list[DemonstrationError] = []
    kept, recs = [], []
    seen: dict[str, int] = {}
    columns = config.columns or (tuple(fields["columns"]) if fields.get("columns") else None)
    for e in entries:
        if isinstance(e, DemonstrationError):
            _fail(e, problems)
            continue
        if e.file in seen:
            _fail(
                DemonstrationError(
                    manifest,
                    f"{e.file} is listed twice (also {unit} {seen[e.file]})",
                    e.line,
                    "file",
                    unit,
                    fix=f"delete one of the two {unit}s",
                ),
                problems,
            )
            continue
        seen[e.file] = e.line
        try:
            rec = inspect_recording(
                folder / e.file, config.limits, config.time_column, tolerance=config.tolerance, columns=columns
            )
        except DemonstrationError as err:
            _fail(_leave_out(err, manifest, e, unit), problems)
            continue
        if columns is None and not e.file.lower().endswith(".json"):
            columns = rec.columns  # the first file's columns, in the order of the limits
        kept.append(e)
        recs.append(rec)
    off = _mixed_units(recs, kept, manifest, unit)
    if off:
        typical = float(np.median([r.median_dt for r in recs]))
        for i in off:
            _fail(_units_problem(recs[i], kept[i], folder, typical, manifest, unit), problems)
        kept = [e for i, e in enumerate(kept) if i not in off]
        recs = [r for i, r in enumerate(recs) if i not in off]
    if not kept:
        if problems and not config.drop_invalid:
            raise ImportProblems(problems, len(entries))
        raise DemonstrationError(
            manifest,
            "no valid demonstration to import" + (f" ({len(problems)} problem(s))" if problems else ""),
            fix="fix the files listed above",
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
            _fail(err, problems)
            short_tuples.append(key)
    for key in short_tuples:
        del by_tuple[key]
    if problems and not config.drop_invalid:
        raise ImportProblems(problems, len(entries))
    if not by_tuple:
        raise DemonstrationError(manifest, "no tuple has enough valid realizations for the split")
    dropped = [p.as_dict() for p in problems]

    order, heldout = [], []
    for key in sorted(by_tuple):
        idx = sorted(by_tuple[key], key=lambda i: realization[i])
        held = np.random.default_rng([config.seed, *key]).choice(len(idx), config.heldout_per_tuple, replace=False)
        order += idx
        heldout += [k in set(held.tolist()) for k in range(len(idx))]
    left_out = len(entries) - len(order)
    if config.drop_invalid and left_out > config.max_dropped * len(entries):
        raise TooManyDropped(
            problems,
            rejected,
            f"{left_out} of {len(entries)} file(s) not imported ({100 * left_out / len(entries):.0f}%: "
            f"{len({p.file for p in problems})} with problems, {len(rejected)} rejected by screening), more than "
            f"--max-dropped {config.max_dropped:g} ({100 * config.max_dropped:g}%); nothing was written",
            manifest,
        )
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
        "tolerance": config.tolerance,
        "clipped": {kept[i].file: recs[i].clipped for i in order if recs[i].clipped},
        "notes": {kept[i].file: list(recs[i].notes) for i in range(len(kept)) if recs[i].notes},
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
    card["regenerate"] = "python -m jgrounding.library " + " ".join(argv if argv is not None else sys.argv[1:])
    path = library.save(arrays, card, args.out)
    print(
        f"wrote {path} and {path.with_suffix('.json')}: {card['num_records']} demonstrations "
        f"({card['num_train']} train / {card['num_heldout']} held out) of {len(card['counts_per_tuple'])} tuples, "
        f"N_u = {card['num_tendons']}, {len(card['rejected'])} rejected, {len(card['dropped'])} dropped; "
        f"{sum(sum(c.values()) for c in card['clipped'].values())} reading(s) in {len(card['clipped'])} file(s) "
        f"clipped into the limits (tolerance {100 * card['tolerance']:g}% of the travel)"
    )
    return 0
