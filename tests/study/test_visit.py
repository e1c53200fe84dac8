"""``python -m jgrounding.study simulate URL``: simulated participants through a running study server (enrolled,
episodes played on the live stream, ratings stored), and the analysis warns that one participant is a small
sample instead of printing a bare "100.0% [100.0%, 100.0%]"."""

from __future__ import annotations

import dataclasses

import pytest

SQLALCHEMY = pytest.importorskip(
    "sqlalchemy", reason="the study's database needs sqlalchemy (requirements.txt pins it)"
)
from jgrounding.study import Store  # noqa: E402 (after the skip: the store imports sqlalchemy)


def test_simulated_participants_run_through_the_server_and_the_report_warns(tmp_path, design, capsys):
    from jgrounding.serving import Running
    from jgrounding.study.__main__ import analyze, main
    from jgrounding.study.app import StudyServer

    store = Store(tmp_path / "study.db")
    run = Running(StudyServer(dataclasses.replace(design, episodes=design.episodes[:1]), store))
    try:
        assert main(["simulate", run.http, "--participants", "1", "--seed", "3"]) == 0
    finally:
        run.stop()
    said = capsys.readouterr().out
    assert "block 2 of 2" in said and "1 simulated participants rated" in said
    rows = store.long_ratings()
    assert len(rows) == 2 * 6 and {r["condition"] for r in rows} == {"av_only", "scripted"}
    runs = store.table("executions")
    assert len(runs) == 2 and all(e["planned_sha256"] == e["executed_sha256"] for e in runs)
    report = analyze(tmp_path / "study.db", tmp_path / "analysis")
    text = (tmp_path / "analysis" / "report.md").read_text()
    assert report["participants"] == 1
    assert "small sample: scripted vs av_only rests on n = 1 complete pair" in text


def test_simulate_refuses_bad_settings_and_an_unreachable_server(capsys):
    from jgrounding.study import visit
    from jgrounding.study.__main__ import main

    with pytest.raises(ValueError, match="participants"):
        visit.run("http://127.0.0.1:9", participants=0)
    with pytest.raises(ValueError, match="dropout"):
        visit.run("http://127.0.0.1:9", dropout=1.0)
    assert main(["simulate", "http://127.0.0.1:9"]) == 2
    assert "cannot reach the study server" in capsys.readouterr().err


def test_the_warning_names_n_and_stays_away_from_large_samples():
    from jgrounding.study.analysis import small_sample_warnings

    def report(pairs, n):
        return {
            "conditions": ["a", "b"],
            "comparisons": [{"a": "a", "b": "b", "tests": [{"pairs": pairs}, {"pairs": pairs + 1}]}],
            "descriptive": [{"condition": c, "n": n} for c in ("a", "b")],
        }

    assert small_sample_warnings(report(40, 40)) == []
    warned = small_sample_warnings(report(3, 40))
    assert len(warned) == 1 and "n = 3 complete pairs" in warned[0]
    assert len(small_sample_warnings(report(3, 3))) == 3


def test_the_simulated_ratings_follow_the_papers_ratios_and_a_middle_for_others():
    from jgrounding.study import simulate, visit

    model = visit.model_for(["av_only", "trunk", "scripted"], ["naturalness", "my_item"])
    positive = model.probabilities[..., 3:].sum(-1)
    assert positive[0, 0] == pytest.approx(simulate.PAPER_RATIOS["av_only"][0])
    assert positive[1, 0] == pytest.approx(simulate.PAPER_RATIOS["trunk"][0])
    assert positive[2, 0] == pytest.approx(
        (simulate.PAPER_RATIOS["av_only"][0] + simulate.PAPER_RATIOS["trunk"][0]) / 2
    )
    assert positive[0, 1] == pytest.approx(sum(simulate.PAPER_RATIOS["av_only"]) / 6)
