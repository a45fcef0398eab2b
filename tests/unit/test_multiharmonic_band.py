"""The multi-harmonic model's band assembly and factorisation (docs/harmonics.md, section 10.4).

:func:`snapjump_kernels.banded.band_ldlt_into` and :func:`~snapjump_kernels.banded.bordered_factor_into`
factorise a band into a buffer the caller keeps, copying each column just before it is first
used: they must return the factors, inertia, ``K^-1 b`` and Schur complement of ``band_ldlt`` and
``bordered_factor`` (which factorise a copy) *bit for bit*, which the tests check with
``array_equal`` (and, independently, against dense algebra). The fused assembly
(:func:`snapjump_kernels.mh_element.mh_assemble_band`) must give the band that the element
matrices of :func:`~snapjump_kernels.mh_element.mh_elements` scattered by ``scatter_band`` give,
also bit for bit, and the model's reused band buffers must never hand out a band still in use.
"""
from __future__ import annotations

import gc

import numpy as np
import pytest

from snapjump_cli.fe.axisym.model import Linearization, factor_bordered
from snapjump_cli.fe.branch.model import MultiHarmonicModel
from snapjump_kernels.banded import band_ldlt, band_ldlt_into, bordered_factor, bordered_factor_into
from snapjump_kernels.calls import mh_cavity, mh_elements, scatter_band, scatter_vector
from tests.unit.test_banded import _extents_of, _random_profile_matrix, _to_band
from tests.unit.test_harmonics_fd import _model, _state
from tests.unit.test_imperfection import _imperfection
from tests.unit.test_multiharmonic import _smooth_modes


def _profile(n: int, kl: int, seed: int, shift: float):
    A = _random_profile_matrix(n, kl, seed, shift)
    return A, _to_band(A, kl), _extents_of(A, kl)


@pytest.mark.parametrize("n, kl, seed", [(120, 9, 3), (97, 23, 5), (61, 60, 7), (6, 5, 1), (13, 2, 2)])
@pytest.mark.parametrize("shift", [8.0, 0.5, -1.5])  # positive definite / a few / many negative eigenvalues
def test_band_ldlt_into_is_band_ldlt_bit_for_bit(n, kl, seed, shift):
    A, ab, ext = _profile(n, kl, seed, shift)
    f0, f1, src = ab.copy(), np.zeros_like(ab), ab.copy()
    ok0, neg0 = band_ldlt(f0, ext)
    ok1, neg1 = band_ldlt_into(f1, ext, src)
    assert ok0 and ok1 and np.array_equal(src, ab)  # (the source is not changed)
    assert neg1 == neg0 == int(np.sum(np.linalg.eigvalsh(A) < 0))  # the inertia (Sylvester)
    assert np.array_equal(f1, f0)
    if shift < 8.0:
        assert neg1 > 0  # indefinite indeed


def test_band_ldlt_into_reports_a_zero_pivot_as_band_ldlt_does():
    A = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 1.0], [0.0, 1.0, 2.0]])  # the second pivot is 0
    ab = _to_band(A, 2)
    ext = _extents_of(A, 2)
    assert band_ldlt_into(np.zeros_like(ab), ext, ab)[0] is False
    assert band_ldlt(ab.copy(), ext)[0] is False


@pytest.mark.parametrize("shift", [8.0, 0.5])
def test_bordered_factor_into_is_bordered_factor_and_solves(shift):
    from snapjump_cli.fe.axisym.model import BorderedSolver

    n, kl = 150, 17
    A, ab, ext = _profile(n, kl, 11, shift)
    rng = np.random.default_rng(2)
    b, c, d = rng.standard_normal(n), rng.standard_normal(n), 0.3
    ok0, neg0, fac0, Kib0, s0 = bordered_factor(ab, ext, b, c, d)
    fac = np.zeros_like(ab)
    ok1, neg1, Kib1, s1 = bordered_factor_into(ab, ext, b, c, d, fac)
    assert ok0 and ok1 and neg0 == neg1
    assert np.array_equal(fac, fac0) and np.array_equal(Kib1, Kib0) and s1 == s0
    # the factors solve the bordered system (against dense algebra)
    Bm = np.block([[A, b[:, None]], [c[None, :], np.array([[d]])]])
    rhs = rng.standard_normal(n + 1)
    x = BorderedSolver(fac, ab, b, c, d, n, neg1, ext, Kib1, s1).solve(rhs)
    x_dense = np.linalg.solve(Bm, rhs)
    assert np.linalg.norm(x - x_dense) <= 1e-12 * np.linalg.norm(x_dense) * np.linalg.cond(Bm) ** 0.5


