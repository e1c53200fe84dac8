"""The import of a folder, in order: :func:`import_folder`.

1. read the manifest (:mod:`~jgrounding.library.importer.manifest`) and pick the reference file whose
   tendon columns name the tendons (the first listed CSV with one column per declared limit);
2. read and check every listed file (:func:`~jgrounding.library.importer.recording.inspect_recording`),
   also those whose manifest row is bad, then the folder's checks (one time unit, realization ids);
3. map to [0, 1], resample to T = 150, optionally reduce by Eq. (ci), and screen;
4. check that every tuple can be split, then split it into train / held-out realizations;
5. assemble the arrays and the card (:mod:`~jgrounding.library.importer.card`).

Every problem of steps 1-4 lands in one report (``ImportProblems``), or with ``drop_invalid`` in the
card's ``dropped``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from jgrounding import safety
from jgrounding.actuation import splines
from jgrounding.config import NUM_STEPS  # T of Table I
from jgrounding.library import screening
from jgrounding.library.importer import card as cards
from jgrounding.library.importer import checks, markers, parse
from jgrounding.library.importer.errors import DemonstrationError, ImportProblems, TooManyDropped, problems_of
from jgrounding.library.importer.manifest import Manifest, find_manifest, read_manifest, tuple_name
from jgrounding.library.importer.recording import Recording, inspect_recording

MAX_DROPPED = 0.2  # --drop-invalid fails (exit 1, nothing written) when more than 20% of the files are dropped
TRUNK_TENDONS = cards.TRUNK_TENDONS


@dataclasses.dataclass(frozen=True)
class ImportConfig:
    limits: tuple[tuple[float, float], ...]  # per tendon (slack, full pull) in the lab's units; len = N_u
    num_controls: int | None = None  # --controls P: reduce by Eq. (ci); None keeps the resampled recording
    simulate: bool = False  # screen on the built-in 4-tendon trunk too (data recorded for our trunk model)
    heldout_per_tuple: int = 1  # held-out realizations per tuple (the rest train)
    seed: int = 0  # which realizations are held out
    time_column: str | None = None  # None: the first of TIME_COLUMNS in the header
    drop_invalid: bool = False  # drop bad files (listed) instead of stopping
    tolerance: float = checks.TOLERANCE  # readings this fraction of the travel outside the limits are clipped
    max_dropped: float = MAX_DROPPED  # --drop-invalid fails when more than this fraction of files is dropped
    columns: tuple[str, ...] | None = None  # tendon column names in the order of the limits (None: the first file's)

    @property
    def num_tendons(self) -> int:
        return len(self.limits)


def normalize(values: np.ndarray, limits) -> np.ndarray:
    """Lab units ``(..., N_u)`` -> [0, 1] per tendon: slack -> 0, full pull -> 1 (either order)."""
    lim = np.asarray(limits, np.float64)
    return (values - lim[:, 0]) / (lim[:, 1] - lim[:, 0])


def resample(time: np.ndarray, values: np.ndarray, num_steps: int = NUM_STEPS) -> np.ndarray:
    """Linear interpolation of ``(n, N_u)`` onto ``num_steps`` uniform times over [time[0], time[-1]]."""
    grid = np.linspace(time[0], time[-1], num_steps)
    return np.stack([np.interp(grid, time, values[:, j]) for j in range(values.shape[1])], axis=-1)


def _reduce(x: np.ndarray, num_controls: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(controls ``(B, N_u, P)``, raw ``(B, T, N_u)``, u ``(B, T, N_u)``) of resampled recordings ``x``.

    With ``num_controls`` the expert trajectory is ``u = make_safe(R(c))``, ``c`` by Eq. (ci), as in the
    built-in library; without it ``u`` is the recording itself (screened, never clamped) and ``c`` its
    Eq. (ci) controls at P = 4 for the spline methods.
    """
    c = np.asarray(splines.fit(x.astype(np.float32), num_controls=num_controls or splines.NUM_CONTROLS))
    if num_controls is None:
        u = x.astype(np.float32)
        return c, u, u
    raw = np.asarray(splines.reconstruct(c, num_steps=x.shape[1]))
    return c, raw, np.asarray(safety.make_safe(raw), np.float32)


