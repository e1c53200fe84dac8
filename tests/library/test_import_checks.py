"""The importer's checks one by one, and the defects of issue #33 item 6: manifest and recording problems in
one report, columns that are not tendons ignored with a note, a missing column named with its fix, a fix for
an unknown label, ``--drop-invalid`` counting files."""

import json

import numpy as np
import pytest
from test_importer import edit_line, write_folder

from jgrounding.library import importer
from jgrounding.library.importer import ImportConfig, ImportProblems, checks, import_folder
from jgrounding.library.importer.parse import Table
from jgrounding.vocabulary import INTENSITIES, INTENTS

LIMITS = ((2.0, 12.0),) * 4


def config(**kw):
    return ImportConfig(limits=LIMITS, **kw)


def table(time, values, columns=("a", "b")):
    """A :class:`Table` of ``time (n,)`` and ``values (n, N_u)``, row i on file line i + 2."""
    values = np.asarray(values, np.float64).reshape(len(time), -1)
    lines = tuple(range(2, len(time) + 2))
    return Table("rec.csv", np.asarray(time, np.float64), values, columns, lines, "time", "line", ())


def problems(folder, **kw) -> list:
    with pytest.raises(ImportProblems) as info:
        import_folder(folder, config(**kw))
    return info.value.problems


def add_column(folder, name, cell):
    """Append a column ``name`` (header) with ``cell`` in every row to each recording of ``folder``."""
    for path in folder.glob("*_*_*.csv"):
        lines = path.read_text().splitlines()
        path.write_text("\n".join([lines[0] + name] + [ln + cell for ln in lines[1:]]) + "\n")


# ---------------------------------------------------------------- one check each


def test_time_checks_find_a_duplicate_stamp_and_a_gap():
    t = np.arange(20) * 0.1
    assert checks.check_time_increases(table(t, np.zeros((20, 2)))) == []
    dup = t.copy()
    dup[5] = dup[4]
    [p] = checks.check_time_increases(table(dup, np.zeros((20, 2))))
    assert "duplicate time stamp: 0.4 at line 6" in p.reason and p.line == 7 and p.column == "time"
    gap = t.copy()
    gap[10:] += 2.0  # 2.1 s between rows 9 and 10: 21 x the median step of 0.1 s
    [p] = checks.check_time_gaps(table(gap, np.zeros((20, 2))))
    assert "gap in time: 0.9 s at line 11, then 3 s" in p.reason and p.line == 12
    assert checks.check_time_gaps(table(dup, np.zeros((20, 2)))) == []  # no gap check on time that repeats


def test_limits_check_and_the_noise_clipping_share_one_tolerance():
    t = np.arange(12) * 0.1
    x = np.full((12, 2), 7.0)
    x[3, 0], x[4, 1] = 12.05, 12.5  # 0.5% and 5% of the travel of 10 above full pull
    rec = table(t, x)
    [p] = checks.check_limits(rec, ((2.0, 12.0),) * 2)
    assert p.column == "b" and p.line == 6 and "value 12.5 is outside the declared limits [2, 12]" in p.reason
    values, clipped = checks.clip_noise(rec, ((2.0, 12.0),) * 2)
    assert clipped == {"a": 1} and values[3, 0] == 12.0 and values[4, 1] == 12.5  # b is an error: left as read


def test_flat_and_stuck_recordings():
    t = np.arange(400) * 0.01
    moving = 7.0 + 4.0 * np.sin(t)
    flat = table(t, np.stack([np.full(400, 7.0), np.full(400, 7.1)], -1))
    assert "flat recording" in checks.check_flat(flat, flat.values, ((2.0, 12.0),) * 2)[0].reason
    stuck = np.stack([moving, np.where((t > 1.0) & (t < 3.0), 9.0, moving)], -1)
    rec = table(t, stuck)
    [p] = checks.check_stuck(rec, rec.values, ((2.0, 12.0),) * 2)
    assert p.column == "b" and "stuck channel: reads exactly 9" in p.reason and "while 'a' moves" in p.reason
    ok = table(t, np.stack([moving, moving[::-1]], -1))
    assert checks.check_flat(ok, ok.values, ((2.0, 12.0),) * 2) == []
    assert checks.check_stuck(ok, ok.values, ((2.0, 12.0),) * 2) == []


def test_row_count():
    assert "only 4 data row(s)" in checks.check_row_count(table(np.arange(4.0), np.zeros((4, 2))))[0].reason
    assert checks.check_row_count(table(np.arange(10.0), np.zeros((10, 2)))) == []


# ---------------------------------------------------------------- issue #33's defects


def test_manifest_and_recording_problems_come_in_one_report(tmp_path):
    folder = write_folder(tmp_path / "rec")
    manifest = folder / "manifest.csv"
    manifest.write_text(manifest.read_text().replace("nodding_moderate_1.csv,nodding", "nodding_moderate_1.csv,waving"))
    edit_line(folder / "nodding_moderate_1.csv", 6, "0.200,nan,5,5,5")  # the file of the bad row
    edit_line(folder / "greeting_emphatic_0.csv", 5, "0.160,5,5,inf,5")
    found = problems(folder)
    assert [(p.file.rsplit("/", 1)[-1], p.line, p.column) for p in found] == [
        ("manifest.csv", 3, "intent"),
        ("nodding_moderate_1.csv", 6, "pull_0"),
        ("greeting_emphatic_0.csv", 5, "pull_2"),
    ]
    assert "delete manifest.csv line 3" in found[1].fix


