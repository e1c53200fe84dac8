"""Importing recorded demonstrations (issue #18): every bad-data case with its message, N_u != 4, card."""

import json

import numpy as np
import pytest

from jgrounding import load_library
from jgrounding.actuation import splines
from jgrounding.library import importer
from jgrounding.library.importer import DemonstrationError, ImportConfig, import_folder

TUPLES = (("nodding", "moderate"), ("greeting", "emphatic"))


def smooth_motion(rng, num_tendons, rows=120):
    """A smooth recording in [0, 1]: a reconstruction of random controls (no screening failure)."""
    c = rng.uniform(0.3, 0.7, (num_tendons, 4))
    return np.asarray(splines.reconstruct(c, num_steps=rows), np.float64)


def write_folder(path, num_tendons=4, realizations=3, limits=(2.0, 12.0), rows=120, seed=0, manifest="csv"):
    """A folder of ``len(TUPLES) * realizations`` CSV recordings in 'mm' with a manifest."""
    rng = np.random.default_rng(seed)
    path.mkdir(parents=True, exist_ok=True)
    entries = []
    for name, level in TUPLES:
        for r in range(realizations):
            x = limits[0] + smooth_motion(rng, num_tendons, rows) * (limits[1] - limits[0])
            t = np.arange(rows) * 0.04
            lines = ["time," + ",".join(f"pull_{j}" for j in range(num_tendons))]
            lines += [f"{ti:.3f}," + ",".join(f"{v:.5f}" for v in row) for ti, row in zip(t, x)]
            file = f"{name}_{level}_{r}.csv"
            (path / file).write_text("\n".join(lines) + "\n")
            entries.append((file, name, level, f"say it {r}"))
    if manifest == "csv":
        (path / "manifest.csv").write_text(
            "file,intent,intensity,texts\n" + "".join(f"{f},{m},{z},{t}\n" for f, m, z, t in entries)
        )
    else:
        (path / "manifest.json").write_text(
            json.dumps(
                {"demonstrations": [{"file": f, "intent": m, "intensity": z, "texts": [t]} for f, m, z, t in entries]}
            )
        )
    return path


def config(num_tendons=4, **kw):
    return ImportConfig(limits=((2.0, 12.0),) * num_tendons, **kw)


def edit_line(path, line, new):
    """Replace 1-based line ``line`` of a text file."""
    lines = path.read_text().splitlines()
    lines[line - 1] = new
    path.write_text("\n".join(lines) + "\n")


def test_clean_folder_imports_with_a_balanced_split_and_card(tmp_path):
    arrays, card = import_folder(write_folder(tmp_path / "rec"), config())
    assert arrays["u"].shape == (6, 150, 4) and arrays["controls"].shape == (6, 4, 4)
    assert 0.0 <= arrays["u"].min() and arrays["u"].max() <= 1.0
    assert card["counts_per_tuple"] == {
        "nodding/moderate": {"train": 2, "heldout": 1},
        "greeting/emphatic": {"train": 2, "heldout": 1},
    }
    assert set(card["sources_sha256"]) == {f"{m}_{z}_{r}" + ".csv" for m, z in TUPLES for r in range(3)}
    assert card["rejected"] == [] and card["dropped"] == []
    assert any("--simulate" in s for s in card["screening"])  # 4 tendons, not simulated: the card says so


def test_units_are_mapped_from_the_declared_limits(tmp_path):
    folder = write_folder(tmp_path / "rec", realizations=2)
    arrays, _ = import_folder(folder, config())
    rec = importer.read_recording(folder / "nodding_moderate_0.csv", ((2.0, 12.0),) * 4)
    first = (rec.values[0] - 2.0) / 10.0  # slack 2 mm -> 0, full pull 12 mm -> 1
    row = np.flatnonzero(arrays["source"] == "nodding_moderate_0.csv")[0]
    np.testing.assert_allclose(arrays["u"][row, 0], first, atol=1e-6)
    reversed_limits = importer.normalize(np.array([[12.0, 2.0]]), ((12.0, 2.0), (12.0, 2.0)))
    np.testing.assert_allclose(reversed_limits, [[0.0, 1.0]])  # slack may be the larger reading


def test_library_loads_and_cli_writes_npz_and_card(tmp_path, capsys):
    folder = write_folder(tmp_path / "rec", manifest="json")
    out = tmp_path / "my_library.npz"
    assert (
        importer.main(
            ["import", str(folder), "--out", str(out), "--limits", "2:12", "--tendons", "4", "--controls", "5"]
        )
        == 0
    )
    lib = load_library(out)
    assert len(lib.train) == 4 and len(lib.heldout) == 2 and lib.train.controls.shape[1:] == (4, 5)
    assert lib.meta["reduced"] and lib.meta["num_tendons"] == 4
    assert "wrote" in capsys.readouterr().out and not list(tmp_path.glob(".*tmp"))


