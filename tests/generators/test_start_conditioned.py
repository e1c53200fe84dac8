"""Start-conditioned sampling (issue #23): the first spline control is inpainted to the robot's command
during the flow integration, so a new motion is generated from the state the robot is in."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jgrounding as jg
from jgrounding import safety
from jgrounding.actuation import splines
from jgrounding.config import SampleConfig
from jgrounding.generators import flows, methods
from jgrounding.policy import sampling


@pytest.fixture(scope="module")
def mid_motion():
    """The command at t = 2.5 s of another sample: a state mid-motion."""
    return jg.sample(jax.random.key(1), "greeting", "pronounced")[75]


def test_rf_sample_inpaints_known_coordinates_exactly():
    eps = jax.random.normal(jax.random.key(0), (3, 8))
    target = jnp.linspace(-1, 1, 24).reshape(3, 8)
    mask = jnp.arange(8) % 4 == 0
    seen = []

    def velocity(x, t):  # a field that would move every coordinate away from the target
        seen.append(t)
        return jnp.ones_like(x) * 3.0

    for sampler in flows.RF_SAMPLERS:
        out = flows.rf_sample(velocity, eps, steps=5, sampler=sampler, known=(mask, target))
        np.testing.assert_allclose(np.asarray(out)[:, ::4], np.asarray(target)[:, ::4], atol=1e-6)
        free = np.asarray(out)[:, 1::4]  # the others follow the field: eps + 3 over lambda in [0, 1]
        np.testing.assert_allclose(free, np.asarray(eps)[:, 1::4] + 3.0, atol=1e-5)
    plain = flows.rf_sample(velocity, eps, steps=5)
    np.testing.assert_allclose(np.asarray(plain), np.asarray(eps) + 3.0, atol=1e-5)


def test_ungated_actuation_is_a_spline_through_the_start(mid_motion):
    trained, emb = sampling.load()
    start = np.stack([mid_motion, np.zeros(4, np.float32), np.full(4, 0.9, np.float32)])
    cond, z = jnp.asarray(emb[[0, 2, 5]]), jnp.array([1, 0, 3], jnp.int32)
    u = trained.actuation(jax.random.key(3), cond, z, SampleConfig(steps=10), start=jnp.asarray(start))
    u = np.asarray(u)
    np.testing.assert_allclose(u[:, 0], start, atol=1e-5)  # R(c; 0) = c[:, 0]: generated from there
    refit = np.asarray(splines.reconstruct(splines.fit(jnp.asarray(u), num_controls=trained.num_controls)))
    np.testing.assert_allclose(refit, u, atol=1e-4)  # a spline of the model's controls, nothing blended on


@pytest.mark.parametrize("steps, k", [(50, 1), (50, 6), (2, 3)])  # steps=2: the shipped few-step model
def test_public_sampler_starts_at_current_and_passes_the_gate(mid_motion, steps, k):
    u = jg.sample(jax.random.key(2), "comforting", "subtle", k, steps=steps, current=mid_motion, start_conditioned=True)
    u = u.reshape(-1, 150, 4)
    np.testing.assert_allclose(u[:, 0], np.broadcast_to(mid_motion, (len(u), 4)), atol=1e-6)
    assert safety.is_safe(u, current=mid_motion)


def test_sequences_and_rest():
    u = jg.sample(jax.random.key(4), ["greeting", "nodding"], "moderate", 2, current="rest", start_conditioned=True)
    assert u.shape == (2, 2, 150, 4)
    assert np.abs(u[:, :, 0]).max() <= 1e-6
    assert safety.is_safe(u, current=np.zeros(4))


def test_deterministic_per_key_and_not_the_blend(mid_motion):
    a = jg.sample(jax.random.key(5), "playful_swing", "emphatic", current=mid_motion, start_conditioned=True)
    b = jg.sample(jax.random.key(5), "playful_swing", "emphatic", current=mid_motion, start_conditioned=True)
    blend = jg.sample(jax.random.key(5), "playful_swing", "emphatic", current=mid_motion)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - blend).max() > 1e-3  # generated from the state, not the blended trajectory


def test_bad_options_are_refused(mid_motion):
    with pytest.raises(ValueError, match="needs the robot's current command"):
        jg.sample(jax.random.key(0), "greeting", "moderate", current=None, start_conditioned=True)
    with pytest.raises(ValueError, match="start_conditioned must be True or False"):
        jg.sample(jax.random.key(0), "greeting", "moderate", current=mid_motion, start_conditioned="yes")
    with pytest.raises(ValueError, match="methods that can: tuple_spline_rf"):
        methods.check_start_conditioning("tuple_spline_ddpm")
    with pytest.raises(ValueError, match="current command must lie in"):
        jg.sample(jax.random.key(0), "greeting", "moderate", current=np.full(4, 1.5), start_conditioned=True)
