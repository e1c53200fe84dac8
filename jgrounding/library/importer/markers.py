"""Motion-capture markers beside the tendon columns: the manifest's marker map and every check of the marker
columns of one recording.

A JSON manifest declares the markers::

    "markers": [{"name": "mid", "s": 0.35, "columns": ["mid_x", "mid_y", "mid_z"]},
                {"name": "tip", "s": "tip", "columns": ["tip_x", "tip_y", "tip_z"]}],
    "marker_units": "mm",          # or "m"
    "max_marker_gap_s": 0.05       # optional, the default

``s`` is the arc length from the base along the undeformed backbone in metres (``"tip"``: the trunk's length,
:data:`jgrounding.sim.mjcf.TRUNK_LENGTH`). Positions are in the world frame of the trunk model: the base at
``(0, 0, BASE_HEIGHT)``, z up, the trunk hanging along -z, the user at +x. The marker columns are sampled on
the recording's own clock, in the same rows as the tendon columns; a missing sample is an empty cell or NaN.

Checks (each problem with its file, line, column and fix; nothing raises here): the map itself (names, arc
lengths, three distinct columns per marker, one unit for all, a column suffix ``_mm`` / ``_m`` that says
another unit); per recording, the map against the header (a declared column missing, an undeclared
``name_x/_y/_z`` triplet), cells that are not numbers or are infinite, values whose size says another unit,
gaps (a marker missing for at most ``max_marker_gap_s`` is interpolated linearly, held at the ends; a longer
gap rejects the recording) and a recording shorter than :data:`MIN_DURATION_S`.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np

from jgrounding.library.importer import parse
from jgrounding.library.importer.errors import DemonstrationError
from jgrounding.sim.mjcf import TRUNK_LENGTH

MARKER_UNITS = {"m": 1.0, "mm": 1e-3}  # declared unit -> metres per unit
MAX_MARKER_GAP_S = 0.05  # a marker missing this long (or less) is interpolated; longer rejects the recording
MIN_DURATION_S = 1.0  # a recording with markers lasts at least this long (30 control steps at 30 Hz)
MARKER_FIELDS = ("markers", "marker_units", "max_marker_gap_s")  # a JSON manifest's marker fields
LOOKS_LIKE_MM = 20.0  # |value| over 20 in a map declared in metres: millimetres (the trunk spans ~1.2 m)
LOOKS_LIKE_M = 5.0  # every |value| under 5 in a map declared in millimetres: metres
_AXES = ("x", "y", "z")


@dataclasses.dataclass(frozen=True)
class Marker:
    name: str
    s: float  # arc length from the base along the undeformed backbone (m)
    columns: tuple[str, str, str]  # x, y, z


@dataclasses.dataclass(frozen=True)
class MarkerMap:
    markers: tuple[Marker, ...]
    units: str  # "m" or "mm"
    max_gap_s: float = MAX_MARKER_GAP_S

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.markers)

    @property
    def s(self) -> np.ndarray:
        return np.array([m.s for m in self.markers], np.float64)

    @property
    def columns(self) -> tuple[str, ...]:
        return tuple(c for m in self.markers for c in m.columns)

    @property
    def scale(self) -> float:
        return MARKER_UNITS[self.units]


def _problem(manifest, reason: str, column: str, fix: str) -> DemonstrationError:
    return DemonstrationError(manifest, reason, None, column, fix=fix)


def _one_marker(k: int, m, units: str, manifest, seen_names: set, seen_cols: set):
    """(the k-th marker of the map, or None; its problems)."""
    where = f"markers[{k}]"
    if not isinstance(m, dict):
        fix = 'write {"name": "tip", "s": 0.70, "columns": ["tip_x", "tip_y", "tip_z"]}'
        return None, [_problem(manifest, f"marker {k} is {type(m).__name__}, expected an object", where, fix)]
    problems = []
    name = str(m.get("name") or "").strip()
    if not name:
        problems.append(_problem(manifest, f"marker {k} has no name", where, 'give it a "name"'))
    elif name in seen_names:
        problems.append(_problem(manifest, f"marker name {name!r} used twice", where, "give each marker its own name"))
    seen_names.add(name)
    s = m.get("s")
    if isinstance(s, str) and s.strip().lower() == "tip":
        s = TRUNK_LENGTH
    try:
        s = float(s)
        ok = math.isfinite(s) and s >= 0.0
    except (TypeError, ValueError):
        ok = False
    if not ok:
        problems.append(
            _problem(
                manifest,
                f"marker {name or k!r}: s = {m.get('s')!r} is not an arc length",
                where + ".s",
                'write the arc length from the base along the undeformed backbone in metres (>= 0), or "tip"',
            )
        )
    cols = m.get("columns")
    if not (isinstance(cols, list) and len(cols) == 3 and all(isinstance(c, str) and c.strip() for c in cols)):
        problems.append(
            _problem(
                manifest,
                f"marker {name or k!r}: columns {cols!r} are not three column names",
                where + ".columns",
                f'name its x, y, z columns, e.g. ["{name or "tip"}_x", "{name or "tip"}_y", "{name or "tip"}_z"]',
            )
        )
        cols = None
    else:
        cols = tuple(c.strip() for c in cols)
        for c in cols:
            if c.lower() in seen_cols:
                problems.append(
                    _problem(manifest, f"column {c!r} is mapped twice", where + ".columns", "map each column once")
                )
            seen_cols.add(c.lower())
            other = {"m": "_mm", "mm": "_m"}.get(units)
            if other and c.lower().endswith(other):
                problems.append(
                    _problem(
                        manifest,
                        f"mixed units: column {c!r} says {other[1:]} but marker_units is {units!r}",
                        where + ".columns",
                        f"record every marker in one unit and declare it in marker_units ({' or '.join(MARKER_UNITS)})",
                    )
                )
    own = m.get("units")
    if own is not None and own != units:
        problems.append(
            _problem(
                manifest,
                f"mixed units: marker {name or k!r} declares units {own!r} but marker_units is {units!r}",
                where + ".units",
                "record every marker in one unit and declare it once in marker_units",
            )
        )
    if problems:
        return None, problems
    return Marker(name, s, cols), []


def marker_map(fields: dict, manifest) -> tuple[MarkerMap | None, list[DemonstrationError]]:
    """(the manifest's marker map, or None when it declares no markers; every problem of the map). A map with
    problems still comes back with its valid markers (None when none is valid or the unit is unknown), so that
    the recordings' marker columns are checked in the same run."""
    if "markers" not in fields:
        extra = [k for k in MARKER_FIELDS if k in fields]
        if extra:
            fix = 'declare the markers: "markers": [{"name": ..., "s": ..., "columns": [x, y, z]}, ...]'
            return None, [_problem(manifest, f"{extra[0]} given but no markers declared", extra[0], fix)]
        return None, []
    markers, units = fields["markers"], fields.get("marker_units")
    problems = []
    if units not in MARKER_UNITS:
        problems.append(
            _problem(
                manifest,
                f"marker_units is {units!r}",
                "marker_units",
                f'declare the markers\' unit: "marker_units": one of {", ".join(map(repr, MARKER_UNITS))}',
            )
        )
    gap = fields.get("max_marker_gap_s", MAX_MARKER_GAP_S)
    if not isinstance(gap, (int, float)) or isinstance(gap, bool) or not (math.isfinite(gap) and gap >= 0):
        problems.append(_problem(manifest, f"max_marker_gap_s is {gap!r}", "max_marker_gap_s", "write seconds >= 0"))
    if not isinstance(markers, list) or not markers:
        problems.append(
            _problem(manifest, "markers is not a non-empty list", "markers", "list each marker: name, s, columns")
        )
        return None, problems
    names, cols, found = set(), set(), []
    for k, m in enumerate(markers):
        marker, bad = _one_marker(k, m, units, manifest, names, cols)
        problems += bad
        if marker is not None:
            found.append(marker)
    if not found or units not in MARKER_UNITS:
        return None, problems
    gap = float(gap) if not any(p.column == "max_marker_gap_s" for p in problems) else MAX_MARKER_GAP_S
    return MarkerMap(tuple(found), units, gap), problems


def declared_columns(fields: dict) -> tuple[str, ...]:
    """Every column a manifest's marker map names, even a map with problems: never read as a tendon."""
    markers = fields.get("markers")
    if not isinstance(markers, list):
        return ()
    cols = [m.get("columns") for m in markers if isinstance(m, dict)]
    return tuple(c for cs in cols if isinstance(cs, list) for c in cs if isinstance(c, str))


def _triplets(header: list[str]) -> list[tuple[str, str]]:
    """``(name, x column)`` of each ``name_x``, ``name_y``, ``name_z`` triplet of columns (any case; an optional
    ``_m`` / ``_mm`` suffix)."""
    lower = {h.lower() for h in header}
    out = []
    for h in header:
        m = re.fullmatch(r"(.+)_x(_mm|_m)?", h.lower())
        if m and all(f"{m.group(1)}_{a}{m.group(2) or ''}" in lower for a in "yz"):
            out.append((h[: len(m.group(1))], h))
    return out


def _runs(missing: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of the runs of True in ``missing``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], missing.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _fill(x: np.ndarray, time: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``x`` (n,) with its invalid samples interpolated linearly in time (held at the ends)."""
    return np.interp(time, time[valid], x[valid])


def read_markers(
    path, mmap: MarkerMap, time: np.ndarray, lines, declared=()
) -> tuple[np.ndarray | None, list[str], list]:
    """(positions ``(n, M, 3)`` in metres with short gaps filled, or None; notes; problems) of the marker
    columns of one recording whose time and tendon columns were read (``time`` in seconds and ``lines``, the
    file line of each of its rows); ``declared``: every column the manifest's map names (also those of its
    markers with problems), never an unmapped marker."""
    table = parse.read_cells(path)
    header = table.header
    index = {h.lower(): k for k, h in enumerate(header)}
    problems = []
    missing = [c for c in mmap.columns if c.lower() not in index]
    if missing:
        problems.append(
            DemonstrationError(
                path,
                f"marker columns {missing} of the manifest's marker map are not in the file (its columns: {header})",
                table.header_line,
                missing[0],
                fix="correct the manifest's 'markers' map to the file's column names, or add the columns",
            )
        )
    mapped = {c.lower() for c in mmap.columns + tuple(declared)}
    stray = [(n, x) for n, x in _triplets(header) if x.lower() not in mapped]
    if stray:
        problems.append(
            DemonstrationError(
                path,
                f"marker columns of {[n for n, _ in stray]} are not in the manifest's marker map (markers: "
                f"{list(mmap.names)})",
                table.header_line,
                stray[0][1],
                fix="add each marker to the manifest's 'markers' (name, s, columns), or delete its columns",
            )
        )
    if problems:
        return None, [], problems
    cells = dict(table.rows)
    cols = [index[c.lower()] for c in mmap.columns]
    values = np.full((len(lines), len(cols)), np.nan)
    bad: dict[tuple[str, str], list] = {}
    for i, line in enumerate(lines):
        row = cells[line]
        for j, k in enumerate(cols):
            text = row[k].strip().replace(",", ".") if table.decimal_comma else row[k].strip()
            if not text or text.lower() == "nan":
                continue
            try:
                x = float(text)
            except ValueError:
                bad.setdefault(("not a number", header[k]), [line, text, 0])[2] += 1
                continue
            if not math.isfinite(x):
                bad.setdefault(("infinite value", header[k]), [line, text, 0])[2] += 1
                continue
            values[i, j] = x
    for (what, column), (line, text, n) in bad.items():
        problems.append(
            DemonstrationError(
                path,
                f"{what}: {text!r}" + (f" ({n} rows in all)" if n > 1 else ""),
                line,
                column,
                fix="write a number, or leave the cell empty (a missing marker sample)",
            )
        )
    duration = float(time[-1] - time[0])
    if duration < MIN_DURATION_S:
        problems.append(
            DemonstrationError(
                path,
                f"too short: {duration:.3g} s from line {lines[0]} to {lines[-1]}; a recording with markers lasts at "
                f"least {MIN_DURATION_S:g} s",
                lines[-1],
                fix="record a longer motion",
            )
        )
    size = np.nanmax(np.abs(values)) if np.isfinite(values).any() else float("nan")
    if mmap.units == "m" and size > LOOKS_LIKE_MM:
        k = int(np.nanargmax(np.nanmax(np.abs(values), axis=0)))
        line = lines[int(np.nanargmax(np.abs(values[:, k])))]
        problems.append(
            DemonstrationError(
                path,
                f"mixed units: a marker value of {size:g} in a map declared in metres (millimetres?)",
                line,
                mmap.columns[k],
                fix='convert this file to metres, or declare "marker_units": "mm" if every file is in millimetres',
            )
        )
    elif mmap.units == "mm" and size < LOOKS_LIKE_M:
        problems.append(
            DemonstrationError(
                path,
                f"mixed units: every marker value is under {LOOKS_LIKE_M:g} in a map declared in millimetres (metres?)",
                lines[0],
                mmap.columns[0],
                fix='convert this file to millimetres, or declare "marker_units": "m" if every file is in metres',
            )
        )
    notes = []
    out = values.reshape(len(lines), len(mmap.markers), 3) * mmap.scale
    for m, marker in enumerate(mmap.markers):
        gone = ~np.isfinite(out[:, m]).all(axis=1)
        if gone.all():
            problems.append(
                DemonstrationError(
                    path,
                    f"marker {marker.name!r} has no sample",
                    lines[0],
                    marker.columns[0],
                    fix="re-record, or take the marker out of the manifest's map",
                )
            )
            continue
        runs, filled = _runs(gone), 0
        for a, b in runs:
            t0 = time[a - 1] if a > 0 else time[a]
            t1 = time[b] if b < len(time) else time[b - 1]
            if t1 - t0 > mmap.max_gap_s:
                column = marker.columns[int(np.argmax(~np.isfinite(out[a, m])))]
                problems.append(
                    DemonstrationError(
                        path,
                        f"marker {marker.name!r} missing for {t1 - t0:.3g} s (lines {lines[a]}-{lines[b - 1]}), "
                        f"longer than max_marker_gap_s = {mmap.max_gap_s:g} s",
                        lines[a],
                        column,
                        fix="re-record, cut the recording at the gap, or allow longer gaps with max_marker_gap_s "
                        "(the motion across a gap is made up by interpolation)",
                    )
                )
                break
            filled += b - a
        else:
            if runs:
                valid = ~gone
                out[:, m] = np.stack([_fill(out[:, m, a], time, valid) for a in range(3)], axis=-1)
                notes.append(f"marker {marker.name!r}: {filled} missing sample(s) in {len(runs)} gap(s) interpolated")
    return (None if problems else out), notes, problems
