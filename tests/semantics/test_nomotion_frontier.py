"""tools.nomotion_frontier: the no-motion decision's act/hold frontier on dev, and the goals it is read against."""

import pytest

from experiments import bench_semantics_scores as bs
from tools import nomotion_frontier as nf
from tools import semantics_system_dev as sd


def _row(held=0.97, nm_ece=0.04, sit_ece=0.04) -> dict:
    r = {name: dict(none_held=None, ece=0.0, acted=0.8) for name in [*sd.SETS, *sd.POOLED]}
    r[sd.NO_MOTION_DEV] |= dict(none_held=held, ece=nm_ece)
    r[sd.UNFITTED_BOTH]["ece"] = sit_ece
    return r


def test_a_threshold_meets_the_goals_only_when_all_three_are_met():
    g = bs.GOALS_34
    assert nf.meets(_row())
    assert nf.meets(_row(held=g["none_held"], nm_ece=g["ece"], sit_ece=g["ece"]))  # the goals are inclusive
    assert not nf.meets(_row(held=0.94))  # holds too little
    assert not nf.meets(_row(nm_ece=0.06))  # a no-motion set's ECE
    assert not nf.meets(_row(sit_ece=0.06))  # a situation set's ECE: its false holds


def test_the_table_marks_each_row_and_names_every_column():
    text = nf.table([("0.5000", _row()), ("rule only", _row(held=0.9))])
    lines = text.splitlines()
    assert all(c[2] in lines[0] for c in nf.COLUMNS)
    assert lines[2].startswith("| 0.5000 | 0.970 |") and lines[2].endswith("| yes |")
    assert lines[3].startswith("| rule only | 0.900 |") and lines[3].endswith("| no |")


@pytest.fixture(scope="module")
def small_runs():
    """Eight texts of each dev set, grounded as jg.ground grounds them."""
    return nf.groundings({name: sd.read(paths)[::40][:8] for name, paths in sd.SETS.items()})


def test_the_shipped_row_is_what_jg_ground_gives_and_no_decision_holds_nothing(small_runs, monkeypatch):
    rows = dict(nf.frontier(small_runs, thresholds=(0.0, 1.01)))
    shipped = next(r for label, r in rows.items() if label.endswith("(shipped)"))
    monkeypatch.setattr(sd, "read", lambda paths: small_runs[next(n for n, p in sd.SETS.items() if p == paths)][0])
    assert shipped == sd.evaluate()  # every set and pool, through jg.ground text by text
    # holds only add: threshold 0 >= shipped >= above 1 (no learned hold: the rule alone) >= no decision at all
    for name in (sd.NO_MOTION_DEV,):
        held = [r[name]["none_held"] for r in (rows["0.0000"], shipped, rows["1.0100"], rows["no decision"])]
        assert held == sorted(held, reverse=True), (name, held)
        assert rows["1.0100"][name] == rows["rule only"][name]
    acted = [r[sd.UNFITTED_BOTH]["acted"] for r in (rows["0.0000"], shipped, rows["no decision"])]
    assert acted == sorted(acted)
