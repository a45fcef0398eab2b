"""Stability of a followed branch outside its harmonics (snapjump_cli.fe.branch.secondary).

* A branch state lifted into the model with every harmonic keeps its energy, volume, residual and
  tangent to round-off, and the harmonics outside the branch decouple from it exactly (Bloch), at
  a non-axisymmetric state, for n_c = 2 and 3.
* At an axisymmetric state the volume-constrained count of unstable modes is the constrained
  count of harmonic 0 plus the harmonic check's inertia of each K_n kept: in the branch's model
  (harmonics 0, 2, 4) and in the full one (0..4), on a clamped cap past its n = 2 bifurcation.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.stability.harmonics import harmonic_operator
from snapjump_cli.fe.axisym.lower_state import constrained_instability
from snapjump_cli.fe.branch.model import MultiHarmonicModel
from snapjump_cli.fe.branch.secondary import (extra_dofs, extra_harmonics, full_model, lift, outside_modes,
                                              unstable_modes)
from snapjump_cli.fe.stability.eigen import band_smallest_eigen, extra_eigen
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.geometry.caps import CapScene
from snapjump_cli.settings import MeshSettings, SolverSettings


@pytest.fixture(scope="module")
def cap():
    """A clamped cap above the asymmetric threshold (lambda = 6.1): harmonic 2 goes first."""
    return solve_scene(CapScene(theta_deg=30.0, eta=50.0, bc="clamped"), MeshSettings(nt=1, aspect=2.0),
                       SolverSettings())


@pytest.mark.parametrize("hn", [[0, 2, 4], [0, 3, 6]])
def test_a_lifted_branch_state_is_the_same_state_and_the_other_harmonics_decouple(cap, hn):
    M = cap.model
    pt = cap.path.points[20]
    rng = np.random.default_rng(1)
    nn = M.X.shape[0]
    mh = MultiHarmonicModel(M, hn)
    full = full_model(mh, hn[-1])
    assert extra_harmonics(mh, full) == [n for n in range(hn[-1] + 1) if n % hn[1]]
    U = mh.embed(pt.u, {n: 1e-3 * rng.standard_normal((nn, 3)) * M.X[:, :1] ** 2 for n in hn[1:]})
    Uf = lift(mh, full, U)
    for n in mh.hn:
        np.testing.assert_array_equal(full.harmonic_part(Uf, int(n)), mh.harmonic_part(U, int(n)))
    assert full.energy(Uf) == pytest.approx(mh.energy(U), rel=1e-13)
    assert full.volume(Uf) == pytest.approx(mh.volume(U), rel=1e-13)
    a, b = mh.linearize(U, pt.p), full.linearize(Uf, pt.p)
    ex = extra_dofs(mh, full)
    own = np.setdiff1d(np.arange(full.n), ex)
    assert len(own) == mh.n and len(ex) > 0
    Ka, Kb = a.stiffness().toarray(), b.stiffness().toarray()
    scale = np.abs(Ka).max()
    np.testing.assert_allclose(Kb[np.ix_(own, own)], Ka, rtol=0, atol=1e-13 * scale)
    assert np.abs(Kb[np.ix_(ex, own)]).max() < 1e-13 * scale  # the Bloch classes decouple
    assert np.abs(b.R[ex]).max() < 1e-13 * np.abs(a.R).max()  # a branch state has no force outside it
    np.testing.assert_allclose(b.R[own], a.R, rtol=0, atol=1e-13 * np.abs(a.R).max())
    assert np.abs(b.g[ex]).max() < 1e-13 * np.abs(a.g).max()  # nor any volume change


def test_the_unstable_count_is_the_harmonic_checks_inertias_at_an_axisymmetric_state(cap):
    M = cap.model
    mh = MultiHarmonicModel(M, [0, 2, 4])
    full = full_model(mh, 4)
    pts = cap.path.points[: cap.states.k_before + 1]
    seen_odd = False
    for pt in pts[:: max(1, len(pts) // 10)]:
        inert = {n: harmonic_operator(M, n).inertia(pt.u, pt.p) for n in range(1, 5)}
        c0 = constrained_instability(cap.tracer, M.linearize(pt.u, pt.p))
        U = mh.embed(pt.u)
        assert unstable_modes(mh, U, pt.p) == c0 + inert[2] + inert[4]
        assert unstable_modes(full, lift(mh, full, U), pt.p) == c0 + sum(inert.values())
        assert outside_modes(mh, full, U, pt.p) == inert[1] + inert[3]  # the block of the others alone
        seen_odd |= inert[1] + inert[3] > 0
    assert seen_odd  # the comparison covered unstable harmonics outside the branch


def test_the_extra_eigenvalue_changes_sign_where_the_odd_harmonics_lose_stability(cap):
    M = cap.model
    mh = MultiHarmonicModel(M, [0, 2, 4])
    full = full_model(mh, 4)
    ex = extra_dofs(mh, full)
    pts = cap.path.points[: cap.states.k_before + 1]
    n_neg_max = 0
    for pt in pts[:: max(1, len(pts) // 6)]:
        odd = harmonic_operator(M, 1).inertia(pt.u, pt.p) + harmonic_operator(M, 3).inertia(pt.u, pt.p)
        U = lift(mh, full, mh.embed(pt.u))
        eig, mode = extra_eigen(full, U, pt.p, extra_harmonics(mh, full))
        assert (eig < 0) == (odd > 0)
        assert outside_modes(mh, full, mh.embed(pt.u), pt.p) == odd  # the block's inertia
        assert np.all(mode[np.setdiff1d(np.arange(full.n), ex)] == 0.0)
        # the smallest eigenvalue of the block, not only one near zero: against the dense spectrum
        K = full.linearize(U, pt.p).stiffness().toarray()[np.ix_(ex, ex)]
        w = np.linalg.eigvalsh(K)
        assert eig == pytest.approx(w[0], rel=1e-8, abs=1e-12 * np.abs(w).max())
        n_neg_max = max(n_neg_max, int(np.sum(w < 0)))
    assert n_neg_max >= 2  # a state with several negative eigenvalues was among them


def test_the_extra_eigenvalue_is_the_smallest_even_far_below_zero():
    """Shift-invert near zero alone would return the eigenvalue nearest zero: with one far below
    the others (-5 against 1..3) the inertia sends the shift down to it."""
    import scipy.sparse as sp

    rng = np.random.default_rng(3)
    Q, _ = np.linalg.qr(rng.standard_normal((40, 40)))
    for spectrum in ([-5.0, *np.linspace(1.0, 3.0, 39)], [-5.0, -4.0, -3.0, -2.0, -0.01, *np.linspace(1e-3, 3.0, 35)],
                     list(np.linspace(0.5, 3.0, 40)),
                     # wide ranges, as a stiffness has: five negative ones against a largest of 1e8, and
                     # one at -1e4 beside one near zero
                     [-1.0, -0.9, -0.8, -0.7, -0.6, *np.logspace(-2, 8, 35)], [-1e4, -1e-3, *np.logspace(-3, 2, 38)]):
        Kd = (Q * np.array(spectrum)) @ Q.T
        K = sp.csc_matrix(Kd)
        ab = np.array([[Kd[j + k, j] if j + k < 40 else 0.0 for k in range(40)] for j in range(40)])  # dense band
        eig, mode = band_smallest_eigen(ab, 39 - np.arange(40))
        assert eig == pytest.approx(min(spectrum), rel=1e-8)
        assert abs(mode @ K @ mode - eig * (mode @ mode)) < 1e-7 * np.abs(spectrum).max() * (mode @ mode)