@pytest.mark.parametrize(
    "case, edit, match",
    [
        ("nan", lambda p: edit_line(p, 5, "0.160,nan,5,5,5"), r"nodding_moderate_0.csv line 5, column 'pull_0': NaN"),
        ("inf", lambda p: edit_line(p, 7, "0.240,5,5,inf,5"), r"line 7, column 'pull_2': Inf"),
        ("empty", lambda p: edit_line(p, 9, "0.320,5,,5,5"), r"line 9, column 'pull_1': empty value"),
        ("duplicate time", lambda p: edit_line(p, 4, "0.040,5,5,5,5"), r"line 4, column 'time': duplicate time stamp"),
        ("time backwards", lambda p: edit_line(p, 6, "0.100,5,5,5,5"), r"line 6, column 'time': time goes backwards"),
        (
            "too short",
            lambda p: p.write_text("time,a,b,c,d\n" + "".join(f"{i},5,5,5,5\n" for i in range(4))),
            r"nodding_moderate_0.csv: only 4 data row\(s\); at least 10",
        ),
        (
            "columns",
            lambda p: p.write_text("time,a,b,c\n" + "".join(f"{i},5,5,5\n" for i in range(20))),
            r"line 1: tendon columns \['a', 'b', 'c'\] do not match \['pull_0', 'pull_1', 'pull_2', 'pull_3'\] "
            r"\(the tendon columns of nodding_moderate_1.csv, in the order of the limits\)",
        ),
        (
            "limits",
            lambda p: edit_line(p, 8, "0.240,5,12.5,5,5"),
            r"line 8, column 'pull_1': value 12.5 is outside the declared limits \[2, 12\]",
        ),
        ("ragged", lambda p: edit_line(p, 3, "0.040,5,5"), r"line 3: 3 cells, but the header has 5"),
    ],
)
def test_bad_recording_names_file_line_and_column(tmp_path, case, edit, match):
    folder = write_folder(tmp_path / "rec")
    edit(folder / "nodding_moderate_0.csv")
    with pytest.raises(DemonstrationError, match=match):
        import_folder(folder, config())


@pytest.mark.parametrize(
    "field, value, match",
    [
        (
            "intent",
            "waving",
            r"manifest.csv line 2, column 'intent': nodding_moderate_0.csv: unknown intent 'waving'; "
            r"valid intents: greeting, farewell",
        ),
        (
            "intensity",
            "huge",
            r"line 2, column 'intensity': .*unknown intensity 'huge'; valid intensities: subtle, "
            r"moderate, pronounced, emphatic",
        ),
    ],
)
def test_unknown_labels_list_the_valid_ones(tmp_path, field, value, match):
    folder = write_folder(tmp_path / "rec")
    text = (
        (folder / "manifest.csv")
        .read_text()
        .replace(
            "nodding_moderate_0.csv,nodding,moderate",
            "nodding_moderate_0.csv,waving,moderate" if field == "intent" else "nodding_moderate_0.csv,nodding,huge",
        )
    )
    (folder / "manifest.csv").write_text(text)
    with pytest.raises(DemonstrationError, match=match):
        import_folder(folder, config())


def test_json_manifest_rows_are_entries(tmp_path):
    folder = write_folder(tmp_path / "rec", manifest="json")
    doc = json.loads((folder / "manifest.json").read_text())
    doc["demonstrations"][3]["intent"] = "hugging"
    (folder / "manifest.json").write_text(json.dumps(doc))
    with pytest.raises(DemonstrationError, match=r"manifest.json entry 4, column 'intent': .*unknown intent 'hugging'"):
        import_folder(folder, config())


def test_tuple_with_too_few_realizations_for_the_split(tmp_path):
    folder = write_folder(tmp_path / "rec", realizations=1)
    with pytest.raises(
        DemonstrationError,
        match=r"manifest.csv line 3: tuple greeting/emphatic has 1 valid "
        r"realization\(s\) \(greeting_emphatic_0.csv\); the train/held-out "
        r"split needs at least 2",
    ):
        import_folder(folder, config())


def test_screening_rejection_is_named_in_the_split_error(tmp_path):
    folder = write_folder(tmp_path / "rec", realizations=2)
    rng = np.random.default_rng(1)  # sensor noise: third differences far above the smoothness bound
    x = 2.0 + 10.0 * np.clip(0.5 + 0.05 * rng.standard_normal((120, 4)), 0, 1)
    (folder / "greeting_emphatic_1.csv").write_text(
        "time,pull_0,pull_1,pull_2,pull_3\n"
        + "".join(f"{0.04 * i:.3f}," + ",".join(f"{v:.4f}" for v in row) + "\n" for i, row in enumerate(x))
    )
    with pytest.raises(DemonstrationError, match=r"rejected by screening: greeting_emphatic_1.csv \(.*smooth\)"):
        import_folder(folder, config())


