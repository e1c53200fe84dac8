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
