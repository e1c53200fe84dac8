import numpy as np
import pytest

from jgrounding import safety


def test_emit_clamps_and_rate_limits():
    u = np.zeros((150, 4), np.float32)
    u[50:] = 3.0
    u[:10, 1] = -1.0
    out = safety.emit(u)
    assert out.dtype == np.float32 and out.shape == (150, 4)
    assert safety.is_safe(out)
    assert out[-1, 0] == pytest.approx(1.0)


def test_valid_trajectory_is_unchanged():
    u = 0.5 + 0.3 * np.sin(np.linspace(0, 6, 150))[:, None] * np.ones(4)
    np.testing.assert_allclose(safety.emit(u), u, atol=1e-6)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_is_refused(bad):
    u = np.zeros((150, 4))
    u[7, 2] = bad
    with pytest.raises(safety.UnsafeActuationError, match="non-finite"):
        safety.emit(u)


def test_wrong_shape_is_refused():
    with pytest.raises(safety.UnsafeActuationError, match="shape"):
        safety.emit(np.zeros((150, 3)))


def _jumpy(seed):
    """A trajectory that starts far from rest and ends far from where it started."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, 150)[:, None]
    a, b = rng.uniform(0, 1, (2, 4))
    return (a + (b - a) * t).astype(np.float32)


def test_blend_from_rest_bounds_the_first_step():
    u = np.full((150, 4), 0.2, np.float32)
    u[:, 0] = 0.76  # the beckoning of the issue: tendon 0 starts at 0.76, the robot is at rest
    out = safety.emit(u, current="rest")
    assert safety.is_safe(out, current=np.zeros(4))
    assert not safety.is_safe(safety.emit(u), current=np.zeros(4))  # without current the jump is there
    np.testing.assert_allclose(out[safety.BLEND_STEPS :], u[safety.BLEND_STEPS :], atol=1e-6)  # back on track


def test_blend_weights_fade_from_one_to_zero():
    w = np.asarray(safety.blend_weights(150))
    assert w[0] == pytest.approx(1.0) and w[safety.BLEND_STEPS - 1] > 0 and np.all(w[safety.BLEND_STEPS :] == 0)
    assert np.all(np.diff(w) <= 0) and np.abs(np.diff(w)).max() <= np.pi / (2 * safety.BLEND_STEPS) + 1e-6


def test_stream_of_responses_never_exceeds_the_slew_bound():
    current, stream = "rest", [np.zeros((1, 4), np.float32)]
    for turn in range(12):
        out = safety.emit(_jumpy(turn), current=current)
        stream.append(out)
        current = out[-1]
    steps = np.abs(np.diff(np.concatenate(stream), axis=0))
    assert steps.max() <= safety.MAX_SLEW + 1e-6
    raw = np.concatenate([np.zeros((1, 4))] + [safety.emit(_jumpy(t)) for t in range(12)])
    assert np.abs(np.diff(raw, axis=0)).max() > safety.MAX_SLEW  # the same stream without current jumps


def test_batched_current_and_invalid_current():
    u = np.stack([_jumpy(0), _jumpy(1)])
    out = safety.emit(u, current=np.full(4, 0.5))
    assert safety.is_safe(out, current=np.full(4, 0.5)) and np.all(out[:, 0] == pytest.approx(0.5))
    for bad, err in (("home", "rest"), (np.zeros(3), "shape"), (np.full(4, 1.5), r"\[0, 1\]")):
        with pytest.raises(ValueError, match=err):
            safety.emit(u, current=bad)
    with pytest.raises(safety.UnsafeActuationError, match="NaN"):
        safety.emit(u, current=np.array([0, np.nan, 0, 0]))


def test_a_gated_function_is_clamped_slew_limited_and_refuses_non_finite():
    import jax.numpy as jnp

    fn = safety.gated(lambda scale: scale * jnp.ones((2, 150, 4)).at[:, :75].set(-1.0))
    out = fn(jnp.float32(3.0))
    assert isinstance(out, np.ndarray) and out.dtype == np.float32 and out.shape == (2, 150, 4)
    assert safety.is_safe(out) and out[0, 0, 0] == 0.0 and out[0, -1, 0] == pytest.approx(1.0)
    assert out[0, 75, 0] == pytest.approx(safety.MAX_SLEW)  # slewing up from 0, not jumping to 1
    out[0, 0, 0] = 0.5  # a fresh, writable copy
    with pytest.raises(safety.UnsafeActuationError, match="non-finite"):
        fn(jnp.float32(jnp.nan))
