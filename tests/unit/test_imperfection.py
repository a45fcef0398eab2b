"""An initial geometric imperfection in the multi-harmonic model (snapjump_cli.fe.branch.model).

Checks, each able to fail on a wrong term:

* a zero imperfection is the perfect model (energy, residual, tangent, volume);
* a homothetic imperfection ``x0 = (1 + e) X`` scales the body: the energy of the deformation
  ``x = (1 + e)(X + u')`` is ``(1 + e)^3`` that of the perfect body under ``u'``, and so is the
  cavity volume (a non-axisymmetric ``u'``; this holds only if the pressure mass, the
  dilatation and the energy all carry ``det F0``);
* residual, ``dV/du`` and tangent are the derivatives of energy and volume (central differences)
  for a non-axisymmetric imperfection, Q4 and Q9;
* an imperfection that folds the body is refused.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch.model import MultiHarmonicModel
from tests.unit.test_harmonics_fd import _model, _state
from tests.unit.test_multiharmonic import _smooth_modes, assert_derivatives_of_the_energy


def _imperfection(mh: MultiHarmonicModel, scale: float) -> np.ndarray:
    """Nodal amplitudes (nn, nc) of smooth imperfections in every kept harmonic (axis conditions
    enforced by the model's own free-vector round trip)."""
    M = mh.base
    U = mh.embed(np.zeros(M.n), _smooth_modes(M, list(mh.hn), scale, shift=1.1))
    return mh.amplitudes(U)


def test_zero_imperfection_is_the_perfect_model():
    M = _model(2)
    hn = [0, 1, 2]
    a = MultiHarmonicModel(M, hn)
    b = MultiHarmonicModel(M, hn, imperfection=np.zeros((M.X.shape[0], a.nc)))
    U = a.embed(_state(M, 3), _smooth_modes(M, hn, 0.02))
    la, lb = a.linearize(U, 0.4), b.linearize(U, 0.4)
    assert lb.E == pytest.approx(la.E, rel=1e-14)
    assert lb.V == pytest.approx(la.V, rel=1e-14)
    np.testing.assert_allclose(lb.R, la.R, rtol=0, atol=1e-13 * np.abs(la.R).max())
    Ka, Kb = la.stiffness().toarray(), lb.stiffness().toarray()
    np.testing.assert_allclose(Kb, Ka, rtol=0, atol=1e-13 * np.abs(Ka).max())


@pytest.mark.parametrize("order", [1, 2])
def test_homothetic_imperfection_scales_energy_and_volume(order):
    M = _model(order)
    hn = [0, 1, 2]
    eps = 0.07
    perfect = MultiHarmonicModel(M, hn)
    A0 = np.zeros((M.X.shape[0], perfect.nc))
    A0[:, :2] = eps * M.X
    imperfect = MultiHarmonicModel(M, hn, imperfection=A0)
    U1 = perfect.embed(_state(M, 5), _smooth_modes(M, hn, 0.03))
    W1, V1 = perfect.energy_volume(U1)
    W2, V2 = imperfect.energy_volume((1.0 + eps) * U1)
    off = M.V_offset
    assert W2 == pytest.approx((1.0 + eps) ** 3 * W1, rel=1e-12)
    assert V2 - off == pytest.approx((1.0 + eps) ** 3 * (V1 - off), rel=1e-12)
    # and the imperfect body is stress-free where the perfect one is
    assert imperfect.energy(np.zeros(imperfect.n)) == pytest.approx(0.0, abs=1e-14)
    assert abs(W1) > 1e-3  # the state is strained: the comparison means something


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("hn", [[0, 1, 2], [0, 2, 4]])
def test_imperfect_residual_and_tangent_are_the_derivatives_of_the_energy(order, hn):
    M = _model(order)
    mh0 = MultiHarmonicModel(M, hn)
    mh = MultiHarmonicModel(M, hn, imperfection=_imperfection(mh0, 0.05))
    assert np.abs(mh.A_imp).max() > 1e-3
    assert np.abs(mh.Jimp - 1.0).max() > 1e-3  # the imperfection changes the volume element
    p = 0.6
    U = mh.embed(_state(M, 4), _smooth_modes(M, hn, 0.02))
    v = mh.embed(0.01 * np.random.default_rng(5).standard_normal(M.n), _smooth_modes(M, hn, 1.0, shift=0.4))
    assert_derivatives_of_the_energy(mh, U, v, p)
    # the imperfection changes the answer (the test is not of the perfect model)
    assert abs(mh.energy(U) - mh0.energy(U)) > 1e-4 * abs(mh0.energy(U))


def test_an_imperfection_that_folds_the_body_is_refused():
    M = _model(2)
    A0 = np.zeros((M.X.shape[0], 5))
    A0[:, 1] = -1.5 * M.X[:, 1]  # z -> -z / 2: inside out (det F0 = -1/2)
    with pytest.raises(ValueError, match="folds the body"):
        MultiHarmonicModel(M, [0, 1], imperfection=A0)
