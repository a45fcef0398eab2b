"""The cubic Hermite interpolation shared by the continuation, the snap location and the metrics."""
import numpy as np
import pytest

from snapjump_cli.fe.continuation import hermite


def test_basis_reproduces_cubics():
    rng = np.random.default_rng(3)
    c = rng.normal(size=4)
    y = lambda t: c[0] + c[1] * t + c[2] * t**2 + c[3] * t**3  # noqa: E731
    dy = lambda t: c[1] + 2 * c[2] * t + 3 * c[3] * t**2  # noqa: E731
    t = np.linspace(0.0, 1.0, 11)
    h00, h10, h01, h11 = hermite.basis(t)
    np.testing.assert_allclose(h00 * y(0) + h10 * dy(0) + h01 * y(1) + h11 * dy(1), y(t), atol=1e-14)


def test_basis_end_conditions():
    h = np.array(hermite.basis(np.array([0.0, 1.0])))  # (4 weights, 2 ends)
    np.testing.assert_array_equal(h, [[1, 0], [0, 0], [0, 1], [0, 0]])
    eps = 1e-6  # the derivative weights: slope 1 at their own end, 0 at the other
    d = (np.array(hermite.basis(np.array([eps, 1.0]))) - np.array(hermite.basis(np.array([0.0, 1.0 - eps])))) / eps
    np.testing.assert_allclose(d, [[0, 0], [1, 0], [0, 0], [0, 1]], atol=1e-5)


def test_power_coefficients_match_basis():
    rng = np.random.default_rng(4)
    y0, d0, y1, d1 = rng.normal(size=4)
    c = hermite.power_coefficients(y0, d0, y1, d1)
    t = np.linspace(-0.5, 1.5, 9)
    h00, h10, h01, h11 = hermite.basis(t)
    np.testing.assert_allclose(np.polyval(c[::-1], t), h00 * y0 + h10 * d0 + h01 * y1 + h11 * d1, atol=1e-13)


def test_segment_maxima_against_dense_sampling():
    rng = np.random.default_rng(5)
    y0, d0, y1, d1 = rng.normal(size=(4, 200))
    d0[:5] = 0.0  # flat starts, a quadratic (c3 = 0) and a straight line among the random cubics
    y0[5], d0[5], y1[5], d1[5] = 0.0, 1.0, 0.0, -1.0  # y = t - t^2: maximum 0.25 at t = 0.5
    y0[6], d0[6], y1[6], d1[6] = 0.0, 2.0, 2.0, 2.0  # y = 2t
    t = np.linspace(0.0, 1.0, 20001)[:, None]
    h00, h10, h01, h11 = hermite.basis(t)
    dense = (h00 * y0 + h10 * d0 + h01 * y1 + h11 * d1).max(axis=0)
    got = hermite.segment_maxima(y0, d0, y1, d1)
    assert got[5] == 0.25 and got[6] == 2.0
    assert np.all(got >= dense - 1e-14)  # never below a sampled value
    np.testing.assert_allclose(got, dense, atol=1e-8)  # and the sampling's own error is ~1e-9


def test_interpolate_and_first_root_on_a_known_cubic():
    """``y(t) = t^3 - t / 4`` on [0, 1] (``y(0) = 0``, ``y'(0) = -1/4``, ``y(1) = 3/4``, ``y'(1) = 11/4``):
    the interpolation reproduces it (arrays alike, with the derivatives given per unit ``s`` of a
    step ``h``), its zero inside the step is ``t = 1/2``, its minimum ``t = 1/sqrt(12)``, and a value
    it takes nowhere inside gives ``None``."""
    y0, d0, y1, d1 = 0.0, -0.25, 0.75, 2.75
    for t in (0.0, 0.3, 0.5, 1.0):
        assert hermite.interpolate(t, y0, d0, y1, d1) == pytest.approx(t**3 - t / 4, abs=1e-15)
        assert hermite.interpolate(t, y0, d0 / 2.0, y1, d1 / 2.0, h=2.0) == pytest.approx(t**3 - t / 4, abs=1e-15)
    v = hermite.interpolate(0.3, np.array([y0, 1.0]), np.array([d0, 0.0]), np.array([y1, 1.0]), np.array([d1, 0.0]))
    np.testing.assert_allclose(v, [0.3**3 - 0.075, 1.0], atol=1e-15)
    assert hermite.first_root(y0, d0, y1, d1) == pytest.approx(0.5, abs=1e-12)
    assert hermite.first_root(y0, d0, y1, d1, value=None) == pytest.approx(12 ** -0.5, abs=1e-12)
    assert hermite.first_root(y0, d0, y1, d1, value=2.0) is None
