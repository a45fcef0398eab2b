"""The bifurcation's eigen-solve with few Lanczos vectors (``eigen.LOWEST_NCV``) against ARPACK's
default and against a dense solve of the same pencil, and its fallback where ARPACK does not
converge with them."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from snapjump_cli.fe.branch.bifurcation import locate_bifurcation
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability import eigen
from snapjump_cli.fe.stability.harmonics import harmonic_operator
from snapjump_cli.geometry.caps import CapScene
from snapjump_cli.settings import MeshSettings, SolverSettings


@pytest.fixture(scope="module")
def states():
    """A clamped cap's path (harmonic 2 loses stability on it), that harmonic's operator and three
    states: two stable ones and the bifurcation (where the root finding calls the solve)."""
    res = solve_scene(CapScene(theta_deg=30.0, eta=50.0, bc="clamped"), MeshSettings(nt=1, aspect=2.0),
                      SolverSettings())
    pts = res.path.points[: res.states.k_before + 1]
    bif = locate_bifurcation(res, 2)
    return harmonic_operator(res.model, 2), [pts[len(pts) // 4], pts[len(pts) // 2], bif], res  # (res keeps the model)


def _dense_lowest(op, u, p) -> float:
    """The smallest eigenvalue of the gauged pencil by a dense solve of its shift-inverted form
    (``mu_min / L^2`` units): every eigenvalue, so none can be missed. ``K`` is ill-conditioned
    (~1e10 on this cap), and the dense solve is accurate to ~1e-7 of the smallest eigenvalue."""
    keep = np.setdiff1d(np.arange(op.ndof), op.gauge_dofs(u))
    K = op.matrix(u, p)[keep][:, keep].toarray()
    M = op.mass()[keep][:, keep].toarray()
    mu = float(np.min(op.model.mu))
    theta = sla.eigvals(np.linalg.solve(K + 2.0 * mu * M, M)).real
    return float(np.min(-2.0 * mu + 1.0 / theta)) / mu


def test_few_lanczos_vectors_find_the_default_eigenpair(states):
    op, pts, _ = states
    for pt in pts:
        lam, mode = eigen.lowest_eigen(op, pt.u, pt.p)
        mu = float(np.min(op.model.mu))
        lam_d, mode_d = eigen.eig_near(op, pt.u, pt.p, -2.0 * mu, mode=True)  # ARPACK's own ncv
        assert lam == pytest.approx(lam_d / mu, rel=1e-10, abs=1e-12)
        assert lam == pytest.approx(_dense_lowest(op, pt.u, pt.p), rel=1e-6, abs=1e-6)
        # the same mode up to its sign (both scaled to a largest entry of 1)
        assert min(np.abs(mode - mode_d).max(), np.abs(mode + mode_d).max()) < 1e-7


def test_where_arpack_does_not_converge_with_few_vectors_the_default_is_used(states, monkeypatch):
    op, pts, _ = states
    pt = pts[1]
    expected = eigen.eig_near(op, pt.u, pt.p, -2.0 * float(np.min(op.model.mu)), mode=True)
    real = spla.eigsh
    calls = []

    def eigsh(*args, ncv=None, **kw):
        calls.append(ncv)
        if ncv is not None:
            raise spla.ArpackNoConvergence("no convergence", np.zeros(0), np.zeros((0, 0)))
        return real(*args, **kw)

    monkeypatch.setattr(spla, "eigsh", eigsh)
    lam, _ = eigen.lowest_eigen(op, pt.u, pt.p)
    assert calls == [eigen.LOWEST_NCV, None]
    assert lam == expected[0] / float(np.min(op.model.mu))




def test_the_bifurcation_is_located_with_each_bracket_end_solved_once(monkeypatch):
    """The root finding is handed the bracket's eigenvalues (``root_on_step``'s ``f_ends``): every
    state's eigenproblem is solved once, and the bifurcation is the one located when the root
    finding solves the ends again, bit for bit."""
    from snapjump_cli.fe.branch import bifurcation

    res = solve_scene(CapScene(theta_deg=30.0, eta=50.0, bc="clamped"), MeshSettings(nt=1, aspect=2.0),
                      SolverSettings())
    seen = []
    real = bifurcation.lowest_eigen

    def counted(op, u, p, **kw):
        seen.append(u.tobytes())
        return real(op, u, p, **kw)

    monkeypatch.setattr(bifurcation, "lowest_eigen", counted)
    bif = locate_bifurcation(res, 2)
    assert len(seen) == len(set(seen)) == bif.iterations
    real_root = bifurcation.root_on_step

    def ends_again(*args, f_ends=None, **kw):
        return real_root(*args, **kw)

    monkeypatch.setattr(bifurcation, "root_on_step", ends_again)
    seen.clear()
    ref = locate_bifurcation(res, 2)
    assert len(seen) == len(set(seen)) + 2
    assert np.array_equal(bif.u, ref.u) and bif.eig == ref.eig and np.array_equal(bif.mode, ref.mode)
