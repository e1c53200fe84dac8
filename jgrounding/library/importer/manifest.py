"""The manifest (``manifest.csv`` or ``manifest.json``): per file its ``intent``, ``intensity``, optional
response ``texts`` and ``realization`` id; a JSON manifest may also declare ``limits``, ``columns``,
``time_column`` and ``simulate``.

A bad row does not stop the reading: it becomes a :class:`Row` with its problems, each with a fix, and the
file it names (when it names one) is still read and checked, so that one run reports the manifest's
problems and the recordings' together. Only a manifest that cannot be read at all raises.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
from pathlib import Path

import numpy as np

from jgrounding.library.importer.errors import DemonstrationError
from jgrounding.vocabulary import INTENSITIES, INTENTS, intensity_index, intent_index

MANIFEST_NAMES = ("manifest.json", "manifest.csv")
REQUIRED = ("file", "intent", "intensity")
FIELDS = ("limits", "time_column", "simulate", "columns", "markers", "marker_units", "max_marker_gap_s")
# a JSON manifest's global fields (the last three: motion-capture markers, jgrounding.library.importer.markers)


@dataclasses.dataclass(frozen=True)
class Entry:
    """One valid manifest row."""

    file: str
    intent: int
    intensity: int
    texts: tuple[str, ...]
    realization: int | None
    line: int


@dataclasses.dataclass(frozen=True)
class Row:
    """One manifest row as read: its ``entry`` when valid, else its ``problems``; ``file`` whenever it names one."""

    line: int  # the CSV line, or the 1-based entry of a JSON list
    file: str | None
    entry: Entry | None
    problems: tuple[DemonstrationError, ...] = ()


@dataclasses.dataclass(frozen=True)
class Manifest:
    path: Path
    rows: tuple[Row, ...]
    fields: dict  # a JSON manifest's global fields (FIELDS)
    problems: tuple[DemonstrationError, ...] = ()  # of the manifest as a whole (its header)

    @property
    def unit(self) -> str:
        return manifest_unit(self.path)


def manifest_unit(path: Path) -> str:
    """How a manifest's rows are counted in messages: ``line`` of a CSV, ``entry`` of a JSON list."""
    return "entry" if Path(path).suffix.lower() == ".json" else "line"


def tuple_name(m: int, z: int) -> str:
    """``intent/intensity`` of indices ``(m, z)``, as messages and the card name a tuple."""
    return f"{INTENTS[m]}/{INTENSITIES[z]}"


def find_manifest(folder: Path) -> Path:
    found = [folder / n for n in MANIFEST_NAMES if (folder / n).is_file()]
    if len(found) != 1:
        what = "no manifest" if not found else "two manifests"
        raise DemonstrationError(
            folder, f"{what}: put exactly one of {' or '.join(MANIFEST_NAMES)} in the folder (or pass --manifest)"
        )
    return found[0]


def check_limits(limits, where) -> tuple[tuple[float, float], ...]:
    """Declared limits as ``((slack, full_pull), ...)``, one pair of two different finite numbers per tendon."""
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


# ---------------------------------------------------------------- one row


def _label(row: dict, name: str, index, valid, file: str, where: Path, line: int, unit: str):
    """(index of the row's ``intent`` / ``intensity`` label, or None; its problems)."""
    try:
        return index(str(row.get(name, "")).strip()), []
    except ValueError as e:
        return None, [
            DemonstrationError(
                where, f"{file}: {e}", line, name, unit, fix=f"write one of the valid {name}s: {', '.join(valid)}"
            )
        ]


def _realization(row: dict, file: str, where: Path, line: int, unit: str):
    real = row.get("realization")
    if real in (None, ""):
        return None, []
    try:
        return int(str(real).strip()), []
    except ValueError:
        return None, [
            DemonstrationError(
                where,
                f"{file}: realization must be an integer, got {real!r}",
                line,
                "realization",
                unit,
                fix="write an integer id, or leave the cell empty (an id is assigned)",
            )
        ]


def _texts(row: dict) -> tuple[str, ...]:
    texts = row.get("texts", row.get("text", ())) or ()
    if isinstance(texts, str):
        texts = texts.split("|")
    return tuple(str(t).strip() for t in texts if str(t).strip())


