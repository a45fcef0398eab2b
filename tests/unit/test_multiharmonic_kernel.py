"""The restructured element kernel of the multi-harmonic model against the straightforward one.

``kernels/mh_element.py``'s :func:`mh_elements` forms the tangent harmonic pair by harmonic pair
in contiguous, vectorised loops (docs/harmonics.md, section 10.4); the test oracle
``tests/unit/mh_reference.py`` keeps the element-by-element, node-pair-by-node-pair kernel it replaced. On random
non-axisymmetric states, with and without an imperfection, Q4 and Q9, several harmonic sets, the
energy, residuals and tangents must agree to round-off, 1e-12 of each array's largest entry (the
fast kernel forms the phi-moments of the tangent from Fourier moments and mirrors the element
matrix's upper triangle; the oracle sums every pair's terms over the phi points).
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


@pytest.mark.parametrize("hn", [[0, 1, 2, 3, 4], [0, 2, 4, 6, 8], [0, 3, 6]])
def test_pair_moments_are_the_pair_by_pair_sums(hn):
    """The phi-moments of every harmonic pair from the Fourier moments of the pointwise tangent
    (``_pair_moments``) against the direct sums ``sum_j w_j t_k t_l D_j`` (``t = cos`` for the
    components ``c < 5``, ``sin`` after), for all harmonics and for a selection of them."""
    from snapjump_kernels.mh_basis import phi_rule
    from snapjump_kernels.mh_element import _fourier_tables, _pair_moments

    hn = np.asarray(hn, np.int64)
    n1, K = int(hn[1]), len(hn)
    phis, wphi = phi_rule(n1, 2 * (int(hn[-1]) // n1) + 2)
    rng = np.random.default_rng(5)
    nq, nphi = 4, len(phis)
    D = rng.standard_normal((nq, nphi, 81))
    for sel in (np.ones(K, np.bool_), np.arange(K) % 2 == 1):
        Dtp = np.full((K * (K + 1) // 2, nq, 81), np.nan)
        _pair_moments(D, _fourier_tables(phis, wphi, hn, sel), hn, sel, Dtp)
        pairs = [(k, l) for k in range(K) for l in range(k, K)]  # the kernel's pair order
        comp_cos = np.arange(9)[:, None] < 5
        for p, (k, l) in enumerate(pairs):
            if sel[k] and sel[l]:
                tk = np.where(comp_cos, np.cos(hn[k] * phis), np.sin(hn[k] * phis))  # (9, nphi)
                tl = np.where(comp_cos, np.cos(hn[l] * phis), np.sin(hn[l] * phis))
                w = (wphi[None, None, :] * tk[:, None, :] * tl[None, :, :]).reshape(81, nphi)
                direct = np.einsum("xj,qjx->qx", w, D)
                np.testing.assert_allclose(Dtp[p], direct, rtol=0, atol=1e-13 * np.abs(D).max() * nphi)