def _reference(
    man: Manifest, folder: Path, config: ImportConfig, exclude=()
) -> tuple[tuple[str, ...] | None, str | None]:
    """(the tendon columns' names in the order of the limits, the file they come from): the config's or the
    manifest's ``columns``, else those of the first listed CSV with one tendon column per declared limit."""
    named = config.columns or (tuple(man.fields["columns"]) if man.fields.get("columns") else None)
    if named:
        if len(named) != config.num_tendons:
            raise ValueError(f"{len(named)} tendon columns {list(named)} named for {config.num_tendons} tendon limits")
        return tuple(named), None if config.columns else f"{man.path.name} 'columns'"
    for row in man.rows:
        if row.file is not None:
            found = parse.tendon_candidates(folder / row.file, config.time_column, exclude)
            if found is not None and len(found) == config.num_tendons:
                return found, row.file
    return None, None


def _read_all(
    man: Manifest, folder: Path, config: ImportConfig, problems: list, mmap=None
) -> tuple[list, list[Recording]]:
    """(the valid manifest entries, their recordings): every listed file read and checked (its marker columns
    too, with the marker map ``mmap``), then the folder's checks; every problem on the way appended to
    ``problems``, in manifest order."""
    unit, rows = man.unit, man.rows
    exclude = markers.declared_columns(man.fields)
    columns, reference = _reference(man, folder, config, exclude)
    twice = checks.check_listed_once(rows, man.path, unit)
    recs: dict[int, Recording] = {}
    for i, row in enumerate(rows):
        problems.extend(row.problems)
        if i in twice:
            problems.append(twice[i])
            continue
        if row.file is None:
            continue
        leave_out = f"or leave the file out: delete {man.path.name} {unit} {row.line}"
        try:
            rec = inspect_recording(
                folder / row.file,
                config.limits,
                config.time_column,
                tolerance=config.tolerance,
                columns=columns,
                reference=reference,
                exclude=exclude,
                motion_checks=not exclude,
            )
        except DemonstrationError as err:
            problems.extend(p.with_fix(leave_out) for p in problems_of(err))
            continue
        if mmap is not None:
            _, notes, bad = markers.read_markers(folder / row.file, mmap, rec.time, rec.lines)
            problems.extend(p.with_fix(leave_out) for p in bad)
            if bad:
                continue
            rec = dataclasses.replace(rec, notes=rec.notes + tuple(notes))
        if not exclude or mmap is not None:
            recs[i] = rec
    off = checks.check_time_units(recs, rows, folder, man.path, unit)
    problems.extend(off.values())
    entries = {i: rows[i].entry for i in recs if rows[i].entry is not None and i not in off}
    ids = checks.check_realization_ids(entries, man.path, unit, tuple_name)
    problems.extend(ids.values())
    kept = [i for i in entries if i not in ids]
    return [entries[i] for i in kept], [recs[i] for i in kept]


def _realizations(by_tuple: dict, kept: list) -> dict[int, int]:
    """Each valid recording's realization id: the manifest's, else the smallest free one of its tuple."""
    realization = {}
    for idx in by_tuple.values():
        given = [kept[i].realization for i in idx if kept[i].realization is not None]
        free = (r for r in range(len(idx) + len(given) + 1) if r not in given)
        for i in idx:
            realization[i] = kept[i].realization if kept[i].realization is not None else next(free)
    return realization


def _split(by_tuple: dict, realization: dict, config: ImportConfig) -> tuple[list[int], list[bool]]:
    """(recordings in library order: by tuple, then realization id; held out or not), the held-out ones
    drawn by ``config.seed`` per tuple."""
    order, heldout = [], []
    for key in sorted(by_tuple):
        idx = sorted(by_tuple[key], key=lambda i: realization[i])
        held = np.random.default_rng([config.seed, *key]).choice(len(idx), config.heldout_per_tuple, replace=False)
        order += idx
        heldout += [k in set(held.tolist()) for k in range(len(idx))]
    return order, heldout


