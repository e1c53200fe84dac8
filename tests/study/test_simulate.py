"""Simulated participants: the known distributions come out, and the analysis recovers them (a smaller run of
experiments/study_validation.py: 200 studies instead of 1,000, bounds checked loosely)."""

from __future__ import annotations

import numpy as np
import pytest

from jgrounding.study import simulate


def test_likert_distributions_have_the_papers_positive_ratios():
    model = simulate.paper_model()
    assert model.probabilities.sum(-1) == pytest.approx(np.ones((2, 6)))
    assert model.probabilities[..., 3:].sum(-1)[1, 0] == pytest.approx(0.80)  # trunk, naturalness
    truth = simulate.true_ratios(model, 100)
    assert truth[0].tolist() == pytest.approx(list(simulate.PAPER_RATIOS["av_only"]))


def test_ratings_follow_the_distributions_with_dropouts_and_order():
    model = simulate.paper_model(dropout=0.2, order_shift=0.3)
    ratings, positions = simulate.simulate_study(np.random.default_rng(0), model, 20_000)
    seen = ~np.isnan(ratings[:, :, 0])
    assert seen.any(1).all() and np.mean(~seen.all(1)) == pytest.approx(0.2, abs=0.01)  # left after block 1
    assert (positions[seen] >= 0).all() and (positions[~seen] == -1).all()
    observed = (ratings >= 4).sum(0) / (~np.isnan(ratings)).sum(0)
    assert observed == pytest.approx(simulate.true_ratios(model, 20_000), abs=0.015)
    first = ratings[positions[:, 0] == 0, 0, 0]
    later = ratings[positions[:, 0] == 1, 0, 0]
    assert np.mean(later >= 4) > np.mean(first >= 4) + 0.05  # the order effect is there


def test_a_simulated_participant_answers_every_dimension():
    p = simulate.SimulatedParticipant(simulate.paper_model(), np.random.default_rng(0))
    answers = p.rate("trunk", 1)
    assert set(answers) == set(simulate.DIMENSIONS) and all(1 <= v <= 5 for v in answers.values())


def test_the_analysis_recovers_the_truth_over_200_studies():
    model = simulate.paper_model(order_shift=0.2, dropout=0.05)
    result = simulate.validate(np.random.default_rng(2026), model, studies=200, participants=100)
    assert 0.93 <= result["coverage"] <= 0.97  # 2,400 intervals: binomial sd 0.0044 around 0.95
    assert abs(result["mean_error"]) < 0.01
    assert result["false_positive"]["wilcoxon"] <= 0.07 and result["false_positive"]["mcnemar"] <= 0.07
    assert result["familywise_false_positive"]["mcnemar"] <= 0.09
    assert result["wilcoxon_level"]["max"] <= 0.05  # the exact test's level given the ranks: by construction
    assert result["power"]["mcnemar"] >= 0.8  # five of the six dimensions differ by >= 30 points
