"""A lab's messy recordings (issue #26), written by tools/make_messy_recordings: imported in one run, every
problem reported with file, line and fix, noisy-but-valid files accepted with a clipping report, nothing
wrong accepted silently."""

import json

import numpy as np
import pytest

from jgrounding.library import importer
from jgrounding.library.importer import DemonstrationError, ImportConfig, ImportProblems, import_folder
from tools import make_messy_recordings as messy

LIMITS = tuple(messy.LIMITS_DEG)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return messy.write(tmp_path_factory.mktemp("messy") / "recordings")


def test_strict_run_reports_every_problem_with_file_line_and_fix(folder, tmp_path, capsys):
    out = tmp_path / "lib.npz"
    argv = ["import", str(folder), "--out", str(out), "--limits", messy.LIMITS_FLAG, "--controls", "4"]
    assert importer.main(argv) == 1 and not out.exists()
    err = capsys.readouterr().err
    expected = [  # (file, line, what, fix)
        ("nodding_moderate_4.csv", "line 202, column 'Motor_B_deg'", "stuck channel", "delete manifest.csv line 5"),
        ("nodding_emphatic_3.csv", "line 403, column 'Elapsed_s'", "gap in time: 2 s", "split the file at the gap"),
        ("greeting_moderate_4.csv", "line 2", "flat recording", "delete manifest.csv line 13"),
        ("manifest.csv", "line 14", "7 cells, but the header has 5", '"Hello there, so good to see you!|'),
        ("greeting_moderate_1.csv", "line 3, column 'Elapsed_s'", "time looks like milliseconds", "name it time_ms"),
    ]
    lines = [ln for ln in err.splitlines() if ln.startswith("error: ") and "Fix: " in ln]
    for file, where, what, fix in expected:
        hits = [ln for ln in lines if f"{file} {where}" in ln and what in ln and fix in ln]
        assert len(hits) == 1, (file, err)
    assert "5 problem(s) in 5 file(s) (16 listed in the manifest); nothing was written" in err
    assert len(lines) == 5  # nothing else is wrong: the accepted oddities are not errors


def test_noisy_but_valid_files_are_accepted_with_a_clipping_report(folder, tmp_path, capsys):
    out = tmp_path / "lib.npz"
    argv = ["import", str(folder), "--out", str(out), "--limits", messy.LIMITS_FLAG, "--controls", "4"]
    assert importer.main(argv + ["--drop-invalid"]) == 1  # 5 of 16 left out: over the default 20%
    assert "5 of 16 file(s) not imported (31%" in capsys.readouterr().err and not out.exists()
    assert importer.main(argv + ["--drop-invalid", "--max-dropped", "0.35"]) == 0
    printed = capsys.readouterr().out
    card = json.loads(out.with_suffix(".json").read_text())
    imported = set(card["sources_sha256"])
    assert imported == {f"{m}_{z}_{r}.csv" for m, z in messy.TUPLES for r in range(1, 5)} - set(messy.REFUSED)
    assert card["num_records"] == 11 and len(card["dropped"]) == 5 and card["rejected"] == []
    assert {d["file"].rsplit("/", 1)[-1] for d in card["dropped"]} == set(messy.REFUSED) - {
        "greeting_emphatic_1.csv"
    } | {"manifest.csv"}
    clipped = sum(sum(c.values()) for c in card["clipped"].values())
    assert clipped > 0 and f"{clipped} reading(s) in {len(card['clipped'])} file(s) clipped" in printed
    notes = card["notes"]
    assert "mapped by name" in notes["nodding_moderate_2.csv"][0]
    assert "byte-order mark" in notes["nodding_moderate_3.csv"][0]
    assert "decimal comma read" in notes["nodding_emphatic_1.csv"][0]
    assert card["channels"] == list(messy.MOTORS)
    assert max(card["durations_s"].values()) < 6.0  # every duration in seconds


def test_columns_are_mapped_by_name_and_the_reversed_motor_by_its_limits(folder):
    ref = importer.inspect_recording(folder / "nodding_moderate_1.csv", LIMITS)
    other = importer.inspect_recording(folder / "nodding_moderate_2.csv", LIMITS, columns=ref.columns)
    assert other.columns == ref.columns
    raw = np.genfromtxt(folder / "nodding_moderate_2.csv", delimiter=",", names=True)
    np.testing.assert_allclose(other.values[:, 1], np.clip(raw["Motor_B_deg"], 0, 540))  # B from its own column
    u = importer.normalize(ref.values, LIMITS)
    assert 0.0 <= u.min() and u.max() <= 1.0  # motor C: 540 deg = slack -> 0


@pytest.mark.parametrize(
    "name, text, match",
    [
        (
            "renamed",
            "Elapsed_s,Motor_A_deg,Motor_B_deg,Motor_C_deg,Motor_X_deg\n",
            r"line 1: tendon columns .* do not match .*\['Motor_D_deg'\] missing\. Fix: rename",
        ),
        ("bom", "\ufeffelapsed_S,motor_a_DEG,Motor_B_deg,Motor_C_deg,Motor_D_deg\n", None),
        (
            "decimal comma with commas",
            None,
            r"line 2: 10 cells, but the header has 5 \(decimal commas with ',' between cells\?\) \(1023 rows in all\)",
        ),
    ],
)
def test_header_spellings(folder, tmp_path, name, text, match):
    src = (folder / "nodding_moderate_1.csv").read_text().splitlines()
    if text is None:  # a decimal comma and ',' between cells: ambiguous, named in the error
        body = [src[0]] + [ln.replace(".", ",") for ln in src[1:]]
    else:
        body = [text.rstrip("\n")] + src[1:]
    path = tmp_path / f"{name}.csv"
    path.write_text("\n".join(body) + "\n")
    if match is None:
        rec = importer.inspect_recording(path, LIMITS, columns=messy.MOTORS)  # any case, BOM skipped
        assert rec.values.shape[1] == 4 and rec.time_column == "elapsed_S"
    else:
        with pytest.raises(DemonstrationError, match=match):
            importer.inspect_recording(path, LIMITS, columns=messy.MOTORS)


def test_tolerance_is_configurable_and_beyond_it_is_an_error(folder):
    files = folder / "nodding_emphatic_2.csv"
    assert importer.inspect_recording(files, LIMITS).clipped  # within 1% of the travel: clipped, counted
    with pytest.raises(ImportProblems, match=r"outside the declared limits .* up to 0% is clipped"):
        importer.inspect_recording(files, LIMITS, tolerance=0.0)


def test_api_strict_mode_lists_every_problem(folder):
    with pytest.raises(ImportProblems) as info:
        import_folder(folder, ImportConfig(limits=LIMITS, num_controls=4))
    assert len(info.value.problems) == 5 and all(p.fix for p in info.value.problems)