def test_drop_invalid_keeps_going_and_lists_everything_dropped(tmp_path, capsys):
    folder = write_folder(tmp_path / "rec")
    edit_line(folder / "nodding_moderate_0.csv", 5, "0.160,nan,5,5,5")
    edit_line(folder / "nodding_moderate_1.csv", 4, "0.040,5,5,5,5")
    (folder / "manifest.csv").write_text((folder / "manifest.csv").read_text() + "ghost.csv,nodding,subtle,\n")
    out = tmp_path / "lib.npz"
    argv = ["import", str(folder), "--out", str(out), "--limits", "2:12", "--tendons", "4", "--drop-invalid"]
    assert importer.main(argv) == 1  # 4 of 7 files left out: more than the default --max-dropped 0.2
    err = capsys.readouterr().err
    assert "4 of 7 file(s) not imported (57%" in err and "more than --max-dropped 0.2 (20%)" in err
    assert "nodding_moderate_0.csv line 5, column 'pull_0': NaN" in err and not out.exists()
    assert importer.main(argv + ["--max-dropped", "0.6"]) == 0
    card = json.loads(out.with_suffix(".json").read_text())
    reasons = [d["reason"] for d in card["dropped"]]
    assert len(reasons) == 4  # NaN, duplicate stamp, missing file, and then nodding/moderate has one left
    assert any("NaN" in r for r in reasons) and any("duplicate" in r for r in reasons)
    assert any("file not found" in r for r in reasons) and any("tuple nodding/moderate" in r for r in reasons)
    assert card["counts_per_tuple"] == {"greeting/emphatic": {"train": 2, "heldout": 1}}
    printed = capsys.readouterr().out
    assert printed.count("dropped:") == 4 and "nodding_moderate_0.csv line 5, column 'pull_0'" in printed


def test_three_tendons_import_without_physics(tmp_path):
    arrays, card = import_folder(write_folder(tmp_path / "rec", num_tendons=3), config(3, num_controls=4))
    assert arrays["u"].shape == (6, 150, 3) and arrays["controls"].shape == (6, 3, 4)
    assert card["num_tendons"] == 3
    assert any("4-tendon trunk, these data have N_u = 3" in s for s in card["screening"])
    with pytest.raises(ValueError, match="--simulate screens on the built-in 4-tendon trunk; these data declare 3"):
        import_folder(tmp_path / "rec", config(3, simulate=True))


def test_cli_refuses_missing_or_conflicting_limits(tmp_path, capsys):
    folder = write_folder(tmp_path / "rec")
    with pytest.raises(SystemExit):
        importer.main(["import", str(folder), "--out", str(tmp_path / "x.npz")])
    assert "declare each tendon's limits" in capsys.readouterr().err
    # three pairs declare N_u = 3, and the files have 4 tendon columns
    assert importer.main(["import", str(folder), "--out", str(tmp_path / "x.npz"), "--limits", "0:12,0:12,0:12"]) == 1
    assert "4 tendon column(s) ['pull_0', 'pull_1', 'pull_2', 'pull_3'], but 3 tendon limits" in capsys.readouterr().err


@pytest.mark.parametrize("fmt", ["csv", "json"])
def test_command_stream_round_trip_export_import_reconstruct(tmp_path, fmt):
    """export -> import -> reconstruct gives the exported trajectory back (6-digit files: ~1e-6)."""
    from jgrounding.apps import export
    from jgrounding.io import write_atomic

    rng = np.random.default_rng(3)
    folder = tmp_path / "streams"
    controls, rows = {}, ["file,intent,intensity"]
    for r in range(2):
        c = rng.uniform(0.3, 0.7, (4, 4)).astype(np.float32)  # R(c) is inside [0, 1] and within the slew bound
        u = np.asarray(splines.reconstruct(c))
        write = export.command_stream_csv if fmt == "csv" else export.command_stream_json
        meta = export.tuple_meta(9, 1)
        write_atomic(folder / f"commands_{r}.{fmt}", write(u, control_dt=1 / 30, meta=meta))
        controls[f"commands_{r}.{fmt}"] = c
        rows.append(f"commands_{r}.{fmt},nodding,moderate")
    (folder / "manifest.csv").write_text("\n".join(rows) + "\n")
    arrays, card = import_folder(folder, ImportConfig(limits=((0.0, 1.0),) * 4, num_controls=4))
    for i, file in enumerate(arrays["source"]):
        c = controls[str(file)]
        np.testing.assert_allclose(arrays["controls"][i], c, atol=1e-5)
        np.testing.assert_allclose(arrays["u"][i], np.asarray(splines.reconstruct(c)), atol=1e-5)
    assert card["rejected"] == []


def test_module_entry_point_imports_a_folder(tmp_path):
    """``python -m jgrounding.library import DIR --out ...`` as a user types it."""
    import subprocess
    import sys

    folder = write_folder(tmp_path / "rec", num_tendons=6, manifest="json")
    out = tmp_path / "six.npz"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "jgrounding.library",
            "import",
            str(folder),
            "--out",
            str(out),
            "--limits",
            "2:12",
            "--tendons",
            "6",
            "--controls",
            "5",
        ],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stderr
    assert (
        "N_u = 6" in res.stdout
        and "the built-in simulator is the 4-tendon trunk, these data have N_u = 6" in res.stdout
    )
    lib = load_library(out)
    assert lib.train.u.shape == (4, 150, 6) and lib.train.controls.shape == (4, 6, 5)
