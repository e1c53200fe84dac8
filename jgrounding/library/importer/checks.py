"""Every check of an import, one function each, each returning its problems (an empty list: passed).

Checks of one recording take the :class:`~jgrounding.library.importer.parse.Table` as read; checks of the
folder take the recordings and manifest rows and return their problems keyed by what each one leaves out.
Nothing here raises: the pipeline gathers every problem of a run into one report.
"""

from __future__ import annotations

import numpy as np

from jgrounding.config import NUM_STEPS  # T of Table I
from jgrounding.library.importer.errors import DemonstrationError

MIN_ROWS = 10  # fewer recorded samples than this cannot be resampled to T = 150 meaningfully
TOLERANCE = 0.01  # readings up to 1% of a tendon's travel outside its limits are sensor noise: clipped, counted
GAP_FACTOR = 5.0  # a time step over 5 x the recording's median step is a gap (lost frames): an error
STUCK_SECONDS = 1.0  # one exact reading held this long, away from the limits, while another tendon moves: stuck
STUCK_MOVING = 0.05  # "moves": a range over 5% of that tendon's travel during the run
FLAT_FRACTION = 0.02  # every tendon within 2% of its travel: a flat recording (the robot was off)
UNITS_RATIO = 100.0  # a median time step 100 x off the folder's median: another time unit (ms vs s)


# ---------------------------------------------------------------- one recording


def check_tendon_columns(
    path, header_line: int, time_column: str, candidates, num_tendons: int, columns, reference, notes=()
) -> list[DemonstrationError]:
    """The file's tendon columns against the declared limits: with ``columns`` named (the reference file's or
    the manifest's), each must be there (a missing one is named, with the fix to add or rename it); without,
    the file must have one column per declared limit (``notes``: the columns left out as not tendons)."""
    if columns is None:
        if len(candidates) == num_tendons:
            return []
        ignored = f"; {'; '.join(notes)}" if notes else ""
        return [
            DemonstrationError(
                path,
                f"{len(candidates)} tendon column(s) {list(candidates)}, but {num_tendons} "
                f"tendon limits are declared (one column per tendon besides {time_column!r} and step/frame{ignored})",
                header_line,
                fix=f"declare one 'slack:full' pair per tendon column ({len(candidates)}) in the file's units"
                + (
                    f", or one pair for all with --tendons {len(candidates)}" if num_tendons == 1 and candidates else ""
                ),
            )
        ]
    have = {c.lower() for c in candidates}
    missing = [c for c in columns if c.lower() not in have]
    if not missing:
        return []
    named = {c.lower() for c in columns}
    extra = [c for c in candidates if c.lower() not in named]
    source = f"the tendon columns of {reference}" if reference else "the first file's"
    if extra and len(extra) == len(missing):
        fix = "rename this file's columns to the same names (case does not matter): " + ", ".join(
            f"{a!r} -> {b!r}" for a, b in zip(extra, missing)
        )
    elif extra:
        fix = "rename this file's columns to the same names (case does not matter), or import it separately"
    else:
        fix = (
            f"add the column{'s' if len(missing) > 1 else ''} {', '.join(map(repr, missing))}: every file needs "
            f"the {len(columns)} tendon columns, one per declared limit"
        )
    return [
        DemonstrationError(
            path,
            f"tendon columns {list(candidates)} do not match {list(columns)} ({source}, in the order of the "
            f"limits): {missing} missing",
            header_line,
            fix=fix,
        )
    ]


def check_row_count(table) -> list[DemonstrationError]:
    """At least :data:`MIN_ROWS` rows, to resample to T = 150 steps."""
    if len(table.time) >= MIN_ROWS:
        return []
    return [
        DemonstrationError(
            table.path,
            f"only {len(table.time)} data row(s); at least {MIN_ROWS} are needed to resample to T = {NUM_STEPS} steps",
            fix="record a longer motion",
        )
    ]


def median_step(table) -> float:
    """The recording's median time step (NaN for one row)."""
    step = np.diff(table.time)
    return float(np.median(step)) if step.size else float("nan")


def time_increases(table) -> bool:
    return not np.any(np.diff(table.time) <= 0)


def check_time_increases(table) -> list[DemonstrationError]:
    """Time strictly increases (no duplicate stamp, never backwards): the first place, with a count."""
    time, lines = table.time, table.lines
    step = np.diff(time)
    bad = np.flatnonzero(step <= 0)
    if not bad.size:
        return []
    i = int(bad[0])
    what = "duplicate time stamp" if step[i] == 0 else "time goes backwards"
    return [
        DemonstrationError(
            table.path,
            f"{what}: {time[i]:g} at {table.unit} {lines[i]}, then {time[i + 1]:g}; time must strictly increase"
            + (f" ({bad.size} places in all)" if bad.size > 1 else ""),
            lines[i + 1],
            table.time_column,
            table.unit,
            fix="delete the repeated row(s), or sort the rows by time",
        )
    ]


