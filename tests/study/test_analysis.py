"""The analysis against values computed by hand (in the comments) and against simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jgrounding.study import analysis


def test_wilson_interval_of_8_in_10():
    # p = 0.8, z = 1.96: centre (0.8 + 0.19207) / 1.38415 = 0.71674, half 0.22658 -> (0.4902, 0.9433)
    lo, hi = analysis.wilson(8, 10)
    assert float(lo) == pytest.approx(0.49016, abs=1e-5) and float(hi) == pytest.approx(0.94332, abs=1e-5)
    lo, hi = analysis.wilson(0, 0)
    assert (float(lo), float(hi)) == (0.0, 1.0)
    lo, hi = analysis.wilson(0, 20)
    assert float(lo) == 0.0 and float(hi) == pytest.approx(0.16113, abs=1e-5)  # z^2/(n+z^2) = 3.8415/23.8415


def test_wilcoxon_is_exact_given_the_ties_and_zeros():
    # d = 1, 1, 1, 2, -1 (the 0 dropped): |d| ranks 2.5 x 4 and 5; T+ = 12.5, T- = 2.5. Given those ranks,
    # T+ = 2.5 K + 5 B (K ~ Binomial(4, 1/2): the 1s that are positive; B ~ Bernoulli(1/2): the 2);
    # T+ >= 12.5 only for B = 1, K >= 3: (4 + 1)/16 x 1/2 = 5/32, the smaller tail -> p = 10/32
    w, p = analysis.wilcoxon([0] * 6, [1, 1, 1, 2, -1, 0])
    assert w == 2.5 and p == pytest.approx(10 / 32)
    expected = np.zeros(31)  # P(2 T+ = j), j = 0 .. 2 x 15
    for k in range(5):
        for b in range(2):
            expected[5 * k + 10 * b] += math.comb(4, k) / 32
    assert analysis.signed_rank_null([2.5] * 4 + [5]).tolist() == pytest.approx(expected.tolist())
    # no ties, no zeros: the classical exact test; T- = 4 of ranks 1..5: 7 of 32 sign patterns -> p = 14/32
    assert analysis.wilcoxon([0] * 5, [1, 2, 3, -4, 5])[1] == pytest.approx(14 / 32)
    assert analysis.wilcoxon([3, 4], [3, 4]) == (0.0, 1.0)


def test_wilcoxon_p_is_the_share_of_all_sign_flips():
    import itertools

    from scipy import stats

    rng = np.random.default_rng(0)
    for _ in range(5):  # Likert-like differences: many ties and zeros
        d = rng.integers(-3, 4, 12).astype(float)
        nz = d[d != 0]
        ranks = stats.rankdata(np.abs(nz))
        t = ranks[nz > 0].sum()
        every = np.array([ranks @ np.array(s) for s in itertools.product([0, 1], repeat=len(nz))])
        brute = min(1.0, 2 * min(np.mean(every <= t), np.mean(every >= t)))
        assert analysis.wilcoxon(np.zeros(12), d)[1] == pytest.approx(brute, abs=1e-12)
        p_each = [min(1.0, 2 * min(np.mean(every <= s), np.mean(every >= s))) for s in every]
        level = analysis.wilcoxon_level(np.zeros(12), d)  # its actual level at 0.05: never above it
        assert level == pytest.approx(np.mean(np.array(p_each) < 0.05), abs=1e-12) and level <= 0.05


def test_wilcoxon_level_by_hand():
    # ranks 1..10, no ties: 25 of the 1024 subsets sum to <= 8, the critical value at 0.05 -> 2 x 25 / 1024
    assert analysis.wilcoxon_level(np.zeros(10), np.arange(1, 11)) == pytest.approx(50 / 1024)
    # the hand example: the most extreme of its outcomes (all negative) has p = 2 / 32 = 0.0625: level 0
    assert analysis.wilcoxon_level([0] * 6, [1, 1, 1, 2, -1, 0]) == 0.0


def test_wilcoxon_beyond_the_exact_range_is_normal_with_tie_and_continuity_corrections():
    from scipy import stats

    # the hand example on the normal branch: mean 5 x 6 / 4 = 7.5, variance 5 x 6 x 11 / 24 - (4^3 - 4) / 48
    # = 13.75 - 1.25 = 12.5; z = (|12.5 - 7.5| - 0.5) / sqrt(12.5) = 1.272792; p = 2 (1 - Phi(z)) = 0.203092
    w, p = analysis.wilcoxon([0] * 6, [1, 1, 1, 2, -1, 0], exact_up_to=0)
    assert w == 2.5 and p == pytest.approx(0.203092, abs=1e-6)
    d = np.random.default_rng(1).integers(-3, 4, 1000).astype(float)
    ref = stats.wilcoxon(d, zero_method="wilcox", correction=True, method="asymptotic")
    w, p = analysis.wilcoxon(np.zeros(1000), d)  # ~860 non-zero differences > EXACT_UP_TO: this branch
    assert w == ref.statistic and p == pytest.approx(ref.pvalue, rel=1e-9)
    assert analysis.wilcoxon(np.zeros(1000), d, exact_up_to=10**4)[1] == pytest.approx(p, abs=0.01)  # close


def test_rank_biserial_and_paired_difference():
    assert analysis.rank_biserial([0] * 6, [1, 1, 1, 2, -1, 0]) == pytest.approx(10 / 15)  # (12.5 - 2.5) / 15
    assert analysis.rank_biserial([1, 2], [3, 4]) == 1.0
    a = [True] * 3 + [False] * 7
    b = [True] * 1 + [False] * 2 + [True] * 6 + [False]  # b = 2 (A only), c = 6 (B only) of n = 10
    diff, lo, hi = analysis.paired_difference(a, b)
    se = math.sqrt(8 - 16 / 10) / 10  # sqrt((b + c) - (c - b)^2 / n) / n
    assert diff == pytest.approx(0.4) and lo == pytest.approx(0.4 - 1.959964 * se, abs=1e-6) and hi <= 1


def test_mcnemar_exact_counts_discordant_pairs():
    a = [True] + [False] * 9 + [True] * 5
    b = [False] + [True] * 9 + [True] * 5  # b = 1, c = 9: p = 2 (1 + 10) / 2^10
    assert analysis.mcnemar_exact(a, b) == (1, 9, 22 / 1024)
    assert analysis.mcnemar_exact([True, False], [True, False]) == (0, 0, 1.0)


def test_holm_steps_down():
    # sorted 0.005, 0.01, 0.03, 0.04 x 4, 3, 2, 1 = 0.02, 0.03, 0.06, 0.04 -> running max 0.02, 0.03, 0.06, 0.06
    assert analysis.holm([0.01, 0.04, 0.03, 0.005]).tolist() == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert analysis.holm([0.5, 0.9]).tolist() == [1.0, 1.0]  # 0.5 x 2 = 1.0 carries over to 0.9 x 1


def test_participants_needed_matches_connor_and_reaches_its_power():
    # the paper's overall satisfaction, 46% -> 82%, independent ratings: psi = .46*.18 + .54*.82 = 0.5256,
    # n = (1.95996 sqrt(.5256) + 0.84162 sqrt(.5256 - .1296))^2 / .1296 = 3.8047 / .1296 = 29.36 -> 30
    n = analysis.participants_needed(0.46, 0.82)
    assert n == 30
    assert analysis.participants_needed(0.46, 0.82, discordant=0.40) < n  # correlated ratings need fewer
    rng = np.random.default_rng(0)  # McNemar's exact test on 30 independent pairs at those ratios
    a, b = rng.random((2000, 30)) < 0.46, rng.random((2000, 30)) < 0.82
    power = np.mean([analysis.mcnemar_exact(x, y)[2] < 0.05 for x, y in zip(a, b)])
    assert 0.7 <= power <= 0.9  # the exact test is a little conservative against the 0.8 of the approximation
    with pytest.raises(ValueError, match="two different"):
        analysis.participants_needed(0.5, 0.5)


def _rows(ratings, positions, conditions, dimensions):
    return [
        dict(participant_id=f"P{i:03d}", position=int(positions[i, c]), condition=cond, dimension=dim, value=int(v))
        for i in range(ratings.shape[0])
        for c, cond in enumerate(conditions)
        for d, dim in enumerate(dimensions)
        if not math.isnan(v := ratings[i, c, d])
    ]


def test_the_report_of_a_simulated_study_finds_the_papers_effects(tmp_path):
    from jgrounding.study import simulate

    model = simulate.paper_model(dropout=0.05)
    ratings, positions = simulate.simulate_study(np.random.default_rng(3), model, 100)
    report = analysis.analyze(
        _rows(ratings, positions, model.conditions, model.dimensions), model.conditions, model.dimensions
    )
    assert report["participants"] == 100 and len(report["descriptive"]) == 12
    tests = {t["dimension"]: t for t in report["comparisons"][0]["tests"]}
    for dim in ("naturalness", "expressiveness", "engagement", "overall_satisfaction"):
        assert tests[dim]["mcnemar_p_holm"] < 0.001 and tests[dim]["wilcoxon_p_holm"] < 0.001
        assert tests[dim]["rank_biserial"] > 0.4 and tests[dim]["ratio_difference"] > 0.2
    assert tests["perceived_safety"]["mcnemar_p_holm"] > 0.05  # 86% vs 83%: no effect to find
    assert all(t["wilcoxon_p_holm"] >= t["wilcoxon_p"] for t in tests.values())
    assert {r["condition"] for r in report["order"]} == set(model.conditions) and report["power"]
    text = analysis.markdown(report)
    assert "| naturalness | trunk |" in text and "Holm over 6 dimensions" in text
    analysis.figure(report, tmp_path / "fig.png")
    assert (tmp_path / "fig.png").stat().st_size > 10_000


def test_withdrawn_participants_count_unless_excluded():
    from jgrounding.study import simulate

    model = simulate.paper_model()
    ratings, positions = simulate.simulate_study(np.random.default_rng(4), model, 20)
    rows = _rows(ratings, positions, model.conditions, model.dimensions)
    gone = {"P003", "P011"}
    for r in rows:
        r["status"] = "withdrawn" if r["participant_id"] in gone else "complete"
    every = analysis.analyze(rows, model.conditions, model.dimensions)
    assert every["participants"] == 20 and every["withdrawn"] == ["P003", "P011"]
    assert not every["withdrawn_excluded"] and every["descriptive"][0]["n"] == 20
    kept = analysis.analyze(rows, model.conditions, model.dimensions, exclude_withdrawn=True)
    assert kept["participants"] == 18 and kept["withdrawn"] == ["P003", "P011"] and kept["withdrawn_excluded"]
    assert kept["descriptive"][0]["n"] == 18 and kept["comparisons"][0]["tests"][0]["pairs"] == 18
    rest = [r for r in rows if r["participant_id"] not in gone]
    assert kept["descriptive"] == analysis.analyze(rest, model.conditions, model.dimensions)["descriptive"]
    assert "20 participants (2 withdrawn, included)" in analysis.markdown(every)
    assert "18 participants (2 withdrawn, excluded)" in analysis.markdown(kept)


def test_the_order_check_sees_a_carryover():
    from jgrounding.study import simulate

    model = simulate.paper_model(order_shift=1.5)  # the second block is rated much higher whatever it is
    ratings, positions = simulate.simulate_study(np.random.default_rng(1), model, 100)
    comp = analysis.compare(ratings, positions, 0, 1, model.dimensions)
    assert all(t["order_p"] < 0.01 for t in comp)
    order = analysis.order_effects(ratings, positions, model.conditions, model.dimensions)
    assert all(r["kruskal_p"] < 0.01 for r in order)
