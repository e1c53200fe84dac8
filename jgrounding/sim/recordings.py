"""Recordings of a trunk with motion capture: what calibration fits and the physical reference writes.

A recordings folder is the importer's format (``docs/own_data.md``: a JSON manifest and one CSV per
recording with a time column and one column per tendon in the lab's units) with motion-capture marker
columns in the same CSVs, on the same clock (100-120 Hz). The manifest declares the markers
(:mod:`jgrounding.library.importer.markers`)::

    {"limits": [[0, 1], [0, 1], [0, 1], [0, 1]], "columns": ["u0", "u1", "u2", "u3"], "time_column": "time",
     "markers": [{"name": "mid", "s": 0.35, "columns": ["mid_x", "mid_y", "mid_z"]},
                 {"name": "tip", "s": 0.70, "columns": ["tip_x", "tip_y", "tip_z"]}],
     "marker_units": "mm", "max_marker_gap_s": 0.05,
     "demonstrations": [{"file": "nodding_moderate_0.csv", "intent": "nodding", "intensity": "moderate"}, ...]}

``s`` is the arc length from the base along the undeformed backbone in metres. Positions are in the world
frame of ``jgrounding/assets/trunk.xml``: the base at ``(0, 0, BASE_HEIGHT)`` = (0, 0, 1.10) m, z up, gravity
along -z, the trunk hanging from the base along -z at rest, tendon 0 toward +x (the user).

:func:`load_recordings` reads and checks a folder with the importer's checks plus the marker checks, and
raises one error that lists every problem (file, line, column, fix). :func:`write_recordings` writes the
format atomically.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from jgrounding.io import write_atomic
from jgrounding.library.importer import markers
from jgrounding.library.importer.errors import DemonstrationError, ImportProblems, problems_of
from jgrounding.library.importer.manifest import check_limits, find_manifest, read_manifest
from jgrounding.library.importer.parse import tendon_candidates
from jgrounding.library.importer.recording import inspect_recording
from jgrounding.vocabulary import INTENSITIES, INTENTS

MAX_MARKER_GAP_S = markers.MAX_MARKER_GAP_S
MIN_DURATION_S = markers.MIN_DURATION_S


@dataclasses.dataclass(frozen=True)
class Recording:
    """One recording: commands and marker positions on one clock."""

    name: str
    t: np.ndarray  # (T,) seconds from 0
    u: np.ndarray  # (T, N_u) commands mapped to [0, 1]
    markers: np.ndarray  # (T, M, 3) metres, gaps filled
    marker_names: tuple[str, ...]
    marker_s: np.ndarray  # (M,) metres, arc length from the base along the undeformed backbone
    intent: str
    intensity: str


class RecordingsError(ImportProblems):
    """Every problem of a recordings folder, one per line, each with its file, line, column and fix, and a
    summary line."""

    def __init__(self, problems, files: int | None = None):
        super().__init__(problems)
        bad = len({p.file for p in self.problems})
        listed = f" ({files} listed in the manifest)" if files is not None else ""
        self.args = (self.args[0] + f"\n{len(self.problems)} problem(s) in {bad} file(s){listed}",)


def _limits(limits, fields: dict, manifest: Path):
    if limits is not None:
        return check_limits(limits, "limits")
    if "limits" in fields:
        return check_limits(fields["limits"], manifest)
    raise DemonstrationError(
        manifest,
        "no tendon limits: declare them in the manifest",
        column="limits",
        fix='add "limits": [[slack, full_pull], ...], one pair per tendon column in the file\'s units',
    )


def load_recordings(folder, *, limits=None) -> list[Recording]:
    """Every recording of ``folder`` (manifest order), checked: the manifest, the tendon columns (as the importer
    checks them, but for the stuck-channel and flat checks: these are commands) and the markers (the map, the
    columns, gaps up to ``max_marker_gap_s`` interpolated, at least :data:`MIN_DURATION_S` long, one unit).

    Args:
      folder: the recordings folder (``manifest.json`` with a marker map, one CSV per recording).
      limits: per-tendon ``[(slack, full_pull), ...]`` in the files' units; default the manifest's ``limits``.

    Returns: the recordings. Raises :class:`RecordingsError` listing every problem of the folder.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise DemonstrationError(folder, "not a folder", fix="pass the folder that holds manifest.json and the CSVs")
    man = read_manifest(find_manifest(folder))
    problems = list(man.problems)
    try:
        limits = _limits(limits, man.fields, man.path)
    except ValueError as e:
        raise RecordingsError([e if isinstance(e, DemonstrationError) else DemonstrationError(man.path, str(e))])
    mmap, bad = markers.marker_map(man.fields, man.path)
    problems += bad
    if mmap is None and not bad:
        problems.append(
            DemonstrationError(
                man.path,
                "no motion-capture markers declared: calibration needs marker positions",
                column="markers",
                fix='declare them: "markers": [{"name": "tip", "s": 0.70, "columns": ["tip_x", "tip_y", "tip_z"]}], '
                '"marker_units": "mm"',
            )
        )
    exclude = markers.declared_columns(man.fields)
    columns = tuple(man.fields["columns"]) if man.fields.get("columns") else None
    reference = f"{man.path.name} 'columns'" if columns else None
    if columns is None:
        for row in man.rows:
            found = row.file and tendon_candidates(folder / row.file, man.fields.get("time_column"), exclude)
            if found and len(found) == len(limits):
                columns, reference = found, row.file
                break
    out = []
    for row in man.rows:
        problems += row.problems
        if row.file is None:
            continue
        leave_out = f"or leave the file out: delete {man.path.name} {man.unit} {row.line}"
        try:
            rec = inspect_recording(
                folder / row.file,
                limits,
                man.fields.get("time_column"),
                columns=columns,
                reference=reference,
                exclude=exclude,
                motion_checks=False,
            )
        except DemonstrationError as err:
            problems += [p.with_fix(leave_out) for p in problems_of(err)]
            continue
        if mmap is None:
            continue
        pos, _, bad = markers.read_markers(folder / row.file, mmap, rec.time, rec.lines)
        problems += [p.with_fix(leave_out) for p in bad]
        if bad or row.entry is None:
            continue
        lim = np.asarray(limits, np.float64)
        u = np.clip((rec.values - lim[:, 0]) / (lim[:, 1] - lim[:, 0]), 0.0, 1.0)
        out.append(
            Recording(
                name=Path(row.file).stem,
                t=rec.time - rec.time[0],
                u=u,
                markers=pos,
                marker_names=mmap.names,
                marker_s=mmap.s,
                intent=INTENTS[row.entry.intent],
                intensity=INTENSITIES[row.entry.intensity],
            )
        )
    if problems:
        raise RecordingsError(problems, len(man.rows))
    if not out:
        raise RecordingsError([DemonstrationError(man.path, "no recording listed", fix="list the recordings")])
    return out