def import_folder(folder, config: ImportConfig, manifest=None) -> tuple[dict, dict]:
    """Read, validate, normalize, resample, (reduce,) screen and split a folder of demonstrations.

    Returns ``(arrays, card)`` for :func:`jgrounding.library.save`: arrays ``u (N, 150, N_u)``,
    ``controls (N, N_u, P)``, ``intent``, ``intensity``, ``realization``, ``heldout``, ``texts``, ``source``.
    Raises ``ImportProblems`` with every problem of the manifest and the recordings (or, with
    ``config.drop_invalid``, lists them in ``card["dropped"]`` and goes on; ``TooManyDropped`` past
    ``config.max_dropped``) and ``ValueError`` for an impossible configuration.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise DemonstrationError(folder, "not a folder")
    manifest = Path(manifest) if manifest else find_manifest(folder)
    if config.simulate and config.num_tendons != TRUNK_TENDONS:
        raise ValueError(
            f"--simulate screens on the built-in {TRUNK_TENDONS}-tendon trunk; these data declare "
            f"{config.num_tendons} tendons (physics screening is only for data recorded on our trunk model)"
        )
    man = read_manifest(manifest)
    num_files = len(man.rows)
    mmap, bad_map = markers.marker_map(man.fields, man.path)
    problems: list[DemonstrationError] = list(man.problems) + bad_map
    kept, recs = _read_all(man, folder, config, problems, mmap)
    if not kept:
        if problems and not config.drop_invalid:
            raise ImportProblems(problems, num_files)
        raise DemonstrationError(
            manifest,
            "no valid demonstration to import" + (f" ({len(problems)} problem(s))" if problems else ""),
            fix="fix the files listed above",
        )
    x = np.stack([resample(r.time, normalize(r.values, config.limits)) for r in recs])  # (B, T, N_u)
    controls, raw, u = _reduce(x, config.num_controls)
    intent = np.array([e.intent for e in kept], np.int32)
    screened = screening.screen(
        raw, u, intent, simulate=config.simulate, intensity=np.array([e.intensity for e in kept], np.int32)
    )
    names = [c for c in screening.CHECKS if c in screened]
    rejected = [
        {"file": e.file, "failed": [c for c in names if not screened[c][i]]}
        for i, e in enumerate(kept)
        if not screened["accepted"][i]
    ]
    by_tuple: dict[tuple[int, int], list[int]] = {}
    for i, e in enumerate(kept):
        if screened["accepted"][i]:
            by_tuple.setdefault((e.intent, e.intensity), []).append(i)
    realization = _realizations(by_tuple, kept)
    short = checks.check_split_sizes(
        by_tuple, dict(enumerate(kept)), rejected, config.heldout_per_tuple, manifest, man.unit, tuple_name
    )
    problems.extend(short.values())
    for key in short:
        del by_tuple[key]
    if problems and not config.drop_invalid:
        raise ImportProblems(problems, num_files)
    if not by_tuple:
        raise DemonstrationError(manifest, "no tuple has enough valid realizations for the split")
    order, heldout = _split(by_tuple, realization, config)
    left_out = num_files - len(order)
    num_dropped = left_out - len(rejected)  # files left out for their problems (those rejected by screening aside)
    if config.drop_invalid and left_out > config.max_dropped * num_files:
        raise TooManyDropped(
            problems,
            rejected,
            f"{left_out} of {num_files} file(s) not imported ({100 * left_out / num_files:.0f}%: "
            f"{num_dropped} with problems, {len(rejected)} rejected by screening), more than "
            f"--max-dropped {config.max_dropped:g} ({100 * config.max_dropped:g}%); nothing was written",
            manifest,
        )
    arrays = cards.arrays(kept, order, heldout, realization, u, controls, intent)
    card = cards.card(
        arrays,
        config=config,
        kept=kept,
        recs=recs,
        order=order,
        screening_names=names,
        rejected=rejected,
        dropped=problems,
        num_dropped=num_dropped,
        folder=folder,
        manifest=manifest,
        marker_map=mmap,
    )
    return arrays, card