def test_bordered_solve_at_a_limit_point():
    """``K`` singular to ~1e-9 of its scale (a limit point under pressure control), the bordered
    matrix regular (its border sees the null vector): the new factors solve it as the old ones do,
    bit for bit, and as dense algebra does."""
    from snapjump_cli.fe.axisym.model import BorderedSolver

    n, kl = 140, 12
    A0, _, ext = _profile(n, kl, 17, 0.5)
    lam, V = np.linalg.eigh(A0)
    k = int(np.argmin(np.abs(lam)))
    scale = np.abs(lam).max()
    A = A0 - (lam[k] - 1e-9 * scale) * np.eye(n)  # one eigenvalue 1e-9 of the scale
    ab = _to_band(A, kl)
    v = V[:, k]
    rng = np.random.default_rng(5)
    b = v + 0.1 * rng.standard_normal(n)
    c = v + 0.1 * rng.standard_normal(n)
    d = 0.0
    ok0, neg0, fac0, Kib0, s0 = bordered_factor(ab, ext, b, c, d)
    fac = np.zeros_like(ab)
    ok1, neg1, Kib1, s1 = bordered_factor_into(ab, ext, b, c, d, fac)
    assert ok0 and ok1 and neg1 == neg0 == int(np.sum(np.linalg.eigvalsh(A) < 0))
    assert np.array_equal(fac, fac0) and np.array_equal(Kib1, Kib0) and s1 == s0
    rhs = rng.standard_normal(n + 1)
    x1 = BorderedSolver(fac, ab, b, c, d, n, neg1, ext, Kib1, s1).solve(rhs)
    x0 = BorderedSolver(fac0, ab, b, c, d, n, neg0, ext, Kib0, s0).solve(rhs)
    assert np.array_equal(x1, x0)
    Bm = np.block([[A, b[:, None]], [c[None, :], np.array([[d]])]])
    assert np.linalg.cond(Bm) < 1e-6 / 1e-9  # regular, though K is nearly singular
    x_dense = np.linalg.solve(Bm, rhs)
    assert np.linalg.norm(x1 - x_dense) <= 1e-9 * np.linalg.norm(x_dense)


def _mh_state(order: int, hn, imperfect: bool):
    M = _model(order)
    mh = MultiHarmonicModel(M, hn)
    if imperfect:
        mh = MultiHarmonicModel(M, hn, imperfection=_imperfection(mh, 0.04))
    rng = np.random.default_rng(3 + order + len(hn))
    U = mh.embed(_state(M, 4), _smooth_modes(M, hn, 0.03)) + 1e-3 * rng.standard_normal(mh.n)
    return mh, U


def _unfused(mh: MultiHarmonicModel, U: np.ndarray, p: float) -> Linearization:
    """The model's linearisation as it was formed before 2026-11-28: the element matrices
    (:func:`mh_elements`, ``want = 2``) and the cavity's scattered by ``scatter_band`` into a fresh
    band."""
    M = mh.base
    A = np.ascontiguousarray(mh.total_amplitudes(U))
    E, ok, re, Ke = mh_elements(A, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np, M.Minv,
                                mh.hn, mh.phis, mh.wphi, 2, mh.Fi, mh.Jimp, mh.Minvp)
    assert ok
    Vf, ge, He = mh_cavity(M.X, A, M.edges, mh.hn, mh.phis, mh.wphi, 2)
    R, g = np.zeros(mh.n), np.zeros(mh.n)
    scatter_vector(re, mh.edofs, mh.ecoef, 1.0, R)
    scatter_vector(ge, mh.gdofs, mh.gcoef, 1.0, g)
    R -= p * g
    ab = np.zeros((mh.n, mh.kl + 1))
    scatter_band(Ke, mh.edofs, mh.ecoef, 1.0, ab)
    scatter_band(He, mh.gdofs, mh.gcoef, -float(p), ab)
    return Linearization(mh, U, p, R, g, ab.ravel(), Vf + mh.V_offset, E)


def _factor_unfused(lin: Linearization, c_u, c_p, shift=0.0):
    """The factorisation of before 2026-11-28: ``bordered_factor`` of a copy of the band."""
    data = lin.data.copy()
    if shift:
        data[lin.model.diag_pos] += shift
    return factor_bordered(lin.model, data, -lin.g, c_u, c_p)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("hn", [[0], [0, 1, 2], [0, 2, 4, 6], [0, 1, 2, 3, 4]])
