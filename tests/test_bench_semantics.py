"""bench semantics' goal rows: each of #24's goals is checked, and every shortfall says what was tried."""

import pytest

from experiments import bench_semantics as bench
from experiments import bench_semantics_scores as scores


def _results(situation=0.96, ece=0.02, median=4.0):
    row = {
        "n_motion": 10,
        "intent": 0.97,
        "confident_wrong": 0.0,
        "none_held": 0.95,
        "exact": 0.8,
        "within_one": 0.99,
        "ece": ece,
    }
    res = {
        ("new", "v2 test", "all"): row,
        ("new", "v2 test", "terse"): row,
        ("new", "v2 test", "situation"): dict(row, intent=situation),
        ("new", "v2 test", "quoted"): dict(row, n_motion=0, intent=None),
        ("new", "plain test", "all"): row,
        ("old", "plain test", "all"): dict(row, intent=0.9),
    }
    latency = {"new": {"ms_median": median, "ms_p99": 9.0}}
    return res, latency, [0.7, 0.8, 0.9]


def test_every_goal_is_a_row_and_all_met_means_no_shortfall():
    rows = scores.goal_rows(*_results())
    assert {key for key, *_ in rows} == set(scores.GOALS) | {"plain"}
    assert all(ok for _, _, ok, _ in rows)
    assert scores.shortfalls(rows) == []


def test_a_shortfall_names_its_measure_and_what_was_tried():
    rows = scores.goal_rows(*_results(situation=0.904, median=5.4))
    missed = {key: measured for key, _, ok, measured in rows if not ok}
    assert missed == {
        "intent": "lowest style 0.904",
        "ms_median": "5.40 ms",
    }  # a no-motion style is not a style minimum
    tried = scores.shortfalls(rows)
    assert len(tried) == 2 and "docs/how_it_works.md" in tried[0] and "float16" in tried[1]


def test_a_new_shortfall_says_nothing_was_tried_yet():
    rows = scores.goal_rows(*_results(ece=0.2))
    assert scores.shortfalls(rows) == ["ECE <= 0.05: nothing tried yet (a new shortfall)"]


def test_it_refuses_to_time_jg_ground_when_it_would_escalate_to_an_mllm(monkeypatch, capsys):
    # The benchmark times jg.ground with its defaults; with an endpoint set, unsure texts would go to the network.
    monkeypatch.setenv("JGROUNDING_MLLM_URL", "http://127.0.0.1:9/v1")
    assert bench.main([]) == 1
    assert "JGROUNDING_MLLM_URL" in capsys.readouterr().out


def test_the_goals_of_34_are_read_on_every_blind_bench_and_the_v2_styles():
    res, _, _ = _results(situation=0.93)
    blind = {"n_motion": 5, "intent": 0.96, "confident_wrong": 0.0, "none_held": 0.97, "exact": 0.85, "ece": 0.03}
    res |= {("new", "b1", "all"): blind, ("new", "b2", "all"): dict(blind, none_held=0.9, confident_wrong=0.02)}
    rows = scores.blind_goal_rows(res, ["b1", "b2"])
    missed = [g for _, g, ok, _, _ in rows if not ok]
    assert missed == ["b2: no-motion held >= 0.95", "b2: confident wrong motion <= 1% of motion texts"]
    assert sum(g.startswith("b1") for _, g, _, _, _ in rows) == 5 and rows[-2][3] == "0.930"
    assert all(ref == "" for *_, ref in rows)  # no second reading: an empty reference column
    assert rows[-1][3] == "lowest terse 0.970"


def test_a_bench_of_situations_and_mixed_texts_is_read_per_style_without_a_no_motion_row():
    res, _, _ = _results(situation=0.93)
    motion = {"intent": 0.9, "confident_wrong": 0.0, "exact": 0.85, "ece": 0.03}
    res |= {
        ("new", "s3", "all"): dict(motion, n_motion=6, n_none=0, none_held=None),
        ("new", "s3", "situation"): dict(motion, n_motion=4, n_none=0, intent=0.88),
        ("new", "s3", "mixed"): dict(motion, n_motion=2, n_none=0, intent=0.94),
    }
    rows = [r for r in scores.blind_goal_rows(res, ["s3"]) if r[1].startswith("s3")]
    goals = [g for _, g, _, _, _ in rows]
    assert goals == [
        "s3: confident wrong motion <= 1% of motion texts",
        "s3: mixed intent >= 0.95",
        "s3: situation intent >= 0.9",
        "s3: intensity exact >= 0.8",
        "s3: ECE <= 0.05",
    ]
    assert [ok for _, _, ok, _, _ in rows] == [True, False, False, True, True]


