"""Screening's budget (issue #26): a large num_samples is not refused for an internal budget the user never set."""

import jax
import numpy as np
import pytest

from jgrounding import sim
from jgrounding.policy import sampling


def test_default_budget_is_capped_and_errors_name_the_users_parameter(monkeypatch):
    drawn = []

    def fake_sample(self, key, intent, intensity, num_samples=1, **kw):  # every candidate feasible, no sampler run
        drawn.append(num_samples)
        return np.zeros((num_samples, 150, 4), np.float32)

    sampling.default_config()  # the model loaded (and self-tested) before the fake replaces its sampler
    monkeypatch.setattr(sampling.Model, "sample", fake_sample)  # what screened draws each round with
    monkeypatch.setattr(sim, "margins", lambda u, engine=None, trunk=None: np.ones(len(u)))
    res = sampling.screened(jax.random.key(0), "nodding", "moderate", num_samples=1025)
    assert res.u.shape == (1025, 150, 4) and 1025 <= sum(drawn) <= sampling.MAX_SAMPLES
    with pytest.raises(ValueError, match=r"num_samples must be an integer in 1..4096, got 4097"):
        sampling.screened(jax.random.key(0), "nodding", "moderate", num_samples=4097)
    with pytest.raises(ValueError, match=r"budget must be an integer in num_samples..4096 \(here 8..4096"):
        sampling.screened(jax.random.key(0), "nodding", "moderate", num_samples=8, budget=4)