def check_time_gaps(table) -> list[DemonstrationError]:
    """No step over :data:`GAP_FACTOR` x the median (lost frames): the first three, with a count."""
    median_dt = median_step(table)
    if not time_increases(table) or not median_dt > 0:
        return []
    time, lines, unit = table.time, table.lines, table.unit
    step = np.diff(time)
    gaps = np.flatnonzero(step > GAP_FACTOR * median_dt)
    return [
        DemonstrationError(
            table.path,
            f"gap in time: {time[i]:g} s at {unit} {lines[i]}, then {time[i + 1]:g} s "
            f"({step[i]:.3g} s, {step[i] / median_dt:.0f} x the median step of {median_dt:.3g} s; "
            f"frames lost?)" + (f" ({gaps.size} gaps in all)" if gaps.size > 3 and i == gaps[0] else ""),
            lines[i + 1],
            table.time_column,
            unit,
            fix="re-record, or split the file at the gap into two recordings (the motion across a gap "
            "would be made up by interpolation)",
        )
        for i in gaps[:3]
    ]


def _bounds(limits) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lower, upper, travel) per tendon of ``(slack, full pull)`` limits in either order."""
    lim = np.asarray(limits, np.float64)
    lo, hi = lim.min(axis=1), lim.max(axis=1)
    return lo, hi, hi - lo


def _beyond(values: np.ndarray, limits, tolerance: float) -> np.ndarray:
    """``(n, N_u)`` bool: readings further than ``tolerance`` x the travel outside the limits."""
    lo, hi, travel = _bounds(limits)
    margin = tolerance * travel
    return (values < lo - margin) | (values > hi + margin)


def check_limits(table, limits, tolerance: float = TOLERANCE) -> list[DemonstrationError]:
    """No reading more than ``tolerance`` x the travel outside its tendon's limits: per tendon, the first,
    with a count."""
    values, (lo, hi, travel) = table.values, _bounds(limits)
    beyond = _beyond(values, limits, tolerance)
    problems = []
    for j in np.flatnonzero(beyond.any(axis=0)):
        over = np.flatnonzero(beyond[:, j])
        i = int(over[0])
        excess = max(lo[j] - values[i, j], values[i, j] - hi[j])
        problems.append(
            DemonstrationError(
                table.path,
                f"value {values[i, j]:g} is outside the declared limits [{lo[j]:g}, {hi[j]:g}] of tendon {j} "
                f"by {excess:.3g} ({100 * excess / travel[j]:.2g}% of the travel; up to "
                f"{100 * tolerance:g}% is clipped) ({over.size} row(s) in all)",
                table.lines[i],
                table.columns[j],
                table.unit,
                fix="check the limits declared for this tendon (slack:full in the file's units), "
                "or raise --tolerance if the sensor is that noisy",
            )
        )
    return problems


def clip_noise(table, limits, tolerance: float = TOLERANCE) -> tuple[np.ndarray, dict]:
    """(values clipped into the limits, ``{column: readings clipped}``) for each tendon whose readings all lie
    within the tolerance (sensor noise); a tendon with a reading beyond it is left as read (it is an error)."""
    values, (lo, hi, _) = table.values.copy(), _bounds(limits)
    beyond = _beyond(values, limits, tolerance).any(axis=0)
    clipped = {}
    for j in range(values.shape[1]):
        out = (values[:, j] < lo[j]) | (values[:, j] > hi[j])
        if not beyond[j] and out.any():
            clipped[table.columns[j]] = int(out.sum())
            values[:, j] = np.clip(values[:, j], lo[j], hi[j])
    return values, clipped


def _is_flat(values: np.ndarray, limits) -> tuple[bool, float]:
    span = (values.max(axis=0) - values.min(axis=0)) / _bounds(limits)[2]
    return bool(np.all(span < FLAT_FRACTION)), float(span.max())


def check_flat(table, values: np.ndarray, limits) -> list[DemonstrationError]:
    """Some tendon moves more than :data:`FLAT_FRACTION` of its travel (else the robot was off)."""
    flat, widest = _is_flat(values, limits)
    if not flat:
        return []
    lines, unit = table.lines, table.unit
    return [
        DemonstrationError(
            table.path,
            f"flat recording: every tendon stays within {100 * widest:.2g}% of its travel from {unit} "
            f"{lines[0]} to {lines[-1]} (the robot was off, or the wrong file?)",
            lines[0],
            None,
            unit,
            fix="re-record",
        )
    ]


def _runs(x: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of maximal runs of exactly equal consecutive values in ``x``."""
    change = np.flatnonzero(np.diff(x) != 0) + 1
    edges = np.concatenate([[0], change, [len(x)]])
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def check_stuck(table, values: np.ndarray, limits) -> list[DemonstrationError]:
    """No channel holds one exact reading for :data:`STUCK_SECONDS` or longer, away from the limits, while
    another tendon moves (checked on a recording that is not flat and whose time increases)."""
    if _is_flat(values, limits)[0] or not time_increases(table) or not median_step(table) > 0:
        return []
    time, lines, unit, names = table.time, table.lines, table.unit, table.columns
    lo, hi, travel = _bounds(limits)
    problems = []
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
                        table.path,
                        f"stuck channel: reads exactly {v:g} for {time[b - 1] - time[a]:.3g} s ({unit}s "
                        f"{lines[a]}-{lines[b - 1]}) while {names[moving[0]]!r} moves",
                        lines[a],
                        names[j],
                        unit,
                        fix="check the sensor and re-record",
                    )
                )
                break
    return problems


