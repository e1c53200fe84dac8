"""Properties of the Catmull-Rom actuation space (Sec. III-B, SPEC §3)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from jgrounding.actuation import splines

finite = st.floats(-2.0, 2.0, allow_nan=False, width=32)


@given(p=st.integers(2, 8), c=st.data())
def test_fit_inverts_reconstruct(p, c):
    ctrl = c.draw(arrays(np.float32, (3, 4, p), elements=finite))
    back = splines.fit(splines.reconstruct(ctrl), num_controls=p)
    np.testing.assert_allclose(back, ctrl, atol=2e-4)


@given(p=st.integers(2, 8), c=st.data())
def test_interpolates_controls_at_knots(p, c):
    ctrl = c.draw(arrays(np.float32, (4, p), elements=finite))
    num_steps = 10 * (p - 1) + 1  # knots k/(P-1) fall exactly on grid points 10k
    u = splines.reconstruct(ctrl, num_steps=num_steps)
    np.testing.assert_allclose(u[::10].T, ctrl, atol=1e-5)


@given(p=st.integers(3, 7), c=st.data())
def test_c1_at_segment_joints(p, c):
    ctrl = c.draw(arrays(np.float64, (1, p), elements=st.floats(-1, 1)))
    n = 2000 * (p - 1) + 1
    u = splines.basis_np(n, p) @ ctrl[0]  # float64 basis: finite differences need it
    h = 1.0 / (n - 1)
    for k in range(1, p - 1):
        i = 2000 * k
        left = (3 * u[i] - 4 * u[i - 1] + u[i - 2]) / (2 * h)  # second-order one-sided slopes
        right = (-3 * u[i] + 4 * u[i + 1] - u[i + 2]) / (2 * h)
        assert abs(left - right) < 1e-4 * (1 + abs(left))  # slopes match: no kink


def test_linear_trajectory_is_reproduced_exactly():
    tau = np.linspace(0, 1, 150)
    u = np.stack([0.1 + 0.8 * tau, 0.9 - 0.5 * tau, 0.3 * np.ones_like(tau), tau], -1)
    c = splines.fit(u, num_controls=5)
    np.testing.assert_allclose(splines.reconstruct(c), u, atol=1e-5)


def test_fit_error_falls_with_more_controls():
    tau = np.linspace(0, 1, 150)
    u = 0.5 + 0.3 * np.stack([np.sin(2 * np.pi * f * tau + f) for f in (1.0, 1.5, 0.7, 2.0)], -1)
    errs = [float(jnp.sqrt(jnp.mean((splines.reconstruct(splines.fit(u, p)) - u) ** 2))) for p in (3, 4, 6, 8, 12)]
    assert all(a > b for a, b in zip(errs, errs[1:])), errs
    assert errs[-1] < 0.02


def test_batch_shapes_and_transforms():
    u = jnp.zeros((2, 3, 150, 4))
    c = splines.fit(u, num_controls=6)
    assert c.shape == (2, 3, 4, 6)
    assert splines.reconstruct(c).shape == (2, 3, 150, 4)
    f = jax.jit(jax.vmap(lambda x: splines.reconstruct(splines.fit(x))))
    assert f(jnp.ones((5, 150, 4))).shape == (5, 150, 4)


def test_gradients_are_finite():
    u = jnp.linspace(0, 1, 600).reshape(150, 4)
    g = jax.grad(lambda c: jnp.sum(splines.reconstruct(c) ** 2))(splines.fit(u))
    assert g.shape == (4, 4) and bool(jnp.all(jnp.isfinite(g)))


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: splines.fit(np.zeros((150, 4)), num_controls=1), "num_controls"),
        (lambda: splines.fit(np.zeros((3, 4)), num_controls=4), "num_steps"),
        (lambda: splines.fit(np.zeros(150)), "shape"),
        (lambda: splines.reconstruct(np.zeros(4)), "shape"),
        (lambda: splines.fit(np.full((150, 4), np.nan)), "NaN"),
        (lambda: splines.reconstruct(np.array([[0.0, np.inf]])), "NaN"),
    ],
)
def test_bad_inputs_raise_clear_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()