def _check(recordings) -> None:
    if not recordings:
        raise ValueError("no recordings to write")
    first = recordings[0]
    names = set()
    for r in recordings:
        T = len(r.t)
        if r.u.shape[0] != T or r.markers.shape != (T, len(first.marker_names), 3) or r.u.shape[1] != first.u.shape[1]:
            raise ValueError(
                f"recording {r.name!r}: t {np.shape(r.t)}, u {np.shape(r.u)} and markers {np.shape(r.markers)} do "
                f"not agree with (T,), (T, {first.u.shape[1]}), (T, {len(first.marker_names)}, 3)"
            )
        if r.marker_names != first.marker_names or not np.allclose(r.marker_s, first.marker_s):
            raise ValueError(f"recording {r.name!r}: its markers differ from {first.name!r}'s (one map per folder)")
        if r.name in names or not r.name or os.sep in r.name:
            raise ValueError(f"recording name {r.name!r} is empty, repeated or a path")
        names.add(r.name)


def _csv(r: Recording, scale: float, digits: int) -> str:
    head = ["time"] + [f"u{j}" for j in range(r.u.shape[1])]
    head += [f"{n}_{a}" for n in r.marker_names for a in "xyz"]
    lines = [",".join(head)]
    pos = r.markers.reshape(len(r.t), -1) / scale
    for i in range(len(r.t)):
        cells = [f"{r.t[i]:.6f}"] + [f"{x:.6f}" for x in r.u[i]] + [f"{x:.{digits}f}" for x in pos[i]]
        lines.append(",".join(cells).replace("nan", "NaN"))
    return "\n".join(lines) + "\n"


def write_recordings(
    folder, recordings, *, marker_units: str = "mm", max_marker_gap_s: float = MAX_MARKER_GAP_S, extra=None
) -> Path:
    """Write ``recordings`` as a recordings folder (one CSV each, ``manifest.json``), atomically: the folder
    is built beside ``folder`` and moved into place whole (an existing folder is replaced).

    Commands are written as ``u0..u{N-1}`` in [0, 1] (limits ``[0, 1]``), markers as ``{name}_x/_y/_z`` in
    ``marker_units`` (``"mm"``: 0.1 um steps, ``"m"``: 1e-7 m). ``extra``: more fields for the manifest
    (e.g. the source of the recordings). Returns the folder.
    """
    if marker_units not in markers.MARKER_UNITS:
        raise ValueError(f"marker_units must be one of {', '.join(markers.MARKER_UNITS)}, got {marker_units!r}")
    recordings = list(recordings)
    _check(recordings)
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    first = recordings[0]
    n_u = first.u.shape[1]
    manifest = {
        "limits": [[0.0, 1.0]] * n_u,
        "columns": [f"u{j}" for j in range(n_u)],
        "time_column": "time",
        "markers": [
            {"name": n, "s": round(float(s), 6), "columns": [f"{n}_{a}" for a in "xyz"]}
            for n, s in zip(first.marker_names, first.marker_s)
        ],
        "marker_units": marker_units,
        "max_marker_gap_s": max_marker_gap_s,
        **(extra or {}),
        "demonstrations": [{"file": f"{r.name}.csv", "intent": r.intent, "intensity": r.intensity} for r in recordings],
    }
    scale, digits = markers.MARKER_UNITS[marker_units], 4 if marker_units == "mm" else 7
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        for r in recordings:
            write_atomic(tmp / f"{r.name}.csv", _csv(r, scale, digits))
        write_atomic(tmp / "manifest.json", json.dumps(manifest, indent=1) + "\n")
        os.chmod(tmp, 0o777 & ~_umask())
        old = None
        if folder.exists():
            old = folder.parent / f".{folder.name}.old-{os.getpid()}"
            os.replace(folder, old)
        os.replace(tmp, folder)
        if old is not None:
            shutil.rmtree(old)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