def _bench(texts):
    """Writer's labels of a small bench: (intent, intensity) per text, ids t0, t1, ..."""
    return [
        {
            "id": f"t{i}",
            "text": f"text {i}",
            "intent": m,
            "intensity": z,
            "style": "none" if m == "none" else "contrast",
        }
        for i, (m, z) in enumerate(texts)
    ]


def test_a_second_reading_is_scored_against_the_writer_and_references_rank_right():
    items = _bench(
        [("greeting", "subtle"), ("nodding", "emphatic"), ("resting", "moderate"), ("none", "none"), ("none", "none")]
    )
    writer = {it["id"]: (it["intent"], it["intensity"]) for it in items}
    same = scores.reader_metrics(items, writer)
    assert (same["intent"], same["none_held"], same["exact"], same["within_one"]) == (1.0, 1.0, 1.0, 1.0)
    assert same["confident_wrong"] is None and same["ece"] is None  # a reading has no confidence
    # one level off everywhere: intent and held kept, exact 0, within one 1
    shifted = dict(writer, t0=("greeting", "moderate"), t1=("nodding", "pronounced"), t2=("resting", "subtle"))
    r = scores.reader_metrics(items, shifted)
    assert (r["intent"], r["exact"], r["within_one"]) == (1.0, 0.0, 1.0)
    # a motion read as none is a wrong intent and a wrong intensity; a none read as a motion is not held
    worse = dict(writer, t0=("none", "none"), t3=("greeting", "subtle"))
    r = scores.reader_metrics(items, worse)
    assert (round(r["intent"], 3), round(r["exact"], 3), r["none_held"]) == (0.667, 0.667, 0.5)
    with pytest.raises(ValueError, match="did not label 1 texts"):
        scores.reader_metrics(items, {k: v for k, v in writer.items() if k != "t4"})


def test_the_goal_table_carries_the_second_readers_measure_where_it_has_one():
    res, _, _ = _results(situation=0.93)
    blind = {
        "n_motion": 5,
        "n_none": 3,
        "intent": 0.96,
        "confident_wrong": 0.0,
        "none_held": 0.97,
        "exact": 0.7,
        "ece": 0.03,
    }
    reader = {"n_motion": 5, "intent": 0.98, "none_held": 0.9, "exact": 0.75, "confident_wrong": None, "ece": None}
    res |= {("new", "b1", "all"): blind, (scores.SECOND_READER, "b1", "all"): reader}
    rows = {g: ref for _, g, _, _, ref in scores.blind_goal_rows(res, ["b1"])}
    assert rows["b1: no-motion held >= 0.95"] == "0.900" and rows["b1: intensity exact >= 0.8"] == "0.750"
    assert rows["b1: contrast intent >= 0.95"] == "0.980"
    assert rows["b1: ECE <= 0.05"] == "" and rows["b1: confident wrong motion <= 1% of motion texts"] == ""


def test_every_second_reading_covers_its_bench_exactly():
    """A bench's second_reader.jsonl labels each of its texts once, with valid names (read here by id only)."""
    from jgrounding.vocabulary import INTENSITIES, INTENTS

    for path in bench.BENCH_V3.values():
        labels_path = path.with_name(scores.SECOND_READER_FILE)
        if not labels_path.exists():
            continue
        rows = scores.read_jsonl(labels_path)
        ids = [r["id"] for r in rows]
        assert len(ids) == len(set(ids)), labels_path
        assert set(ids) == {r["id"] for r in scores.read_jsonl(path)}, labels_path
        for r in rows:
            assert set(r) == {"id", "intent", "intensity"}, labels_path
            assert (r["intent"], r["intensity"]) == ("none", "none") or (
                r["intent"] in INTENTS and r["intensity"] in INTENSITIES
            ), (labels_path, r)


def test_only_the_bench_reads_the_frozen_blind_benches():
    """Each blind set's bench.jsonl is frozen; only experiments/bench_semantics.py names it (each set's split.py
    writes it). Every bench.jsonl under assets/ is one of the bench's BENCH_V3, each a set of role bench."""
    import re
    from pathlib import Path

    from tools import semantic_sets

    root = Path(bench.ROOT)
    frozen = sorted((root / "assets").rglob("bench.jsonl"))
    assert frozen == sorted(bench.BENCH_V3.values())
    assert all(p.parent.parent == semantic_sets.FOLDER / "bench" for p in frozen)
    readers = []
    for path in [*root.glob("jgrounding/**/*.py"), *root.glob("tools/*.py"), *root.glob("experiments/*.py")]:
        if re.search(r"[\"']bench\.jsonl[\"']", path.read_text()):  # the file name as a string literal in code
            readers.append(path.relative_to(root).as_posix())
    assert readers == ["experiments/bench_semantics.py"]
