"""Unit checks of the numba kernels: finite-difference derivatives, patch test, rigid motion."""
from __future__ import annotations

import math

import numpy as np
import pytest

from snapjump_cli.fe.axisym.model import Model
from tests.sphere import sphere_mesh
from snapjump_kernels.cavity import cavity_assemble, cavity_volume
from snapjump_kernels.gent import gent_iso


def _model(order: int, two_materials: bool, bulk: float = 50.0) -> Model:
    m = sphere_mesh(1.0, 1.4, 2, 4, order)
    if two_materials:
        mat = (np.arange(m.n_elements) % 2).astype(np.int8)
        m = type(m)(**{**m.__dict__, "material": mat})
    # a moderate bulk ratio keeps the finite-difference truncation error visible above round-off
    return Model(m, np.array([1.0, 1.0 / 5.8]), np.array([24.0, 24.0]), bulk, 1.0, 1.0)


def _random_state(M: Model, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    X = M.free_vector(M.X)
    return 0.15 * X + 0.005 * rng.standard_normal(M.n)  # inflated and randomly distorted


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("two_materials", [False, True])
def test_residual_is_gradient_of_energy(order, two_materials):
    M = _model(order, two_materials)
    u = _random_state(M, 1)
    f, _ = M.internal_force(u)
    d = np.random.default_rng(2).standard_normal(M.n)
    # central differences: the error must fall like eps^2 until round-off
    scale = np.linalg.norm(f) * np.linalg.norm(d)
    errs = []
    for eps in (1e-4, 1e-5):
        fd = (M.energy(u + eps * d) - M.energy(u - eps * d)) / (2 * eps)
        errs.append(abs(fd - f @ d) / scale)
    assert errs[1] < 1e-8
    assert errs[1] < 0.05 * errs[0] or errs[1] < 1e-10


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("two_materials", [False, True])
def test_tangent_is_jacobian_of_residual_with_pressure_load(order, two_materials):
    M = _model(order, two_materials)
    u = _random_state(M, 3)
    p = 0.37
    K = M.stiffness_matrix(u, p)
    d = np.random.default_rng(4).standard_normal(M.n)
    eps = 1e-6
    fd = (M.residual(u + eps * d, p) - M.residual(u - eps * d, p)) / (2 * eps)
    Kd = K @ d
    assert np.linalg.norm(fd - Kd) <= 1e-7 * np.linalg.norm(Kd)
    # symmetric: the load stiffness of a volume-controlled cavity derives from a potential
    assert abs(d @ (K @ (2 * d + 1)) - (2 * d + 1) @ Kd) <= 1e-10 * np.linalg.norm(Kd) * np.linalg.norm(d) * 3


@pytest.mark.parametrize("nen", [2, 3])
def test_cavity_gradient_and_hessian_fd(nen):
    rng = np.random.default_rng(5)
    n_e = 7
    n_nodes = n_e * (nen - 1) + 1
    t = np.linspace(0.1, 1.4, n_nodes)
    x = np.stack([np.sin(t), np.cos(t)], axis=1) + 0.02 * rng.standard_normal((n_nodes, 2))
    if nen == 2:
        edges = np.array([[i, i + 1] for i in range(n_e)])
    else:
        edges = np.array([[2 * i, 2 * i + 2, 2 * i + 1] for i in range(n_e)])
    def derivatives(x):  # cavity_assemble with every dof free and a dense "CSR" of all entries
        nd = 2 * n_nodes
        edofs = np.array([[2 * n + c for n in e for c in range(2)] for e in edges], np.int64)
        pos = (edofs[:, :, None] * nd + edofs[:, None, :]).astype(np.int64)
        g, data = np.zeros(nd), np.zeros(nd * nd)
        V = cavity_assemble(x, edges, edofs, pos, 1.0, 2, g, data)
        return V, g.reshape(n_nodes, 2), data.reshape(nd, nd)

    V, g, H = derivatives(x)
    assert V == pytest.approx(cavity_volume(x, edges), rel=1e-14)
    assert np.allclose(H, H.T, atol=1e-14)
    d = rng.standard_normal(x.shape)
    eps = 1e-6
    fd = (cavity_volume(x + eps * d, edges) - cavity_volume(x - eps * d, edges)) / (2 * eps)
    assert fd == pytest.approx((g * d).sum(), rel=1e-8)
    Vp, gp, _ = derivatives(x + eps * d)
    Vm, gm, _ = derivatives(x - eps * d)
    fdH = ((gp - gm) / (2 * eps)).ravel()
    assert np.allclose(fdH, H @ d.ravel(), rtol=0, atol=1e-8 * np.abs(H @ d.ravel()).max())


def test_cavity_volume_exact_for_quadratic_edges_on_a_cone_and_sphere():
    # a straight edge from (1, 0) to (0, 1): a cone of volume pi/3
    x = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
    assert cavity_volume(x, np.array([[0, 1, 2]])) == pytest.approx(math.pi / 3, rel=1e-14)
    assert cavity_volume(x[:2], np.array([[0, 1]])) == pytest.approx(math.pi / 3, rel=1e-14)


def test_gent_domain_violation_is_reported():
    f = np.array([6.0, 0.0, 0.0, 1.0 / 36.0, 6.0])  # J = 1, I1 - 3 ~ 69 > J_m
    ok, *_ = gent_iso(f, 1.0, 24.0, 2, np.zeros(5), np.zeros((5, 5)), np.zeros(5), np.zeros((5, 5)))
    assert not ok


@pytest.mark.parametrize("order", [1, 2])
def test_rigid_translation_zero_energy_and_residual(order):
    m = sphere_mesh(1.0, 1.4, 2, 4, order)
    m = type(m)(**{**m.__dict__, "node_sets": {**m.node_sets, "dirichlet_y": np.zeros(0, np.int64)}})
    M = Model(m, np.array([1.0]), np.array([24.0]), 1e4, 1.0, 1.0)
    U = np.zeros(M.X.shape)
    U[:, 1] = 0.3
    u = M.free_vector(U)
    f, _ = M.internal_force(u)
    assert abs(M.energy(u)) < 1e-14
    assert np.abs(f).max() < 1e-10  # round-off of kappa-weighted terms (kappa = 1e4)


@pytest.mark.parametrize("order", [1, 2])
def test_patch_homogeneous_deformation_on_distorted_mesh(order):
    """F = diag(1+a, 1+b, 1+a) is represented exactly on any isoparametric mesh; its stress is
    homogeneous with sigma_rr = sigma_tt, so every interior node is in equilibrium."""
    m = sphere_mesh(1.0, 1.5, 3, 5, order)
    X = m.nodes.copy()
    rng = np.random.default_rng(7)
    boundary = np.zeros(len(X), bool)
    r = np.hypot(X[:, 0], X[:, 1])
    boundary |= np.isclose(r, 1.0) | np.isclose(r, 1.5) | (X[:, 0] < 1e-12) | (X[:, 1] < 1e-12)
    corner = np.zeros(len(X), bool)
    corner[np.unique(m.elements[:, :4])] = True
    move = ~boundary & corner  # distort element corners (mid nodes are re-centred below)
    X[move] += 0.03 * rng.standard_normal((move.sum(), 2))
    if order == 2:
        e = m.elements
        for k, (a, b) in enumerate([(0, 1), (1, 2), (2, 3), (3, 0)]):
            mid = e[:, 4 + k]
            inner = ~boundary[mid]
            X[mid[inner]] = 0.5 * (X[e[inner, a]] + X[e[inner, b]])
        X[e[:, 8]] = X[e[:, :4]].mean(axis=1)
    m2 = type(m)(**{**m.__dict__, "nodes": X})
    M = Model(m2, np.array([1.0]), np.array([24.0]), 1e3, 1.0, 1.0)
    a, b = 0.1, -0.08
    U = np.stack([a * M.X[:, 0], b * M.X[:, 1]], axis=1)
    u = M.free_vector(U)
    f, _ = M.internal_force(u)
    F = M.full_displacement(f)
    interior = ~boundary
    assert np.abs(F[interior]).max() < 1e-11 * np.abs(F).max()
    J = M.jacobians(u)
    assert np.allclose(J, (1 + a) ** 2 * (1 + b), rtol=1e-13)
