"""The restructured element kernel of the multi-harmonic model against the straightforward one.

``kernels/mh_element.py``'s :func:`mh_elements` forms the tangent harmonic pair by harmonic pair
in contiguous, vectorised loops (docs/harmonics.md, section 10.4); the test oracle
``tests/unit/mh_reference.py`` keeps the element-by-element, node-pair-by-node-pair kernel it replaced. On random
non-axisymmetric states, with and without an imperfection, Q4 and Q9, several harmonic sets, the
energy, residuals and tangents must agree to round-off (they are formed from the same terms in the
same order: bit for bit today; the test allows 1e-12 of each array's largest entry).
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch.model import MultiHarmonicModel
from tests.unit.test_harmonics_fd import _model, _state
from tests.unit.test_imperfection import _imperfection
from tests.unit.test_multiharmonic import _smooth_modes


def _both(mh: MultiHarmonicModel, U: np.ndarray, p: float, want: int):
    from snapjump_kernels.calls import mh_elements
    from tests.unit.mh_reference import mh_elements_reference

    M = mh.base
    A = np.ascontiguousarray(mh.total_amplitudes(U))
    args = (A, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np, M.Minv, mh.hn, mh.phis,
            mh.wphi, want, mh.Fi, mh.Jimp, mh.Minvp)
    return mh_elements(*args), mh_elements_reference(*args)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("hn", [[0], [0, 1, 2], [0, 2, 4, 6], [0, 1, 2, 3, 4]])
@pytest.mark.parametrize("imperfect", [False, True])
def test_fast_kernel_equals_the_reference(order, hn, imperfect):
    M = _model(order)
    mh = MultiHarmonicModel(M, hn)
    if imperfect:
        mh = MultiHarmonicModel(M, hn, imperfection=_imperfection(mh, 0.04))
    rng = np.random.default_rng(11 + order + len(hn))
    U = mh.embed(_state(M, 4), _smooth_modes(M, hn, 0.03))
    U = U + 1e-3 * rng.standard_normal(mh.n)  # random, non-axisymmetric
    for want in (0, 1, 2):
        (E, ok, re, Ke), (E0, ok0, re0, Ke0) = _both(mh, U, 0.0, want)
        assert ok and ok0
        assert E == pytest.approx(E0, rel=1e-13)
        if want >= 1:
            assert np.abs(re0).max() > 1e-6  # not an equilibrium
            np.testing.assert_allclose(re, re0, rtol=0, atol=1e-12 * np.abs(re0).max())
        if want >= 2:
            assert Ke.shape == Ke0.shape and Ke.shape[1] == M.conn.shape[1] * mh.nc
            scale = np.abs(Ke0).max()
            np.testing.assert_allclose(Ke, Ke0, rtol=0, atol=1e-12 * scale)
            # every entry is compared where it matters: the harmonics do couple at this state
            if len(hn) > 1:
                nc = mh.nc
                cross = Ke0[:, 0, nc - 1]  # harmonic 0 (a of node 0) with the last harmonic's c
                assert np.abs(cross).max() > 1e-8 * scale


def test_a_point_outside_the_gent_domain_is_reported():
    M = _model(2)
    hn = [0, 1, 2]
    mh = MultiHarmonicModel(M, hn)
    U = mh.embed(_state(M, 4), _smooth_modes(M, hn, 50.0))  # far outside the Gent domain
    (E, ok, re, Ke), (E0, ok0, re0, Ke0) = _both(mh, U, 0.0, 2)
    assert not ok and not ok0