def _row(row, where: Path, line: int, unit: str, labelled: bool = True) -> Row:
    """One manifest row (a dict of its cells); ``labelled=False`` when the header lacks the label columns."""
    if not isinstance(row, dict):
        problem = DemonstrationError(
            where,
            f"entry is {type(row).__name__}, expected an object",
            line,
            unit=unit,
            fix='write {"file": ..., "intent": ..., "intensity": ...}',
        )
        return Row(line, None, None, (problem,))
    file = str(row.get("file") or "").strip() or None
    if file is None:
        problem = DemonstrationError(
            where, "no 'file' given", line, "file", unit, fix="name the recording's file, or delete the row"
        )
        return Row(line, None, None, (problem,))
    if not labelled:
        return Row(line, file, None)
    intent, bad_intent = _label(row, "intent", intent_index, INTENTS, file, where, line, unit)
    intensity, bad_intensity = _label(row, "intensity", intensity_index, INTENSITIES, file, where, line, unit)
    real, bad_real = _realization(row, file, where, line, unit)
    problems = tuple(bad_intent + bad_intensity + bad_real)
    if problems:
        return Row(line, file, None, problems)
    return Row(line, file, Entry(file, intent, intensity, _texts(row), real, line))


# ---------------------------------------------------------------- the file


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


def _file_before_texts(header: list[str], cells: list[str]) -> str | None:
    """The file of a row with too many cells, when its cell comes before the texts (the extra cells are the
    texts'), so that the recording is still checked."""
    at = header.index("file")
    if "texts" in header and at > header.index("texts"):
        return None
    return cells[at].strip() or None


def _labels_of(path: Path, header: list[str], cells: list[str], line: int) -> tuple[DemonstrationError, ...]:
    """The other problems (a misspelt intent, a bad realization id) of a row with too many cells, reported with
    its cell count in the same run: read with the extra cells joined to the texts, where they belong; none
    when the header has no texts column (then no cell's place is sure)."""
    if "texts" not in header or not all(k in header for k in REQUIRED):
        return ()
    i, extra = header.index("texts"), len(cells) - len(header)
    merged = cells[:i] + [",".join(cells[i : i + extra + 1])] + cells[i + extra + 1 :]
    return _row(dict(zip(header, merged)), path, line, "line").problems


def _read_json(path: Path) -> Manifest:
    try:
        doc = json.loads(path.read_text())
    except ValueError as e:
        raise DemonstrationError(path, f"not valid JSON: {e}") from None
    rows = doc.get("demonstrations") if isinstance(doc, dict) else doc
    if not isinstance(rows, list):
        raise DemonstrationError(path, "expected {'demonstrations': [{'file', 'intent', 'intensity', ...}]}")
    fields = {k: doc[k] for k in FIELDS if isinstance(doc, dict) and k in doc}
    return Manifest(path, tuple(_row(r, path, i + 1, "entry") for i, r in enumerate(rows)), fields)


def _read_csv(path: Path) -> Manifest:
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise DemonstrationError(path, f"cannot read the manifest ({e})", fix="save it as UTF-8 text") from None
    first = next((ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")), "")
    delimiter = ";" if first.count(";") > first.count(",") else ","
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
    lines = []
    for cells in reader:  # quoted cells may hold the delimiter (and even span lines)
        if cells and any(c.strip() for c in cells) and not cells[0].lstrip().startswith("#"):
            lines.append((reader.line_num, cells))
    if not lines:
        raise DemonstrationError(path, "empty manifest", fix="add a header row: file,intent,intensity,texts")
    header_line, header = lines[0][0], [h.strip().lower() for h in lines[0][1]]
    missing = sorted(set(REQUIRED) - set(header))
    problems = ()
    if missing:
        problems = (
            DemonstrationError(
                path,
                f"manifest header {header} lacks {missing}"
                + ("" if "file" in header else " (no recording could be checked)"),
                header_line,
                fix="the header is file,intent,intensity[,texts][,realization]",
            ),
        )
    rows = []
    for n, cells in lines[1:]:
        if "file" not in header:  # the header's problem is the row's: no file to check
            rows.append(Row(n, None, None))
        elif len(cells) > len(header):
            problem = _too_many_cells(path, n, header, cells, delimiter)
            rows.append(
                Row(n, _file_before_texts(header, cells), None, (problem,) + _labels_of(path, header, cells, n))
            )
        else:
            rows.append(_row(dict(zip(header, cells)), path, n, "line", labelled=not missing))
    return Manifest(path, tuple(rows), {}, problems)


def read_manifest(path) -> Manifest:
    """Every row of a manifest (each a :class:`Row`: its :class:`Entry`, or its problems) and a JSON manifest's
    global fields; raises ``DemonstrationError`` only for a manifest that cannot be read."""
    path = Path(path)
    return _read_json(path) if path.suffix.lower() == ".json" else _read_csv(path)
