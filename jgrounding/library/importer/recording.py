"""One demonstration file, read (:mod:`~jgrounding.library.importer.parse`) and checked
(:mod:`~jgrounding.library.importer.checks`): :func:`inspect_recording`."""

from __future__ import annotations

import dataclasses

import numpy as np

from jgrounding.library.importer import checks, parse
from jgrounding.library.importer.errors import raise_if_any


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


def inspect_recording(
    path,
    limits,
    time_column: str | None = None,
    *,
    tolerance: float = checks.TOLERANCE,
    columns=None,
    reference=None,
    exclude=(),
    motion_checks: bool = True,
) -> Recording:
    """Read and check one demonstration file against per-tendon ``limits`` ``[(slack, full), ...]``.

    ``columns`` names the tendon columns in the order of the limits (other columns are ignored, with a note),
    ``reference`` the file they come from (for messages). Raises ``ImportProblems`` (a
    ``DemonstrationError``) listing every problem of the file, each with its line, column and fix:
    missing or surplus tendon columns; empty / non-numeric / NaN / Inf values; time that does not
    strictly increase (duplicates included); a gap in time over :data:`checks.GAP_FACTOR` x the median step;
    fewer than :data:`checks.MIN_ROWS` rows; a reading more than ``tolerance`` x the travel outside its
    tendon's limits; a stuck channel (the exact same reading for :data:`checks.STUCK_SECONDS` or longer, away
    from the limits, while another tendon moves); a flat recording (every tendon within
    :data:`checks.FLAT_FRACTION` of its travel). Accepted but reported in ``notes``: readings clipped into the
    limits (counted in ``clipped``), columns mapped by name from another order, columns that are not tendons,
    a BOM, another delimiter, a decimal comma, milliseconds.

    ``exclude`` names columns that are never tendons (motion-capture markers). ``motion_checks=False`` skips
    the stuck-channel and flat-recording checks: in a recording with markers the tendon columns are the
    commands sent, where a held command is no stuck sensor and a still trunk is data (its sag).
    """
    table = parse.read_table(path, len(limits), time_column, columns, reference, exclude)
    raise_if_any(checks.check_row_count(table))
    values, clipped = checks.clip_noise(table, limits, tolerance)
    raise_if_any(
        checks.check_time_increases(table)
        + checks.check_time_gaps(table)
        + checks.check_limits(table, limits, tolerance)
        + (
            checks.check_flat(table, values, limits) + checks.check_stuck(table, values, limits)
            if motion_checks
            else []
        )
    )
    notes = list(table.notes)
    if clipped:
        notes.append(
            f"{sum(clipped.values())} reading(s) just outside the limits clipped (within the tolerance of "
            f"{100 * tolerance:g}% of the travel): " + ", ".join(f"{c} {n}" for c, n in clipped.items())
        )
    return Recording(
        time=table.time,
        values=values,
        columns=tuple(table.columns),
        notes=tuple(notes),
        clipped=clipped,
        median_dt=checks.median_step(table),
        lines=tuple(table.lines),
        time_column=table.time_column,
    )


def read_recording(path, limits, time_column: str | None = None, tolerance: float = checks.TOLERANCE) -> Recording:
    """:func:`inspect_recording` (kept for the first interface): raises a ``DemonstrationError``
    naming every problem of the file."""
    return inspect_recording(path, limits, time_column, tolerance=tolerance)
