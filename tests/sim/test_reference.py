"""The physical reference (jgrounding.sim.reference, a PyElastica Cosserat rod) on a short, coarse case: it hangs
under gravity, each tendon bends it toward its side, its recordings read back, and its parameters each have a
source. The first run compiles PyElastica's numba kernels once (cached on disk); later runs take seconds."""

import dataclasses
import math

import numpy as np
import pytest

from jgrounding.sim import mjcf as tm
from jgrounding.sim import reference

ELEMENTS, STEPS = 12, 36  # coarse and short: 1.2 s of motion


def test_every_parameter_has_a_source_and_the_damping_follows_from_them():
    p = reference.PARAMETERS
    assert {f.name for f in dataclasses.fields(p)} == set(reference.SOURCES)
    assert (p.length, p.base_radius, p.tip_radius, p.max_tendon_force) == (
        tm.TRUNK_LENGTH,
        tm.BASE_RADIUS,
        tm.TIP_RADIUS,
        tm.MAX_TENDON_FORCE,
    )
    assert p.damping_constant == pytest.approx(2 * p.damping_ratio * 2 * math.pi * p.first_mode_hz)
    assert p.radius(0.0) == pytest.approx(0.045) and p.radius(p.length) == pytest.approx(0.014)


def test_commands_are_checked():
    with pytest.raises(ValueError, match=r"shape \(T, 4\)"):
        reference.check_commands(np.zeros((10, 3)))
    with pytest.raises(ValueError, match=r"inside \[0, 1\]"):
        reference.check_commands(np.full((10, 4), 1.5))
    with pytest.raises(ValueError, match="n_elements must be >= 8"):
        reference.Rod(4)


@pytest.mark.slow  # a fresh venv compiles PyElastica's numba kernels first (about 90 s on 2 cores), then seconds
def test_the_rod_hangs_and_bends_toward_the_pulled_tendon():
    rest = np.zeros((STEPS, 4))
    nodes = reference.simulate(rest, n_elements=ELEMENTS)
    assert nodes.shape == (4 * STEPS + 1, ELEMENTS + 1, 3) and np.isfinite(nodes).all()
    tip = nodes[:, -1]
    hang = tm.BASE_HEIGHT - tm.TRUNK_LENGTH
    assert np.abs(tip[:, :2]).max() < 1e-6 and hang - 0.01 < tip[:, 2].min() <= tip[:, 2].max() < hang  # stretched
    for j, axis, sign in ((0, 0, 1), (3, 1, -1)):  # tendon 0 toward +x (the user), tendon 3 toward -y
        u = np.zeros((STEPS, 4))
        u[6:, j] = 0.6
        tip = reference.simulate(u, n_elements=ELEMENTS)[-1, -1]
        assert sign * tip[axis] > 0.03 and abs(tip[1 - axis]) < 0.01, (j, tip)
        assert tip[2] > hang  # a bend lifts the tip
    markers = reference.markers(nodes[:-1], noise=reference.MARKER_NOISE_M, rng=np.random.default_rng(0))
    assert markers.shape == (4 * STEPS, len(reference.MARKER_S), 3)
    clean = reference.markers(nodes[:-1], noise=0.0)
    assert np.allclose(clean[:, -1], nodes[:-1, -1]) and 0.3e-3 < np.std(markers - clean) < 0.7e-3


@pytest.mark.slow
def test_the_quick_generation_writes_recordings_that_read_back(tmp_path):
    from experiments import trunk_reference

    out = tmp_path / "ref"
    assert trunk_reference.main(["--quick", "--out", str(out)]) == 0
    assert trunk_reference.verify(out) == []
    from jgrounding.sim.recordings import load_recordings

    [rec] = load_recordings(out / "train")
    assert rec.markers.shape == (4 * trunk_reference.QUICK_STEPS, 4, 3) and rec.marker_names[-1] == "tip"
    (out / "train" / rec.name).with_suffix(".csv").write_text("changed\n")
    assert trunk_reference.verify(out)[0] == f"changed or missing: train/{rec.name}.csv"