@pytest.mark.parametrize("imperfect", [False, True])
def test_fused_assembly_and_factorisation_are_the_unfused_ones_bit_for_bit(order, hn, imperfect):
    mh, U = _mh_state(order, hn, imperfect)
    p = 0.37
    new = mh.linearize(U, p)
    old = _unfused(mh, U, p)
    rng = np.random.default_rng(1)
    c_u, c_p = rng.standard_normal(mh.n), 0.2
    s_old = _factor_unfused(old, c_u, c_p)
    # harmonic 1 of a free body without a gauge: singular (its rigid modes); then shifted
    shift = 0.0 if s_old is not None else 1e-3 * float(np.abs(old.diag_abs()).max())
    if s_old is None:
        s_old = _factor_unfused(old, c_u, c_p, shift)
    assert new.E == old.E and new.V == old.V
    assert np.array_equal(new.R, old.R) and np.array_equal(new.g, old.g)
    assert np.abs(old.data).max() > 0 and np.array_equal(new.data, old.data)
    s_new = new.factor(c_u, c_p, shift)
    assert s_new is not None and s_old is not None
    assert s_new.n_negative == s_old.n_negative and s_new.schur == s_old.schur
    assert np.array_equal(s_new.fac, s_old.fac) and np.array_equal(s_new.Kib, s_old.Kib)
    rhs = rng.standard_normal(mh.n + 1)
    assert np.array_equal(s_new.solve(rhs), s_old.solve(rhs))


def test_band_buffers_in_use_are_not_handed_out_again():
    mh, U = _mh_state(2, [0, 2, 4], False)  # no rigid mode (harmonic 1): the tangent is regular
    p = 0.2
    lin1 = mh.linearize(U, p)
    first = lin1.data.copy()
    lin2 = mh.linearize(U + 1e-3, p)  # lin1's band is still referred to: a new buffer
    assert not np.shares_memory(lin1.data, lin2.data)
    assert np.array_equal(lin1.data, first)
    c_u = np.ones(mh.n)
    s1 = lin1.factor(c_u, 0.0)
    for arr in (lin1.data, lin2.data):
        assert not np.shares_memory(s1.fac, arr)
    fac1 = s1.fac.copy()
    lin3 = mh.linearize(U - 1e-3, p)
    s3 = lin3.factor(c_u, 0.0)
    assert np.array_equal(s1.fac, fac1) and np.array_equal(lin1.data, first)  # untouched
    for arr in (lin1.data, lin2.data, s1.fac, s3.fac):
        assert arr is s3.fac or not np.shares_memory(s3.fac, arr)
    # a band no longer referred to is reused, and is then the band of the new state
    addr = lin2.data.__array_interface__["data"][0]
    del lin2
    gc.collect()
    lin4 = mh.linearize(U + 2e-3, p)
    assert lin4.data.__array_interface__["data"][0] == addr
    ref = _unfused(mh, U + 2e-3, p)
    assert np.array_equal(lin4.data, ref.data)
    # the band outside the envelope is zero (a reused buffer included): the stiffness is exact
    assert (abs(lin4.stiffness() - ref.stiffness())).max() == 0.0


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("hn, block", [([0, 1, 2, 3, 4], [1, 3]), ([0, 1, 2, 3, 4], [0, 2, 4]), ([0, 2, 4, 6], [2, 6])])
@pytest.mark.parametrize("imperfect", [False, True])
def test_a_block_of_the_tangent_is_that_block_of_the_whole_bit_for_bit(order, hn, block, imperfect):
    """``block_band`` forms only the rows of some harmonics (``mh_assemble_band`` with ``sel``):
    at any state, coupled or not, its entries are those of the whole tangent's block, the same
    sums in the same order."""
    from snapjump_cli.fe.axisym.model import band_csr

    mh, U = _mh_state(order, hn, imperfect)
    p = 0.37
    whole = mh.linearize(U, p).stiffness().tocsr()
    ab, blk = mh.block_band(U, p, block)
    assert 0 < blk.n < mh.n and blk.kl < mh.kl
    B, W = band_csr(ab), whole[blk.dofs][:, blk.dofs]
    assert (B != W).nnz == 0 and abs(W).max() > 0


def test_a_factorisation_given_up_at_its_second_negative_pivot_decides_as_the_whole_one():
    """``Linearization.factor(..., max_negative=1)`` of the multi-harmonic model (the descent's test
    of a shifted system): ``None`` exactly where the whole factorisation has two or more negative
    pivots (then no shift makes it positive definite on the constraint), the same solver bit for bit
    otherwise, and counted as a factorisation either way."""
    mh, U = _mh_state(2, [0, 2, 4], False)  # (not an equilibrium: 77 negative pivots unshifted)
    lin = mh.linearize(U, 0.3)
    seen = set()
    for s in (0.0, 2.0, 5.0, 30.0):
        shift = s * lin.diag_abs()
        whole = lin.factor(lin.g, 0.0, shift=shift)
        n0, g0 = mh.n_factorizations, mh.n_given_up
        upto = lin.factor(lin.g, 0.0, shift=shift, max_negative=1)
        assert mh.n_factorizations == n0 + 1
        assert mh.n_given_up == g0 + (whole.n_negative >= 2)
        seen.add(min(whole.n_negative, 2))
        if whole.n_negative >= 2:
            assert upto is None
        else:
            assert upto.n_negative == whole.n_negative and upto.schur == whole.schur
            assert np.array_equal(upto.Kib, whole.Kib) and np.array_equal(upto.fac, whole.fac)
    assert seen == {0, 1, 2}  # each kind of case reached