# ---------------------------------------------------------------- the folder


def check_listed_once(rows, manifest, unit: str) -> dict[int, DemonstrationError]:
    """Each file is listed once: ``{row index: problem}`` for every later listing of a file."""
    first, out = {}, {}
    for i, row in enumerate(rows):
        if row.file is None:
            continue
        if row.file in first:
            out[i] = DemonstrationError(
                manifest,
                f"{row.file} is listed twice (also {unit} {first[row.file]})",
                row.line,
                "file",
                unit,
                fix=f"delete one of the two {unit}s",
            )
        else:
            first[row.file] = row.line
    return out


def check_time_units(recordings: dict, rows, folder, manifest, unit: str) -> dict[int, DemonstrationError]:
    """One time unit in the folder: ``{row index: problem}`` for each recording whose median step is
    :data:`UNITS_RATIO` x off the folder's median (one file in milliseconds among files in seconds);
    ``recordings`` is ``{row index: Recording}`` (three at least, else nothing is compared)."""
    if len(recordings) < 3:
        return {}
    typical = float(np.median([r.median_dt for r in recordings.values()]))
    out = {}
    for i, rec in recordings.items():
        if typical / UNITS_RATIO <= rec.median_dt <= typical * UNITS_RATIO:
            continue
        ratio = rec.median_dt / typical
        looks = "milliseconds" if ratio > 1 else "another unit"
        duration = float(rec.time[-1] - rec.time[0])
        out[i] = DemonstrationError(
            folder / rows[i].file,
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
            + f"; or leave the file out: delete {manifest.name} {unit} {rows[i].line}",
        )
    return out


def check_realization_ids(entries: dict, manifest, unit: str, tuple_name) -> dict[int, DemonstrationError]:
    """Within a tuple each given realization id is used once: ``{row index: problem}`` for every later use
    of an id (``entries`` is ``{row index: Entry}``, in manifest order)."""
    first, out = {}, {}
    for i, e in entries.items():
        if e.realization is None:
            continue
        key = (e.intent, e.intensity, e.realization)
        if key in first:
            out[i] = DemonstrationError(
                manifest,
                f"tuple {tuple_name(e.intent, e.intensity)}: realization id {e.realization} used more than once "
                f"({unit}s {first[key]}, {e.line})",
                e.line,
                "realization",
                unit,
                fix="give each realization of a tuple its own id, or leave the cell empty (an id is assigned)",
            )
        else:
            first[key] = e.line
    return out


def check_split_sizes(
    by_tuple: dict, entries: dict, rejected: list, heldout_per_tuple: int, manifest, unit: str, tuple_name
) -> dict[tuple[int, int], DemonstrationError]:
    """Each tuple has a realization more than it holds out: ``{(intent, intensity): problem}``, naming its
    valid files and those rejected by screening (``by_tuple``: indices of the valid ones per tuple)."""
    need = heldout_per_tuple + 1
    tuple_of = {e.file: (e.intent, e.intensity) for e in entries.values()}
    out = {}
    for key in sorted(by_tuple):
        idx = by_tuple[key]
        if len(idx) >= need:
            continue
        rej = [f"{r['file']} ({', '.join(r['failed'])})" for r in rejected if tuple_of[r["file"]] == key]
        out[key] = DemonstrationError(
            manifest,
            f"tuple {tuple_name(*key)} has {len(idx)} valid realization(s) "
            f"({', '.join(entries[i].file for i in idx)}{'; rejected by screening: ' + ', '.join(rej) if rej else ''}); "
            f"the train/held-out split needs at least {need} ({heldout_per_tuple} held out + 1 to train)",
            entries[idx[0]].line,
            unit=unit,
            fix=f"record {need - len(idx)} more realization(s) of this tuple"
            + (", or fix those rejected by screening" if rej else "")
            + (", or hold fewer out (--heldout)" if heldout_per_tuple > 1 else ""),
        )
    return out
