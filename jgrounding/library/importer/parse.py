"""Reading one demonstration file into a :class:`Table`: a CSV in the lab's units (any delimiter, a BOM, a
decimal comma, seconds or milliseconds) or a command stream JSON of :mod:`jgrounding.apps.export`.

The tendon columns are chosen here: a column that holds no numbers (a status flag, the empty column of a
trailing delimiter) is not a tendon; with the tendon columns named (the reference file's, or the manifest's
``columns``), every other column is ignored, with a note. Cell problems of a file are raised together as
:class:`~jgrounding.library.importer.errors.ImportProblems`, each with its line, column and fix.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np

from jgrounding.library.importer import checks
from jgrounding.library.importer.errors import DemonstrationError, raise_if_any

TIME_COLUMNS = ("time", "time_s", "t", "timestamp", "elapsed", "elapsed_s")  # seconds; matched in any case
TIME_COLUMNS_MS = ("time_ms", "t_ms", "timestamp_ms", "elapsed_ms")  # milliseconds, converted
IGNORED_COLUMNS = ("step", "frame")


@dataclasses.dataclass(frozen=True)
class Table:
    """One file as read, before the recording checks."""

    path: Path
    time: np.ndarray  # (n,) float64 in seconds, as recorded (not yet checked to increase)
    values: np.ndarray  # (n, N_u) float64 in the lab's units, tendon columns in the order of the limits
    columns: tuple[str, ...]  # tendon column names, in the order of the limits (the file's own spelling)
    lines: tuple[int, ...]  # the file line (command) of each row
    time_column: str
    unit: str  # how rows are counted in messages: "line" of a CSV, "command" of a command stream JSON
    notes: tuple[str, ...]  # what was accepted but worth knowing (BOM, delimiter, mapping by name, ms, ...)


@dataclasses.dataclass(frozen=True)
class _Csv:
    header_line: int
    header: list[str]
    delimiter: str
    decimal_comma: bool
    rows: list[tuple[int, list[str]]]  # (file line, cells) of every data row
    notes: list[str]


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


def _is_number(cell: str, decimal_comma: bool) -> bool:
    try:
        float(cell.strip().replace(",", ".") if decimal_comma else cell.strip())
    except ValueError:
        return False
    return True


def _sniff(header: str) -> str:
    """The delimiter of a header line: ``;`` or a tab when it splits the header, else ``,``."""
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=counts.get)
    return best if counts[best] else ","


def _read_csv(path: Path) -> _Csv:
    raw = path.read_bytes()
    notes = ["UTF-8 byte-order mark skipped"] if raw.startswith(b"\xef\xbb\xbf") else []
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
    cells = [(n, next(csv.reader([ln], delimiter=delimiter))) for n, ln in lines]
    header = [h.strip() for h in cells[0][1]]
    return _Csv(lines[0][0], header, delimiter, decimal_comma, cells[1:], notes)


def _time_column(table: _Csv, path: Path, time_column: str | None) -> str:
    names = (time_column.lower(),) if time_column else TIME_COLUMNS + TIME_COLUMNS_MS
    found = next((h for h in table.header if h.lower() in names), None)
    if found is None:
        shown = (time_column,) if time_column else TIME_COLUMNS + TIME_COLUMNS_MS
        raise DemonstrationError(
            path,
            f"no time column: the header is {table.header} (read with {table.delimiter!r} between cells)",
            table.header_line,
            fix=f"name the time column one of {', '.join(shown)} (any case; *_ms for milliseconds), "
            "or pass --time-column NAME",
        )
    return found


def _candidates(table: _Csv, time_column: str, named=(), exclude=()) -> tuple[tuple[str, ...], list[str]]:
    """(the columns that may be tendons, notes on those that hold no numbers and so are not); a column
    ``named`` as a tendon always may be, one in ``exclude`` (a marker column) never is."""
    full = [cells for _, cells in table.rows if len(cells) == len(table.header)]
    named = {c.lower() for c in named}
    excluded = {c.lower() for c in exclude}
    keep, notes = [], []
    for k, name in enumerate(table.header):
        if name == time_column or name.lower() in IGNORED_COLUMNS or name.lower() in excluded:
            continue
        if name.lower() not in named and full and not any(_is_number(cells[k], table.decimal_comma) for cells in full):
            shown = f"column {name!r}" if name else f"column {k + 1} (no name; a trailing delimiter?)"
            filled = any(cells[k].strip() for cells in full)
            notes.append(f"{shown} holds {'no numbers' if filled else 'no values'}: not a tendon, ignored")
            continue
        keep.append(name)
    return tuple(keep), notes


def read_cells(path) -> _Csv:
    """A CSV recording's header and cells as text (delimiter, BOM and comments handled), unchecked: how the
    marker columns are read beside the tendon columns (:mod:`jgrounding.library.importer.markers`)."""
    return _read_csv(Path(path))


def tendon_candidates(path, time_column: str | None = None, exclude=()) -> tuple[str, ...] | None:
    """The columns of a CSV recording that may be tendons (``None`` for a file that cannot be read or a
    command stream JSON): how the import picks the reference file whose columns name the tendons."""
    path = Path(path)
    if path.suffix.lower() == ".json" or not path.is_file():
        return None
    try:
        table = _read_csv(path)
        return _candidates(table, _time_column(table, path, time_column), exclude=exclude)[0]
    except DemonstrationError:
        return None


def _tendons(
    table: _Csv, path: Path, time_column: str, num_tendons: int, columns, reference: str | None, exclude=()
) -> tuple[tuple[str, ...], list[str]]:
    """(tendon columns in the order of the limits, notes), or every column problem raised."""
    candidates, notes = _candidates(table, time_column, columns or (), exclude)
    raise_if_any(
        checks.check_tendon_columns(
            path, table.header_line, time_column, candidates, num_tendons, columns, reference, notes
        )
    )
    if columns is None:
        return candidates, notes
    lower = {c.lower(): c for c in candidates}
    tendons = tuple(lower[c.lower()] for c in columns)
    named = [c for c in candidates if c.lower() in {n.lower() for n in columns}]
    mapping = []
    if list(tendons) != named:
        mapping.append(f"columns in another order {named}: mapped by name to {list(columns)}")
    other = [c for c in candidates if c not in tendons]
    if other:
        mapping.append(f"column(s) {other} not among the tendon columns {list(columns)}: ignored")
    return tendons, mapping + notes


def _read_csv_table(path: Path, num_tendons: int, time_column: str | None, columns, reference, exclude=()) -> Table:
    table = _read_csv(path)
    tcol = _time_column(table, path, time_column)
    tendons, notes = _tendons(table, path, tcol, num_tendons, columns, reference, exclude)
    header = table.header
    order = [header.index(tcol)] + [header.index(c) for c in tendons]
    rows, row_lines, seen = [], [], {}
    for number, cells in table.rows:
        try:
            if len(cells) != len(header):
                more = len(cells) > len(header)
                raise DemonstrationError(
                    path,
                    f"{len(cells)} cells, but the header has {len(header)}"
                    + (" (decimal commas with ',' between cells?)" if more else ""),
                    number,
                    fix="export with '.' as the decimal mark or ';' between cells"
                    if more
                    else "complete or delete the row",
                )
            rows.append([_number(cells[i], path, number, header[i], decimal_comma=table.decimal_comma) for i in order])
            row_lines.append(number)
        except DemonstrationError as e:  # the first of each kind and column, with a count
            key = (e.reason.split(":")[0].split(" (")[0], e.column)
            seen.setdefault(key, [e, 0])[1] += 1
    raise_if_any(
        [
            DemonstrationError(e.file, e.reason + (f" ({n} rows in all)" if n > 1 else ""), e.line, e.column, fix=e.fix)
            for e, n in seen.values()
        ]
    )
    data = np.asarray(rows, np.float64).reshape(-1, 1 + len(tendons))
    if tcol.lower() in TIME_COLUMNS_MS:
        data[:, 0] /= 1000.0
        notes.append(f"time column {tcol!r} read as milliseconds")
    return Table(path, data[:, 0], data[:, 1:], tendons, tuple(row_lines), tcol, "line", tuple(table.notes + notes))


def _read_command_json(path: Path, num_tendons: int) -> Table:
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
    data = np.asarray(rows, np.float64).reshape(-1, 1 + num_tendons)
    return Table(path, data[:, 0], data[:, 1:], names, tuple(range(1, len(rows) + 1)), "time", "command", ())


def read_table(
    path, num_tendons: int, time_column: str | None = None, columns=None, reference=None, exclude=()
) -> Table:
    """Read one demonstration file: a CSV, or a command stream ``.json``.

    Args:
      path: the file.
      num_tendons: N_u, the number of declared tendon limits.
      time_column: the time column's name (``None``: the first of :data:`TIME_COLUMNS` / :data:`TIME_COLUMNS_MS`).
      columns: the tendon columns' names in the order of the limits (matched in any case; other columns are
        ignored), or ``None`` to take every column that holds numbers besides time and step/frame.
      reference: the file ``columns`` come from, named in messages (``None``: "the first file's").
      exclude: columns that are never tendons (the motion-capture marker columns of the manifest's map).

    Returns: the :class:`Table`; raises :class:`DemonstrationError` (``ImportProblems`` for several).
    """
    path = Path(path)
    if not path.is_file():
        raise DemonstrationError(path, "file not found", fix="check the file name in the manifest")
    if path.suffix.lower() == ".json":
        return _read_command_json(path, num_tendons)
    return _read_csv_table(path, num_tendons, time_column, columns, reference, exclude)
