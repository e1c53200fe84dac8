"""The database: every table on SQLite and on a real PostgreSQL server, progress read back from committed rows
alone, ratings checked against where a participant is, and the CSV / Parquet export with its dictionary."""

from __future__ import annotations

import pytest

SQLALCHEMY = pytest.importorskip(
    "sqlalchemy", reason="the study's database needs sqlalchemy (requirements.txt pins it)"
)
from jgrounding.study import Store, StudyError  # noqa: E402 (after the skip: the store imports sqlalchemy)


def _play(store, pid, position, condition, episode, executed=True):
    eid = store.record_execution(
        pid, position, condition, episode, source="hold", seed=7, num_steps=150, start_tick=3, planned_sha256="a" * 64
    )
    if executed:
        store.complete_execution(eid, "a" * 64)
    return eid


def test_a_participant_walks_through_the_blocks(db_url, design):
    store = Store(db_url)
    sid = store.open_session(design)
    first, second = store.enrol(sid), store.enrol(sid)
    assert first["order"] == ["av_only", "scripted"] and second["order"] == ["scripted", "av_only"]
    assert first["participant"].startswith("P001-") and second["number"] == 1
    pid = first["participant"]
    assert store.progress(pid)["phase"] == "episode" and store.progress(pid)["episode"] == 0
    with pytest.raises(StudyError, match="not open for ratings"):
        store.add_rating(pid, 0, "naturalness", 4)
    _play(store, pid, 0, "av_only", 0)
    _play(store, pid, 0, "av_only", 1, executed=False)  # planned, never finished: does not count
    assert store.progress(pid)["episode"] == 1
    _play(store, pid, 0, "av_only", 1)
    prog = store.progress(pid)
    assert prog["phase"] == "questionnaire" and prog["missing"] == list(design.dimensions)
    for v, dim in enumerate(design.dimensions):
        store.add_rating(pid, 0, dim, 1 + v % 5)
    store.add_rating(pid, 0, "naturalness", 5)  # a changed answer: a new row, the latest counts
    assert store.progress(pid)["condition"] == "scripted"
    with pytest.raises(StudyError, match="1..5"):
        store.add_rating(pid, 0, "naturalness", 6)
    with pytest.raises(StudyError, match="unknown dimension"):
        store.add_rating(pid, 0, "beauty", 3)
    for e in range(2):
        _play(store, pid, 1, "scripted", e)
    for dim in design.dimensions:
        store.add_rating(pid, 1, dim, 4)
    assert store.progress(pid)["phase"] == "done" and store.participant(pid)["status"] == "complete"
    rows = store.long_ratings(sid)
    assert len(rows) == 12 and len(store.table("ratings")) == 13
    nat = [r for r in rows if r["dimension"] == "naturalness" and r["position"] == 0]
    assert [r["value"] for r in nat] == [5] and nat[0]["positive"] == 1 and nat[0]["condition"] == "av_only"
    store.set_status(second["participant"], "withdrawn")
    assert store.progress(second["participant"])["phase"] == "withdrawn"
    store.close()


def test_a_reopened_database_resumes_and_a_changed_design_is_a_new_session(db_url, design):
    import dataclasses

    store = Store(db_url)
    sid = store.open_session(design)
    pid = store.enrol(sid)["participant"]
    _play(store, pid, 0, "av_only", 0)
    store.close()
    again = Store(db_url)
    assert again.open_session(design) == sid and again.progress(pid)["episode"] == 1
    assert again.open_session(dataclasses.replace(design, seed=1)) != sid
    again.close()


def test_sqlite_runs_in_wal_mode(tmp_path, design):
    import sqlalchemy as sa

    store = Store(tmp_path / "s.db")
    store.open_session(design)
    with store.engine.connect() as c:
        assert c.execute(sa.text("PRAGMA journal_mode")).scalar() == "wal"
        assert c.execute(sa.text("PRAGMA synchronous")).scalar() == 2  # FULL


def test_export_writes_csv_parquet_and_the_dictionary(tmp_path, design):
    import csv

    pq = pytest.importorskip("pyarrow.parquet", reason="the Parquet export needs pyarrow (requirements.txt pins it)")

    from jgrounding.study.export import DICTIONARY, export

    store = Store(tmp_path / "s.db")
    sid = store.open_session(design)
    pid = store.enrol(sid)["participant"]
    for e in range(2):
        _play(store, pid, 0, "av_only", e)
    for dim in design.dimensions:
        store.add_rating(pid, 0, dim, 4)
    paths = {p.name for p in export(store, tmp_path / "out", sid)}
    assert {"ratings.csv", "ratings.parquet", "ratings_long.parquet", "data_dictionary.md"} <= paths
    long = pq.read_table(tmp_path / "out" / "ratings_long.parquet")
    assert long.column_names == list(DICTIONARY["ratings_long"]) and long.num_rows == 6
    assert set(long.column("positive").to_pylist()) == {1}
    assert str(long.schema.field("rated_at").type) == "timestamp[us, tz=UTC]"
    with open(tmp_path / "out" / "executions.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 and rows[0]["planned_sha256"] == rows[0]["executed_sha256"]
    assert rows[0]["planned_at"].endswith("Z")
    text = (tmp_path / "out" / "data_dictionary.md").read_text()
    assert all(f"| {c} |" in text for cols in DICTIONARY.values() for c in cols)


def test_analyze_excludes_withdrawn_participants_only_when_asked(tmp_path, design, capsys):
    import json

    from jgrounding.study.__main__ import main

    store = Store(tmp_path / "s.db")
    sid = store.open_session(design)
    pids = [store.enrol(sid)["participant"] for _ in range(3)]
    for k, pid in enumerate(pids):
        for position, condition in enumerate(store.participant(pid)["order"]):
            for e in range(2):
                _play(store, pid, position, condition, e)
            for dim in design.dimensions:
                store.add_rating(pid, position, dim, 2 + k)
            if k == 2:  # the third leaves after the first block and is withdrawn by the operator
                store.set_status(pid, "withdrawn")
                break
    store.close()
    for flag, participants in (([], 3), (["--exclude-withdrawn"], 2)):
        out = tmp_path / f"analysis{len(flag)}"
        assert main(["analyze", str(tmp_path / "s.db"), "--out", str(out), *flag]) == 0
        report = json.loads((out / "report.json").read_text())
        assert report["participants"] == participants and report["withdrawn"] == [pids[2]]
        assert report["withdrawn_excluded"] == bool(flag)
        first = {(r["condition"], r["dimension"]): r for r in report["descriptive"]}[("av_only", "naturalness")]
        assert first["n"] == participants and first["positive"] == (participants == 3)  # only P003 rated 4
    assert "(1 withdrawn, excluded)" in capsys.readouterr().out
