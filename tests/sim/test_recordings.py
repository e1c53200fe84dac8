"""Recordings with motion capture (jgrounding.sim.recordings): the writer and the reader agree, and every fault
of a folder (its manifest's marker map, each file's marker columns, gaps, units, length) is reported in one
error with its file, line and column."""

import json

import numpy as np
import pytest

from jgrounding.sim.recordings import Recording, RecordingsError, load_recordings, write_recordings

HZ = 120
NAMES = ("mid", "tip")
S = np.array([0.35, 0.70])


def recording(name="nodding_0", seconds=2.0, intent="nodding", intensity="moderate", seed=0) -> Recording:
    """A smooth synthetic recording: commands in [0, 1], markers swinging around the hanging backbone."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * HZ)) / HZ
    phase = rng.uniform(0, 2 * np.pi, 4)
    u = 0.5 + 0.3 * np.sin(2 * np.pi * 0.5 * t[:, None] + phase)
    swing = 0.05 * np.sin(2 * np.pi * 0.7 * t)[:, None] * S[None, :] / S[-1]
    markers = np.stack([swing, 0.5 * swing, np.broadcast_to(1.10 - S, swing.shape)], axis=-1)
    return Recording(name, t, u, markers, NAMES, S, intent, intensity)


@pytest.fixture
def folder(tmp_path):
    recs = [recording(f"nodding_{i}", seed=i) for i in range(3)]
    return write_recordings(tmp_path / "recs", recs), recs


def _edit_manifest(folder, **fields):
    path = folder / "manifest.json"
    doc = json.loads(path.read_text())
    doc.update(fields)
    path.write_text(json.dumps(doc))


def _set_cells(path, rows, columns, text="NaN"):
    """Replace the cells of ``columns`` on data ``rows`` (0-based, below the header) of a CSV with ``text``."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    for r in rows:
        cells = lines[r + 1].split(",")
        for c in columns:
            cells[header.index(c)] = text
        lines[r + 1] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


def _problems(folder):
    with pytest.raises(RecordingsError) as info:
        load_recordings(folder)
    return info.value.problems


def test_written_recordings_read_back_the_same(folder):
    path, recs = folder
    back = load_recordings(path)
    assert [r.name for r in back] == [r.name for r in recs]
    for a, b in zip(back, recs):
        assert a.t[0] == 0.0 and np.allclose(a.t, b.t, atol=1e-6)
        assert np.allclose(a.u, b.u, atol=1e-6)
        assert np.allclose(a.markers, b.markers, atol=1e-5)  # written in mm with 4 decimals
        assert a.marker_names == NAMES and np.allclose(a.marker_s, S)
        assert (a.intent, a.intensity) == ("nodding", "moderate") and a.markers.shape == (len(a.t), 2, 3)
    # written again: the folder is replaced whole, no temporary folder left beside it
    write_recordings(path, recs[:1], marker_units="m")
    assert [r.name for r in load_recordings(path)] == ["nodding_0"]
    assert sorted(p.name for p in path.parent.iterdir()) == ["recs"]


def test_the_writer_rejects_what_it_cannot_write(tmp_path):
    r = recording()
    with pytest.raises(ValueError, match="marker_units"):
        write_recordings(tmp_path / "a", [r], marker_units="cm")
    with pytest.raises(ValueError, match="repeated"):
        write_recordings(tmp_path / "a", [r, r])
    bad = Recording("b", r.t, r.u[:-1], r.markers, NAMES, S, "nodding", "moderate")
    with pytest.raises(ValueError, match="do not agree"):
        write_recordings(tmp_path / "a", [r, bad])
    assert not (tmp_path / "a").exists()


def test_a_short_marker_gap_is_interpolated_a_long_one_rejects_the_recording(folder):
    path, recs = folder
    tip = ["tip_x", "tip_y", "tip_z"]
    _set_cells(path / "nodding_0.csv", range(50, 53), tip)  # 3 samples: 0.033 s between valid ones
    _set_cells(path / "nodding_1.csv", range(50, 56), ["tip_x"], text="")  # 6 samples: 0.058 s > 0.05 s
    [p] = _problems(path)
    assert p.file.endswith("nodding_1.csv") and p.line == 52 and p.column == "tip_x"
    assert "missing for 0.0583 s (lines 52-57), longer than max_marker_gap_s = 0.05 s" in p.reason
    assert "delete manifest.json entry 2" in p.fix
    _edit_manifest(path, max_marker_gap_s=0.1)
    back = load_recordings(path)
    assert np.allclose(back[0].markers, recs[0].markers, atol=2e-4)  # a smooth path, filled linearly
    assert np.isfinite(back[1].markers).all()


