"""Physics metrics of generated samples: shape RMS, calibrated tolerance, every sample simulated."""

import numpy as np
import pytest

from jgrounding import sim
from jgrounding.evaluation import physics


def test_shape_rms_by_hand():
    a = np.zeros((150, 11, 3))
    b = a.copy()
    b[..., 0] = 0.03  # every point 3 cm away -> RMS 0.03
    b[:75, :, 1] = 0.04  # half of the time also 4 cm sideways -> sqrt((0.03^2 + 0.05^2) / 2)
    assert physics.shape_rms(a, b) == pytest.approx(np.sqrt((0.03**2 + 0.05**2) / 2))


def test_pairwise_matches_direct_and_diversity_is_its_mean():
    x = np.random.default_rng(0).normal(size=(5, 20, 11, 3))
    d = physics.pairwise_shape_rms(x)
    direct = physics.shape_rms(x[:, None], x[None])
    np.testing.assert_allclose(d, direct, atol=1e-6)
    iu = np.triu_indices(5, 1)
    assert physics.shape_diversity(x) == pytest.approx(direct[iu].mean())


def test_calibration_matches_the_actuation_percentile():
    # 4 trajectories on a line: actuation distances 0.1 (x3), 0.2 (x2), 0.3; shape = 2 x actuation (metres)
    u = np.stack([np.full((10, 4), v) for v in (0.0, 0.1, 0.2, 0.3)])
    backbone = np.stack([np.full((10, 2, 3), 2 * v / np.sqrt(3)) for v in (0.0, 0.1, 0.2, 0.3)])
    tol = physics.calibrate(u, backbone, np.array([0, 0, 1, 1]), np.zeros(4, int), tau_rms=0.15)
    assert tol.percentile == pytest.approx(50.0)  # 3 of the 6 pairs are within 0.15
    assert tol.tau_m == pytest.approx(0.2)  # the smallest with half of the pairs within: 0.2 x3, 0.4 x2, 0.6
    assert tol.within_tuple_median_m == pytest.approx(0.2) and tol.oracle_success == 1.0


def test_every_sample_simulated_and_identical_copies_once():
    u = np.zeros((2, 3, 150, 4), np.float32)
    u[1, :, :, 0] = np.linspace(0, 0.5, 150)[None]  # tuple 1: three identical bends toward the user
    u[1, 2, :, 2] = 0.3  # ... one of them also pulls tendon 2
    ref = sim.rollout(np.zeros((2, 150, 4))).backbone
    res = physics.simulate_samples(u, ref, tau_m=0.02)
    assert res["simulated"] == 3  # rest, the bend, the bend + tendon 2: each distinct trajectory once
    assert res["shape_rms"].shape == (2, 3) and np.all(res["shape_rms"][0] < 1e-9)
    assert res["shape_success"][0].all() and not res["shape_success"][1].any()
    assert res["diversity"][0] < 1e-6 and res["diversity"][1] > 0 and res["feasible"].all()
    np.testing.assert_allclose(sim.margins(u.reshape(-1, 150, 4)), res["margin"].reshape(-1))
