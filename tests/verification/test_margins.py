"""The margins: the smallest eigenvalue of each harmonic's tangent along the path (fe/margins.py)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sl

from snapjump_cli.fe.stability.harmonics import check_harmonics, harmonic_operator
from snapjump_cli.fe.stability.margins import path_margins
from snapjump_cli.fe.stability.eigen import smallest_eigenvalue
from snapjump_cli.fe.solve import solve_checked, solve_scene
from snapjump_cli.geometry.caps import CapScene
from snapjump_cli.settings import MeshSettings, SolverSettings


@pytest.fixture(scope="module")
def cap():
    res = solve_scene(CapScene(theta_deg=30.0, eta=50.0, bc="clamped"), MeshSettings(nt=1, aspect=2.0),
                      SolverSettings())
    return res


@pytest.mark.parametrize("n", [0, 1, 2])
def test_the_margin_is_the_smallest_generalised_eigenvalue(cap, n):
    op = harmonic_operator(cap.model, n)
    pt = cap.path.points[cap.states.k_before]  # near the volume limit: some harmonics unstable
    keep = np.setdiff1d(np.arange(op.ndof), op.gauge_dofs(pt.u))
    K = op.matrix(pt.u, pt.p).toarray()[np.ix_(keep, keep)]
    M = op.mass().toarray()[np.ix_(keep, keep)]
    dense = sl.eigh(K, M, eigvals_only=True)[0]
    # K carries the bulk penalty (kappa = 1e4 mu): its condition number ~1e9 limits the dense
    # solver's smallest eigenvalue to ~1e-7 relative
    assert smallest_eigenvalue(op, pt.u, pt.p) == pytest.approx(dense, rel=1e-6, abs=1e-10)


def test_the_margins_agree_with_the_check(cap):
    chk = check_harmonics(cap, 3, refine=0, scan_all=True)
    margins = path_margins(cap, 3)
    summary, table = margins.as_row(), margins.table
    pts = list(cap.path.points[: cap.states.k_before + 1]) + [cap.states.upper]
    assert table.shape == (len(pts), 5)
    mu = float(np.min(cap.model.mu))
    for pt, row in zip(pts, table):
        for n in (1, 2, 3):
            unstable = harmonic_operator(cap.model, n).inertia(pt.u, pt.p) > 0
            assert unstable == (row[1 + n] < -1e-6 * mu)
    assert chk.asym_first and summary["asym_margin"] < 0
    assert table[0, 1] > 0  # the stress-free state is stable in every harmonic, n = 0 included
    assert summary["asym_margin_V_m3"] == table[np.argmin(table[:, 2:].min(axis=1)), 0]


def test_solve_reports_them_when_asked():
    scene = CapScene(theta_deg=30.0, eta=25.0, bc="clamped")
    m = solve_checked(scene, MeshSettings(nt=1, aspect=2.0), SolverSettings(harmonics=2, margins=True)).metrics
    assert m["asym_first"] is False and m["asym_margin"] > 0 and m["asym_margin_n"] in (1, 2)
    m = solve_checked(scene, MeshSettings(nt=1, aspect=2.0), SolverSettings(harmonics=2)).metrics
    assert m["asym_margin"] is None


def test_the_eigen_solve_is_repeatable(cap):
    """The same state gives the same eigenvalue and mode to the last bit (ARPACK's start vector is
    fixed; with its random default, followed answers differed between processes by ~1e-8)."""
    from snapjump_cli.fe.stability.eigen import eig_near

    res = cap
    pt = res.path.points[len(res.path.points) // 2]
    op = harmonic_operator(res.model, 1)
    a = eig_near(op, pt.u, pt.p, -2.0, mode=True)
    b = eig_near(op, pt.u, pt.p, -2.0, mode=True)
    assert a[0] == b[0]
    assert np.array_equal(a[1], b[1])


def test_a_free_actuators_rotation_about_its_axis_is_not_its_n0_margin():
    """A free actuator can turn about its axis: a zero eigenvalue of the n = 0 torsion that is not
    a margin. The margin is the smallest of the other eigenvalues (dense reference, the rotation's
    eigenvector found by its M-cosine), certified by the inertia less the rotation."""
    from snapjump_cli.fe.stability.eigen import axis_rotation
    from snapjump_cli.geometry.designs import get_design

    res = solve_scene(get_design("C"), MeshSettings(nt=1, aspect=4.0), SolverSettings())
    pt = res.path.points[len(res.path.points[: res.states.k_before]) // 3]  # well before p_max
    op = harmonic_operator(res.model, 0)
    r = axis_rotation(op, pt.u)
    assert r is not None and harmonic_operator(res.model, 1) is not None and axis_rotation(harmonic_operator(res.model, 1), pt.u) is None
    keep = np.setdiff1d(np.arange(op.ndof), op.gauge_dofs(pt.u))
    K = op.matrix(pt.u, pt.p).toarray()[np.ix_(keep, keep)]
    M = op.mass().toarray()[np.ix_(keep, keep)]
    np.testing.assert_allclose(K @ r[keep], 0.0, atol=1e-9 * np.abs(K).max() * np.abs(r).max())  # a zero mode
    w, V = sl.eigh(K, M)
    Mr = M @ r[keep]
    cos = np.abs(V.T @ Mr) / np.sqrt(r[keep] @ Mr)  # V is M-orthonormal
    assert cos.max() > 0.999 and abs(w[np.argmax(cos)]) < 1e-8
    others = w[cos < 0.99]
    lam = smallest_eigenvalue(op, pt.u, pt.p)
    assert lam == pytest.approx(others[0], rel=1e-6) and lam > 1e-3 * float(np.min(res.model.mu))


def test_the_n1_margin_projects_the_rigid_modes_out_and_no_gauge_moves_it():
    """A free actuator's n = 1 margin is the smallest eigenvalue of K_1 on the M-orthogonal
    complement of its rigid translation and tilt (dense reference). The gauged pencil of the check
    has the same inertia but lower eigenvalues, and they depend on where the gauge is: a
    deformation that moves a gauge point drags a rigid motion along (docs/harmonics.md section 11)."""
    from snapjump_cli.fe.stability.eigen import eig_near
    from snapjump_cli.fe.stability.harmonics import pivot_columns
    from snapjump_cli.geometry.designs import get_design

    res = solve_scene(get_design("C"), MeshSettings(nt=1, aspect=4.0), SolverSettings())
    pt = res.path.points[res.states.k_before // 2]
    op = harmonic_operator(res.model, 1)
    K = op.matrix(pt.u, pt.p).toarray()
    M = op.mass().toarray()
    R = op.rigid_dof_modes(pt.u)
    assert R.shape[0] == 2  # a free body: translation and tilt
    np.testing.assert_allclose(K @ R.T, 0.0, atol=1e-9 * np.abs(K).max())  # null vectors at an equilibrium
    Z = sl.null_space((M @ R.T).T)
    projected = sl.eigh(Z.T @ K @ Z, Z.T @ M @ Z, eigvals_only=True)

    def gauged(dofs):
        assert abs(np.linalg.det(R[:, dofs])) > 1e-6  # they do fix both modes
        keep = np.setdiff1d(np.arange(op.ndof), dofs)
        return sl.eigh(K[np.ix_(keep, keep)], M[np.ix_(keep, keep)], eigvals_only=True)

    first = op.gauge_dofs(pt.u)
    others = R.copy()
    others[:, first] = 0.0
    other = pivot_columns(others)  # the same rule on the other dofs: next to the top pole
    a, b = gauged(first), gauged(other)
    assert not np.allclose(a[0], b[0], rtol=0.2)  # the gauged eigenvalue depends on the gauge (2x here)
    assert a[0] < projected[0] and b[0] < projected[0]
    lam = smallest_eigenvalue(op, pt.u, pt.p)
    assert lam == pytest.approx(projected[0], rel=1e-6)
    assert smallest_eigenvalue(op, pt.u, pt.p, project=False) == pytest.approx(a[0], rel=1e-6)

    mu = float(np.min(res.model.mu))
    val, A = eig_near(op, pt.u, pt.p, -2.0 * mu, mode=True, project=True)
    x = op.to_vector(A)
    assert val == pytest.approx(projected[0], rel=1e-6)
    np.testing.assert_allclose(R @ (M @ x), 0.0, atol=1e-9 * np.sqrt(x @ M @ x))  # a deformation, no rigid part