def test_a_marker_map_that_does_not_match_the_columns_is_an_error(folder):
    path, _ = folder
    doc = json.loads((path / "manifest.json").read_text())
    doc["markers"][1]["columns"] = ["tip_x", "tip_y", "tipz"]
    (path / "manifest.json").write_text(json.dumps(doc))
    found = _problems(path)
    assert len(found) == 3 and all(p.line == 1 and p.column == "tipz" for p in found)
    assert "marker columns ['tipz'] of the manifest's marker map are not in the file" in found[0].reason
    doc["markers"] = doc["markers"][:1]  # the tip's columns are there but no longer mapped
    (path / "manifest.json").write_text(json.dumps(doc))
    found = _problems(path)
    assert len(found) == 3 and all(
        "marker columns of ['tip'] are not in the manifest's marker map" in p.reason for p in found
    )


def test_mixed_units_are_an_error(folder):
    path, _ = folder
    doc = json.loads((path / "manifest.json").read_text())
    doc["markers"][0]["units"] = "m"  # one marker says metres, the map millimetres
    doc["markers"][1]["columns"] = ["tip_x_m", "tip_y", "tip_z"]
    (path / "manifest.json").write_text(json.dumps(doc))
    found = _problems(path)
    reasons = " | ".join(p.reason for p in found)
    assert "marker 'mid' declares units 'm' but marker_units is 'mm'" in reasons
    assert "column 'tip_x_m' says m but marker_units is 'mm'" in reasons
    assert all(p.column.startswith("markers[") for p in found)
    # values in millimetres in a map declared in metres: the file, line and column of the largest
    _edit_manifest(path, marker_units="m")
    doc = json.loads((path / "manifest.json").read_text())
    del doc["markers"][0]["units"]
    doc["markers"][1]["columns"] = ["tip_x", "tip_y", "tip_z"]
    (path / "manifest.json").write_text(json.dumps(doc))
    found = _problems(path)
    assert len(found) == 3 and all("mixed units: a marker value of" in p.reason for p in found)
    assert all(p.column in ("mid_z", "tip_z") and p.line is not None for p in found)


def test_a_recording_shorter_than_the_minimum_is_rejected(tmp_path):
    path = write_recordings(tmp_path / "r", [recording("a", seconds=2.0), recording("b", seconds=0.5)])
    [p] = _problems(path)
    assert p.file.endswith("b.csv") and "too short: 0.492 s" in p.reason and "at least 1 s" in p.reason


def test_every_fault_of_the_folder_is_reported_in_one_run(folder):
    path, _ = folder
    doc = json.loads((path / "manifest.json").read_text())
    doc["demonstrations"][0]["intent"] = "noding"
    (path / "manifest.json").write_text(json.dumps(doc))
    _set_cells(path / "nodding_1.csv", range(10, 30), ["mid_y"])  # a long gap
    _set_cells(path / "nodding_2.csv", [5], ["u2"], text="abc")  # a bad command cell
    _set_cells(path / "nodding_2.csv", [7], ["tip_z"], text="inf")  # a bad marker cell
    found = _problems(path)
    where = sorted((p.file.rsplit("/", 1)[-1], p.line, p.column) for p in found)
    assert where == [
        ("manifest.json", 1, "intent"),
        ("nodding_1.csv", 12, "mid_y"),
        ("nodding_2.csv", 7, "u2"),
    ]  # the bad command cell stops the reading of that file before its markers
    assert "unknown intent 'noding'" in str(found[0]) or any("noding" in p.reason for p in found)


def test_a_folder_without_markers_is_not_a_calibration_recording(tmp_path, folder):
    path, _ = folder
    doc = json.loads((path / "manifest.json").read_text())
    for k in ("markers", "marker_units", "max_marker_gap_s"):
        del doc[k]
    (path / "manifest.json").write_text(json.dumps(doc))
    [p] = _problems(path)
    assert "no motion-capture markers declared" in p.reason and p.column == "markers"


def test_a_broken_marker_map_does_not_hide_the_files_faults(folder):
    path, _ = folder
    doc = json.loads((path / "manifest.json").read_text())
    doc["markers"][0]["units"] = "m"  # the mid marker is refused; the tip is still checked in every file
    (path / "manifest.json").write_text(json.dumps(doc))
    _set_cells(path / "nodding_2.csv", range(50, 60), ["tip_y"])
    found = _problems(path)
    assert [(p.file.rsplit("/", 1)[-1], p.column) for p in found] == [
        ("manifest.json", "markers[0].units"),
        ("nodding_2.csv", "tip_y"),
    ]
