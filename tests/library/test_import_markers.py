"""The importer with motion-capture markers (jgrounding.library.importer.markers): a folder with markers imports
as before and its card names the markers; the marker checks run in the import too; commands-only folders are
untouched; and a manifest row with an unquoted comma and a misspelt intent shows both faults in one run."""

import json

import numpy as np
import pytest
from test_importer import smooth_motion, write_folder

from jgrounding.library.importer import ImportConfig, ImportProblems, import_folder
from jgrounding.library.importer.markers import MAX_MARKER_GAP_S, MIN_DURATION_S, marker_map
from jgrounding.sim.recordings import Recording, write_recordings

S = np.array([0.35, 0.70])


def mocap_folder(path, seed=0):
    """Six recordings (two tuples x three realizations) of smooth commands with two markers, in mm."""
    rng = np.random.default_rng(seed)
    recs = []
    for m, z in (("nodding", "moderate"), ("greeting", "emphatic")):
        for r in range(3):
            u = smooth_motion(rng, 4, rows=240)
            t = np.arange(240) / 120
            markers = np.stack([0.1 * u[:, :1] * S, 0.1 * u[:, 1:2] * S, np.broadcast_to(1.10 - S, (240, 2))], axis=-1)
            recs.append(Recording(f"{m}_{z}_{r}", t, u, markers, ("mid", "tip"), S, m, z))
    return write_recordings(path, recs)


def test_a_folder_with_markers_imports_and_its_card_names_the_markers(tmp_path):
    folder = mocap_folder(tmp_path / "mocap")
    arrays, card = import_folder(folder, ImportConfig(limits=((0.0, 1.0),) * 4))
    assert arrays["u"].shape == (6, 150, 4) and card["channels"] == ["u0", "u1", "u2", "u3"]
    assert card["markers"] == {"names": ["mid", "tip"], "s_m": [0.35, 0.7], "units": "mm", "max_gap_s": 0.05}
    assert card["notes"] == {}  # the marker columns are not reported as ignored tendon columns


def test_the_import_runs_the_marker_checks_with_the_others(tmp_path):
    folder = mocap_folder(tmp_path / "mocap")
    path = folder / "greeting_emphatic_1.csv"
    lines = path.read_text().splitlines()
    for k in range(100, 120):  # 20 samples of the mid marker lost: 0.175 s
        cells = lines[k].split(",")
        cells[5] = "NaN"
        lines[k] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ImportProblems) as info:
        import_folder(folder, ImportConfig(limits=((0.0, 1.0),) * 4))
    [p] = info.value.problems
    assert p.file.endswith("greeting_emphatic_1.csv") and p.line == 101 and p.column == "mid_x"
    assert "longer than max_marker_gap_s" in p.reason and "delete manifest.json entry 5" in p.fix


def test_commands_only_folders_import_as_before(tmp_path):
    arrays, card = import_folder(write_folder(tmp_path / "rec"), ImportConfig(limits=((2.0, 12.0),) * 4))
    assert arrays["u"].shape == (6, 150, 4) and card["markers"] is None


def test_the_marker_map_is_checked_as_a_whole():
    good = {"markers": [{"name": "tip", "s": "tip", "columns": ["a", "b", "c"]}], "marker_units": "m"}
    mmap, problems = marker_map(good, "manifest.json")
    assert problems == [] and mmap.s[0] == 0.70 and mmap.max_gap_s == MAX_MARKER_GAP_S and MIN_DURATION_S == 1.0
    bad = {
        "markers": [
            {"name": "tip", "s": -1, "columns": ["a", "b"]},
            {"name": "tip", "s": 0.3, "columns": ["a_mm", "e", "f"]},
        ],
        "marker_units": "m",
        "max_marker_gap_s": "long",
    }
    mmap, problems = marker_map(bad, "manifest.json")
    reasons = [p.reason for p in problems]
    assert mmap is None and len(problems) == 5, reasons
    assert "max_marker_gap_s is 'long'" in reasons[0]
    assert "s = -1 is not an arc length" in reasons[1] and "are not three column names" in reasons[2]
    assert "marker name 'tip' used twice" in reasons[3] and "column 'a_mm' says mm" in reasons[4]
    _, problems = marker_map({"marker_units": "mm"}, "manifest.json")
    assert "marker_units given but no markers declared" in problems[0].reason


def test_a_row_with_an_unquoted_comma_and_a_misspelt_intent_shows_both_faults(tmp_path):
    folder = write_folder(tmp_path / "rec")
    manifest = folder / "manifest.csv"
    lines = manifest.read_text().splitlines()
    lines[2] = "nodding_moderate_1.csv,noding,moderate,Yes, I agree"
    manifest.write_text("\n".join(lines) + "\n")
    with pytest.raises(ImportProblems) as info:
        import_folder(folder, ImportConfig(limits=((2.0, 12.0),) * 4))
    on_line = [p for p in info.value.problems if p.line == 3]
    assert len(on_line) == 2, [str(p) for p in info.value.problems]
    assert "5 cells, but the header has 4" in on_line[0].reason and "unquoted ','" in on_line[0].reason
    assert "unknown intent 'noding'" in on_line[1].reason and on_line[1].column == "intent"
    assert json.loads(json.dumps([p.as_dict() for p in on_line]))[1]["line"] == 3


def test_the_shipped_reference_example_imports_from_the_command_line(tmp_path):
    from experiments.trunk_reference import EXAMPLE, verify
    from jgrounding.library.importer import main

    assert verify(EXAMPLE) == []  # the files are those the reference wrote (trunk_reference.sha256)
    out = tmp_path / "lib.npz"
    assert main(["import", str(EXAMPLE), "--out", str(out)]) == 0
    card = json.loads(out.with_suffix(".json").read_text())
    assert card["markers"]["names"] == ["quarter", "mid", "three_quarter", "tip"] and card["num_records"] == 16