def test_a_manifest_header_problem_does_not_hide_the_recordings(tmp_path, capsys):
    folder = write_folder(tmp_path / "rec")
    manifest = folder / "manifest.csv"
    manifest.write_text(manifest.read_text().replace("file,intent,intensity", "file,intent,level"))
    edit_line(folder / "greeting_emphatic_0.csv", 5, "0.160,nan,5,5,5")
    argv = ["import", str(folder), "--out", str(tmp_path / "x.npz"), "--limits", "2:12", "--tendons", "4"]
    assert importer.main(argv) == 1  # an error of the run (exit 1), not a usage error that stops before it
    err = capsys.readouterr().err
    assert "manifest.csv line 1: manifest header ['file', 'intent', 'level', 'texts'] lacks ['intensity']" in err
    assert "greeting_emphatic_0.csv line 5, column 'pull_0': NaN value" in err
    assert "2 problem(s) in 2 file(s) (6 listed in the manifest)" in err


def test_a_repeated_realization_id_joins_the_report(tmp_path):
    folder = write_folder(tmp_path / "rec")
    manifest = folder / "manifest.csv"
    rows = manifest.read_text().splitlines()
    rows = [rows[0] + ",realization"] + [r + ",0" for r in rows[1:]]  # every realization id 0
    manifest.write_text("\n".join(rows) + "\n")
    edit_line(folder / "greeting_emphatic_2.csv", 5, "0.160,nan,5,5,5")
    found = problems(folder)
    ids = [p for p in found if p.column == "realization"]
    assert [p.line for p in ids] == [3, 4, 6]  # line 7's file has a NaN: not a valid entry
    assert "tuple nodding/moderate: realization id 0 used more than once (lines 2, 3)" in ids[0].reason
    assert any("NaN" in p.reason for p in found) and all(p.fix for p in found)


@pytest.mark.parametrize(
    "header, cell, note",
    [
        (",status", ",ok", "column 'status' holds no numbers: not a tendon, ignored"),
        (",", ",", "column 6 (no name; a trailing delimiter?) holds no values: not a tendon, ignored"),
    ],
)
def test_columns_that_are_not_tendons_are_ignored_with_a_note(tmp_path, header, cell, note):
    clean, _ = import_folder(write_folder(tmp_path / "clean"), config())
    folder = write_folder(tmp_path / "rec")
    add_column(folder, header, cell)
    arrays, card = import_folder(folder, config())
    assert card["notes"]["nodding_moderate_0.csv"] == [note]
    np.testing.assert_array_equal(arrays["u"], clean["u"])  # the same library as without the column


def test_a_column_not_named_as_a_tendon_is_ignored_in_a_later_file(tmp_path):
    folder = write_folder(tmp_path / "rec")
    path = folder / "greeting_emphatic_1.csv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join([lines[0] + ",temp_C"] + [ln + ",21.5" for ln in lines[1:]]) + "\n")
    _, card = import_folder(folder, config())
    assert card["notes"]["greeting_emphatic_1.csv"] == [
        "column(s) ['temp_C'] not among the tendon columns ['pull_0', 'pull_1', 'pull_2', 'pull_3']: ignored"
    ]


def test_a_missing_column_is_named_and_its_fix_keeps_the_count(tmp_path):
    folder = write_folder(tmp_path / "rec")
    path = folder / "nodding_moderate_1.csv"
    path.write_text("\n".join(",".join(ln.split(",")[:4]) for ln in path.read_text().splitlines()) + "\n")
    [p] = problems(folder)
    assert p.line == 1 and "(the tendon columns of nodding_moderate_0.csv" in p.reason
    assert p.reason.endswith("['pull_3'] missing")
    assert p.fix.startswith("add the column 'pull_3': every file needs the 4 tendon columns")
    assert "slack:full" not in p.fix  # the declared limits are right; the file lacks a column


def test_a_renamed_column_gets_the_rename_as_its_fix(tmp_path):
    folder = write_folder(tmp_path / "rec")
    path = folder / "greeting_emphatic_0.csv"
    path.write_text(path.read_text().replace("pull_3", "pull_D", 1))
    [p] = problems(folder)
    assert p.fix.startswith("rename this file's columns to the same names (case does not matter): 'pull_D' -> 'pull_3'")


@pytest.mark.parametrize(
    "old, new, column, valid",
    [
        ("nodding_moderate_0.csv,nodding,", "nodding_moderate_0.csv,waving,", "intent", INTENTS),
        (",nodding,moderate,say it 0", ",nodding,huge,say it 0", "intensity", INTENSITIES),
    ],
)
def test_an_unknown_label_gets_a_fix_that_lists_the_valid_ones(tmp_path, old, new, column, valid):
    folder = write_folder(tmp_path / "rec")
    manifest = folder / "manifest.csv"
    manifest.write_text(manifest.read_text().replace(old, new))
    [p] = problems(folder)
    assert p.column == column and p.fix == f"write one of the valid {column}s: {', '.join(valid)}"


def test_drop_invalid_counts_files_not_problems(tmp_path, capsys):
    folder = write_folder(tmp_path / "rec", realizations=4)
    path = folder / "greeting_emphatic_0.csv"
    for line, text in [(5, "0.160,nan,5,5,5"), (9, "0.320,5,,5,5"), (12, "0.440,5,5,inf,5"), (14, "0.520,5,5,5,x")]:
        edit_line(path, line, text)
    out = tmp_path / "lib.npz"
    argv = ["import", str(folder), "--out", str(out), "--limits", "2:12", "--tendons", "4", "--drop-invalid"]
    assert importer.main(argv) == 0
    printed = capsys.readouterr().out
    card = json.loads(out.with_suffix(".json").read_text())
    assert len(card["dropped"]) == 4 and printed.count("dropped: ") == 4  # every problem listed
    assert card["num_dropped"] == 1 and "0 rejected, 1 file(s) dropped;" in printed  # one file left out
