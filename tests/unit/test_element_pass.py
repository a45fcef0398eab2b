"""The element pass (``snapjump_kernels.assembly.assemble``) against a plain numpy reference.

The reference builds, per element and quadrature point, the dense 5 x 2nen matrix ``B`` (rows
``F_rR, F_rZ, F_zR, F_zZ, F_theta``), takes the energy density and its derivatives from
``gent_iso`` and sums ``W B^T (dpsi + p dJ)`` and ``W B^T (d2psi + p_geo d2J) B + kappa G^T M^-1 G``
with numpy, element by element, into dense arrays. The kernel batches elements and exploits the
sparsity of ``B``; both storages it supports are checked: every entry (a CSR pattern) and the
lower triangle only (the band storage).
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.axisym.model import Model
from tests.sphere import sphere_mesh
from snapjump_kernels.assembly import assemble
from snapjump_kernels.element_plain import assemble_plain
from snapjump_kernels.gent import gent_iso


def _model(order: int) -> Model:
    # 3 x 7 = 21 elements: two full batches of the kernel and a partial one
    m = sphere_mesh(1.0, 1.4, 3, 7, order)
    m = type(m)(**{**m.__dict__, "material": (np.arange(m.n_elements) % 2).astype(np.int8)})
    return Model(m, np.array([1.0, 1.0 / 5.8]), np.array([24.0, 9.0]), 50.0, 1.0, 1.0)


def _state(M: Model, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    X = M.free_vector(M.X)
    return M.full_displacement(0.15 * X + 0.005 * rng.standard_normal(M.n))


def _reference(M: Model, U: np.ndarray, p_geo: np.ndarray | None):
    """Energy, force (n,), stiffness (n, n), element pressures and their derivatives H."""
    ne, nen = M.conn.shape
    nd, npr = 2 * nen, M.Np.shape[1]
    n = M.n
    E, F, K = 0.0, np.zeros(n), np.zeros((n, n))
    PB, HS = np.zeros((ne, npr)), np.zeros((ne, npr, nd))
    dev = 0.0
    for e in range(ne):
        m = M.mat[e]
        mu, jm, ka = M.mu[m], M.jm[m], M.kappa[m]
        ue = U[M.conn[e]].ravel()  # [u_r0, u_z0, u_r1, ...]: the element dof order
        pts = []
        g = np.zeros(npr)
        for q in range(M.Wq.shape[1]):
            dN, N, R, W = M.dNdX[e, q], M.N_ref[q], M.Rq[e, q], M.Wq[e, q]
            B = np.zeros((5, nd))
            B[0, 0::2], B[1, 0::2], B[4, 0::2] = dN[:, 0], dN[:, 1], N / R
            B[2, 1::2], B[3, 1::2] = dN[:, 0], dN[:, 1]
            f = np.array([1.0, 0.0, 0.0, 1.0, 1.0]) + B @ ue
            dpsi, d2psi, dJ, d2J = np.zeros(5), np.zeros((5, 5)), np.zeros(5), np.zeros((5, 5))
            ok, psi, J = gent_iso(f, mu, jm, 2, dpsi, d2psi, dJ, d2J)
            assert ok
            E += W * psi
            g += W * M.Np[q] * (J - 1.0)
            pts.append((B, W, dpsi, d2psi, dJ, d2J))
        pb = ka * M.Minv[e] @ g
        E += 0.5 * g @ pb
        pg = pb if p_geo is None else p_geo[e]
        fe, Ke, G = np.zeros(nd), np.zeros((nd, nd)), np.zeros((npr, nd))
        for q, (B, W, dpsi, d2psi, dJ, d2J) in enumerate(pts):
            fe += W * B.T @ (dpsi + (M.Np[q] @ pb) * dJ)
            Ke += W * B.T @ (d2psi + (M.Np[q] @ pg) * d2J) @ B
            G += W * np.outer(M.Np[q], B.T @ dJ)
            dev = max(dev, abs(M.Np[q] @ pb) / ka)
        Ke += ka * G.T @ M.Minv[e] @ G
        PB[e], HS[e] = pb, ka * M.Minv[e] @ G
        d = M.edofs[e]
        free = d >= 0
        np.add.at(F, d[free], fe[free])
        K[np.ix_(d[free], d[free])] += Ke[np.ix_(free, free)]
    return E, F, K, PB, HS, dev


def _kernel(M: Model, U: np.ndarray, p_geo: np.ndarray | None, lower: bool, want: int = 2, kernel=assemble):
    """The kernel's results with the stiffness in a dense (n, n) array: ``epos`` points every
    element entry (``lower``: those on and below the diagonal) at its place in it."""
    ne, nd, npr, n = M.conn.shape[0], M.edofs.shape[1], M.Np.shape[1], M.n
    r = np.repeat(M.edofs, nd, axis=1).reshape(ne, nd, nd)
    c = np.tile(M.edofs, (1, nd)).reshape(ne, nd, nd)
    keep = (r >= 0) & (c >= 0) & ((r >= c) if lower else True)
    epos = np.where(keep, r * n + c, -1).astype(np.int64)
    f, data = np.zeros(n), np.zeros(n * n)
    pb, H = np.zeros((ne, npr)), np.zeros((ne, npr, nd))
    pg = np.zeros((0, npr)) if p_geo is None else p_geo
    E, ok, dev = kernel(U, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np, M.Minv,
                          M.edofs, epos, want, f, data, pg, pb, H)
    K = data.reshape(n, n)
    if lower:
        K = K + np.tril(K, -1).T
    return E, ok, dev, f, K, pb, H


def _rel(x, ref) -> float:
    return float(np.abs(x - ref).max() / np.abs(ref).max())


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("mixed", [False, True])
@pytest.mark.parametrize("lower", [False, True])
def test_element_pass_matches_dense_reference(order, mixed, lower):
    M = _model(order)
    U = _state(M, 11)
    p_geo = None
    if mixed:  # element pressures other than the element's own kappa M^-1 g(u)
        p_geo = 0.3 + np.random.default_rng(12).standard_normal((M.conn.shape[0], M.Np.shape[1]))
    E0, F0, K0, PB0, H0, dev0 = _reference(M, U, p_geo)
    E, ok, dev, f, K, pb, H = _kernel(M, U, p_geo, lower)
    assert ok
    assert E == pytest.approx(E0, rel=1e-12)
    assert dev == pytest.approx(dev0, rel=1e-12)
    assert _rel(f, F0) < 1e-12
    assert _rel(K, K0) < 1e-12
    assert _rel(pb, PB0) < 1e-12
    assert _rel(H, H0) < 1e-12


@pytest.mark.parametrize("order", [1, 2])
def test_energy_and_force_do_not_depend_on_want(order):
    """The energy and force of the energy-only and residual-only passes are those of the stiffness
    pass, bit for bit (they share the arithmetic)."""
    M = _model(order)
    U = _state(M, 13)
    E2, _, dev2, f2, *_ = _kernel(M, U, None, True, want=2)
    E1, ok1, dev1, f1, *_ = _kernel(M, U, None, True, want=1)
    E0, ok0, dev0, f0, *_ = _kernel(M, U, None, True, want=0)
    assert ok1 and ok0
    assert E0 == E1 == E2 and dev0 == dev1 == dev2
    assert np.array_equal(f1, f2) and not f0.any()


@pytest.mark.parametrize("order", [1, 2])
def test_point_outside_the_gent_domain_fails_the_pass(order):
    M = _model(order)
    U = _state(M, 14)
    last = M.conn[-1]  # an element of the last, partial batch
    U[last] += 3.0 * np.random.default_rng(15).standard_normal((len(last), 2))
    E, ok, *_ = _kernel(M, U, None, True)
    assert not ok


@pytest.mark.parametrize("mixed", [False, True])
def test_q9_lanes_agree_with_the_plain_loop(mixed):
    """The batched Q9 pass against the element-by-element loop that every other element uses:
    energy, force, element pressures and their derivatives bit for bit, the stiffness to round-off."""
    M = _model(2)
    U = _state(M, 16)
    p_geo = 0.3 + np.random.default_rng(17).standard_normal((M.conn.shape[0], 3)) if mixed else None
    E, ok, dev, f, K, pb, H = _kernel(M, U, p_geo, True)
    E1, ok1, dev1, f1, K1, pb1, H1 = _kernel(M, U, p_geo, True, kernel=assemble_plain)
    assert ok and ok1
    assert E == E1 and dev == dev1
    assert np.array_equal(f, f1) and np.array_equal(pb, pb1) and np.array_equal(H, H1)
    assert _rel(K, K1) < 1e-14
