"""bench semantics' goal rows: each of #24's goals is checked, and every shortfall says what was tried."""

from experiments import bench_semantics as bench


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
    rows = bench.goal_rows(*_results())
    assert {key for key, *_ in rows} == set(bench.GOALS) | {"plain"}
    assert all(ok for _, _, ok, _ in rows)
    assert bench.shortfalls(rows) == []


def test_a_shortfall_names_its_measure_and_what_was_tried():
    rows = bench.goal_rows(*_results(situation=0.904, median=5.4))
    missed = {key: measured for key, _, ok, measured in rows if not ok}
    assert missed == {
        "intent": "lowest style 0.904",
        "ms_median": "5.40 ms",
    }  # a no-motion style is not a style minimum
    tried = bench.shortfalls(rows)
    assert len(tried) == 2 and "docs/how_it_works.md" in tried[0] and "float16" in tried[1]


def test_a_new_shortfall_says_nothing_was_tried_yet():
    rows = bench.goal_rows(*_results(ece=0.2))
    assert bench.shortfalls(rows) == ["ECE <= 0.05: nothing tried yet (a new shortfall)"]


def test_it_refuses_to_time_jg_ground_when_it_would_escalate_to_an_mllm(monkeypatch, capsys):
    # The benchmark times jg.ground with its defaults; with an endpoint set, unsure texts would go to the network.
    monkeypatch.setenv("JGROUNDING_MLLM_URL", "http://127.0.0.1:9/v1")
    assert bench.main([]) == 1
    assert "JGROUNDING_MLLM_URL" in capsys.readouterr().out


def test_the_goals_of_34_are_read_on_every_blind_bench_and_the_v2_styles():
    res, _, _ = _results(situation=0.93)
    blind = {"n_motion": 5, "intent": 0.96, "confident_wrong": 0.0, "none_held": 0.97, "exact": 0.85, "ece": 0.03}
    res |= {("new", "b1", "all"): blind, ("new", "b2", "all"): dict(blind, none_held=0.9, confident_wrong=0.02)}
    rows = bench.blind_goal_rows(res, ["b1", "b2"])
    missed = [g for _, g, ok, _ in rows if not ok]
    assert missed == ["b2: no-motion held >= 0.95", "b2: confident wrong motion <= 1% of contrast texts"]
    assert sum(g.startswith("b1") for _, g, _, _ in rows) == 5 and rows[-2][3] == "0.930"
    assert rows[-1][3] == "lowest terse 0.970"
