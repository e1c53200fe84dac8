"""tools.nomotion_frontier: the act/hold decision's cost on dev, the vectorised decision that it fits (the same as
jgrounding.semantics.decision.decide, text by text), the tie rule and the choice of the least-cost point."""

import numpy as np
import pytest

from jgrounding.semantics import decision
from tools import nomotion_frontier as nf
from tools import semantics_system_dev as sd


@pytest.fixture(scope="module")
def small():
    """Eight texts of each dev set, as the decision reads them."""
    return nf.records({name: sd.read(paths)[::40][:8] for name, paths in sd.SETS.items()})


def test_the_vectorised_decision_is_decide_text_by_text(small):
    from jgrounding.semantics import embedded

    points = [
        decision.point(),
        decision.fallback_point(),
        decision.OperatingPoint(dict.fromkeys(decision.KINDS, 0.0), 0.0),
    ]
    for p in points:
        hold = nf.held(small, p.thresholds, p.detector)
        for text, h in zip(small["text"], hold):
            (g,), v = embedded.ground_embedded_vectors([str(text)], threshold=0.0)
            assert (not decision.decide(str(text), g, vector=v[0], p=p).confident) == h, (text, p)


def test_costs_and_figures_count_what_the_decision_does():
    r = {
        "motion": np.array([True, True, True, False]),
        "right": np.array([True, False, True, False]),
    }
    hold = np.array([False, False, True, False])  # right acted, wrong acted, motion held, no-motion acted
    c = decision.COSTS
    assert nf.costs(r, hold).tolist() == [0.0, c["acted_wrong"], c["held_motion"], c["acted_no_motion"]]
    f = nf.figures(r, hold)
    assert f["cost"] == pytest.approx(sum(c.values()) / 4)
    assert (f["acted_right"], f["held_motion"], f["acted_wrong"], f["none_held"]) == (1 / 3, 1 / 3, 1 / 3, 0.0)


def test_a_tie_takes_the_middle_of_the_flat_stretch():
    assert nf.middle([0.1, 0.2, 0.3, 0.4, 0.5], [3, 1, 1, 1, 2]) == 0.3
    assert nf.middle([0.1, 0.2], [1, 0]) == 0.2


def test_the_chosen_point_costs_no_more_than_any_grid_point_on_its_texts(small):
    thresholds, detector, rows = nf.choose(small)
    best = nf.costs(small, nf.held(small, thresholds, detector)).mean()
    assert best == pytest.approx(min(c for _, _, c in rows))
    for t in (0.0, 0.5, 0.9, 1.01):
        for d in nf.DETECTOR_GRID[::4]:
            assert best <= nf.costs(small, nf.held(small, dict.fromkeys(decision.KINDS, t), d)).mean() + 1e-12


def test_the_report_names_the_costs_and_every_point(small):
    thresholds, detector, rows = nf.choose(small)
    md, payload = nf.report(
        small, decision.point(), (thresholds, detector), rows, nf.sweep(small, thresholds, detector)
    )
    assert all(f"**{v:g}**" in md for v in decision.COSTS.values())
    assert set(payload["points"]) == {"one threshold", "shipped", "chosen"}


def test_quick_writes_nothing_and_cannot_write_or_check(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    before = sorted(nf.OUT.parent.glob("nomotion_frontier.*"))
    stamps = [p.stat().st_mtime_ns for p in before]
    assert nf.main(["--quick"]) == 0
    assert "| chosen |" in capsys.readouterr().out
    assert [p.stat().st_mtime_ns for p in before] == stamps
    for flag in ("--write", "--check"):
        with pytest.raises(SystemExit):
            nf.main(["--quick", flag])


def test_the_one_threshold_row_is_the_decision_before_it_was_per_kind(small):
    """The row the chosen point is compared with is jg.ground's decision before (experiments.bench_acting's
    ``before``, which reproduces it from the same pass)."""
    from experiments import bench_acting

    one = decision.fallback_point()
    hold = np.logical_or(*nf.held_parts_before(small, one.thresholds["order"], one.detector))
    for text, h in zip(small["text"], hold):
        assert (not bench_acting.before_and_after(str(text))[0].confident) == h, text
