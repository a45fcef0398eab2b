"""Finite-difference checks of the Fourier-harmonic tangent K_n (docs/harmonics.md).

The reference is an independent numpy evaluation of the 3D potential ``Pi = W - p V`` of the
perturbed state ``u_r = U_r + e a cos n phi``, ``u_z = U_z + e b cos n phi``,
``u_phi = e c sin n phi``: Cartesian positions of the node rings, the phi-derivative by complex
step, the full 3x3 deformation gradient, the Gent energy with the mixed element's projected
dilatation evaluated at every phi, and the cavity volume as the flux of (x, y, 0)/2 through the
perturbed surface, all integrated over phi with a uniform rule (exact for the quadratic terms).
It shares no code with :mod:`snapjump_kernels.harmonics`.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.stability.harmonics import HarmonicOperator, harmonic_operator, pivot_columns, rigid_modes
from snapjump_cli.fe.axisym.model import Model
from tests.sphere import sphere_mesh
from snapjump_kernels.elements import element_tables

_GP = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GW = np.array([5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0])


class Energy3D:
    """The 3D potential of a harmonically perturbed axisymmetric state (numpy, for checks only)."""

    def __init__(self, M: Model, n: int, m_phi: int | None = None):
        self.M, self.n = M, n
        tab = element_tables(M.mesh.order)
        Xe = M.X[M.conn]  # (ne, nen, 2)
        J0 = np.einsum("qak,eai->eqik", tab.dN, Xe)  # dX_i / dxi_k
        det = J0[..., 0, 0] * J0[..., 1, 1] - J0[..., 0, 1] * J0[..., 1, 0]
        inv = np.linalg.inv(J0)  # dxi_k / dX_i
        self.dNdX = np.einsum("qak,eqki->eqai", tab.dN, inv)
        self.N = tab.N
        self.Rq = np.einsum("qa,ea->eq", tab.N, Xe[..., 0])
        self.Wq = tab.w * det * 2 * np.pi * self.Rq
        self.Np = tab.Np
        self.Minv = np.linalg.inv(np.einsum("eq,qk,ql->ekl", self.Wq, tab.Np, tab.Np))
        self.mu = M.mu[M.mat][:, None]
        self.jm = M.jm[M.mat][:, None]
        self.kappa = M.kappa[M.mat]
        m = m_phi or 4 * n + 4
        self.phi = 2 * np.pi * (np.arange(m) + 0.37) / m  # uniform rule, exact for degree < m

    def _rings(self, U, A, eps, phi):
        """Cartesian node positions (nn, 3) at angle ``phi`` (complex: complex-step derivative)."""
        n = self.n
        X = self.M.X
        cn, sn = np.cos(n * phi), (np.sin(n * phi) if n > 0 else 1.0 + 0 * phi)
        rho = X[:, 0] + U[:, 0] + eps * A[:, 0] * cn
        sig = eps * A[:, 2] * sn
        z = X[:, 1] + U[:, 1] + eps * A[:, 1] * cn
        c, s = np.cos(phi), np.sin(phi)
        return np.stack([rho * c - sig * s, rho * s + sig * c, z + 0 * phi], axis=-1)

    def potential(self, U, A, eps, p):
        """``(W, V)``: strain energy and cavity volume (scaled, with the offset)."""
        M, h = self.M, 1e-30
        W = 0.0
        V = 0.0
        for phi in self.phi:
            xc = self._rings(U, A, eps, phi + 1j * h)
            x = xc.real
            x_phi = xc.imag / h
            xe, xpe = x[M.conn], x_phi[M.conn]  # (ne, nen, 3)
            dR = np.einsum("eqa,eai->eqi", self.dNdX[..., 0], xe)
            dZ = np.einsum("eqa,eai->eqi", self.dNdX[..., 1], xe)
            dP = np.einsum("qa,eai->eqi", self.N, xpe) / self.Rq[..., None]
            G = np.stack([dR, dP, dZ], axis=-1)  # columns: d/dR, (1/R) d/dPhi, d/dZ
            J = np.linalg.det(G)
            I1 = np.sum(G**2, axis=(-2, -1))
            arg = 1.0 - (J ** (-2.0 / 3.0) * I1 - 3.0) / self.jm
            assert np.all(arg > 0) and np.all(J > 0)
            psi = -0.5 * self.mu * self.jm * np.log(arg)
            g = np.einsum("eq,qk,eq->ek", self.Wq, self.Np, J - 1.0)
            W += np.sum(self.Wq * psi) + 0.5 * np.sum(self.kappa * np.einsum("ek,ekl,el->e", g, self.Minv, g))
            # cavity: V = -1/2 int int (x, y, 0) . (x_s x x_phi) ds dphi
            E = M.edges
            nen = E.shape[1]
            for s, w in zip(_GP, _GW):
                if nen == 2:
                    Ns, dNs = np.array([0.5 * (1 - s), 0.5 * (1 + s)]), np.array([-0.5, 0.5])
                else:
                    Ns = np.array([0.5 * s * (s - 1), 0.5 * s * (s + 1), 1 - s * s])
                    dNs = np.array([s - 0.5, s + 0.5, -2 * s])
                xs = np.einsum("a,mai->mi", Ns, x[E])
                x_s = np.einsum("a,mai->mi", dNs, x[E])
                x_p = np.einsum("a,mai->mi", Ns, x_phi[E])
                v = xs.copy()
                v[:, 2] = 0.0
                V += -0.5 * 2 * np.pi * w * np.sum(v * np.cross(x_s, x_p))
        m = len(self.phi)
        return W / m, V / m + M.V_offset

    def Pi(self, U, A, eps, p):
        W, V = self.potential(U, A, eps, p)
        return W - p * V


def _model(order: int, bulk: float = 50.0) -> Model:
    m = sphere_mesh(1.0, 1.4, 2, 3, order)
    mat = (np.arange(m.n_elements) % 2).astype(np.int8)  # two materials
    m = type(m)(**{**m.__dict__, "material": mat})
    return Model(m, np.array([1.0, 1.0 / 5.8]), np.array([24.0, 18.0]), bulk, 1.0, 1.0)


def _state(M: Model, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return 0.15 * M.free_vector(M.X) + 0.01 * rng.standard_normal(M.n)  # inflated, distorted, not in equilibrium


def _mixed_fd(f, h):
    """``d2 f / ds dt`` at 0 by central differences, Richardson-extrapolated (error O(h^4))."""
    def d(h):
        return (f(h, h) - f(h, -h) - f(-h, h) + f(-h, -h)) / (4 * h * h)

    return (4 * d(h / 2) - d(h)) / 3


@pytest.mark.parametrize("order", [1, 2])
def test_axisymmetric_evaluator_matches_the_model(order):
    """At e = 0 the 3D evaluator reproduces the model's energy and cavity volume (any phi rule)."""
    M = _model(order)
    u = _state(M, 0)
    ev = Energy3D(M, 2)
    W, V = ev.potential(M.full_displacement(u), np.zeros((M.X.shape[0], 3)), 0.0, 0.0)
    assert W == pytest.approx(M.energy(u), rel=1e-12)
    assert V == pytest.approx(M.volume(u), rel=1e-12)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("n", [0, 1, 2, 3, 4])
def test_K_n_is_the_second_variation_of_the_3d_potential(order, n):
    M = _model(order)
    u = _state(M, 10 + n)
    p = 0.9
    op = harmonic_operator(M, n)
    K = op.matrix(u, p)
    ev = Energy3D(M, n)
    U = M.full_displacement(u)
    rng = np.random.default_rng(100 + 7 * n + order)
    for _ in range(3):
        v, w = rng.standard_normal(op.ndof), rng.standard_normal(op.ndof)
        Av, Aw = op.to_nodal(v), op.to_nodal(w)
        fd = _mixed_fd(lambda s, t: ev.Pi(U, s * Av + t * Aw, 1.0, p), 5e-4)
        exact = v @ (K @ w)
        scale = np.sqrt(abs(v @ (K @ v)) * abs(w @ (K @ w)))
        # the Richardson-extrapolated error falls like h^4 to ~1e-11 (h = 5e-4: <= 6e-10)
        assert abs(fd - exact) <= 5e-9 * scale, (fd, exact, scale)
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()


@pytest.mark.parametrize("n", [1, 2, 3])
def test_volume_load_stiffness_and_vanishing_first_variation(n):
    """The cavity volume alone: its second variation is the load-stiffness matrix H_V (K_n at
    p = 1 minus K_n at p = 0), and its first variation vanishes for n >= 1 (volume control does
    not act on the harmonic), whereas it does not for n = 0."""
    M = _model(2)
    u = _state(M, 20 + n)
    op = harmonic_operator(M, n)
    HV = op.matrix(u, 0.0) - op.matrix(u, 1.0)
    ev = Energy3D(M, n)
    U = M.full_displacement(u)
    rng = np.random.default_rng(n)
    v, w = rng.standard_normal(op.ndof), rng.standard_normal(op.ndof)
    Av, Aw = op.to_nodal(v), op.to_nodal(w)
    fd = _mixed_fd(lambda s, t: ev.potential(U, s * Av + t * Aw, 1.0, 0.0)[1], 5e-4)
    exact = v @ (HV @ w)
    assert abs(exact) > 1e-3
    assert abs(fd - exact) <= 1e-8 * max(1.0, abs(exact))
    h = 1e-4
    dV = (ev.potential(U, Av, h, 0.0)[1] - ev.potential(U, Av, -h, 0.0)[1]) / (2 * h)
    # the same amplitudes as an axisymmetric (n = 0) perturbation change the volume at first order
    ev0 = Energy3D(M, 0)
    dV0 = (ev0.potential(U, Av, h, 0.0)[1] - ev0.potential(U, Av, -h, 0.0)[1]) / (2 * h)
    assert abs(dV0) > 1e-2
    assert abs(dV) <= 1e-10 * abs(dV0)


@pytest.mark.parametrize("order", [1, 2])
def test_n0_reproduces_the_axisymmetric_tangent(order):
    """K_0 restricted to (a, b) is the model's K_T (with the load stiffness); the torsion c is decoupled."""
    M = _model(order)
    u = _state(M, 5)
    p = 0.6
    KT = M.stiffness_matrix(u, p).toarray()
    op = harmonic_operator(M, 0)
    K0 = op.matrix(u, p).toarray()
    idx = np.full(M.n, -1)
    for v in range(M.X.shape[0]):
        for c in range(2):
            if M.dofmap[v, c] >= 0:
                idx[M.dofmap[v, c]] = op.layout.dofmap[v, c]
    assert np.all(idx >= 0)
    assert np.abs(K0[np.ix_(idx, idx)] - KT).max() <= 1e-12 * np.abs(KT).max()
    cd = op.layout.dofmap[:, 2][op.layout.dofmap[:, 2] >= 0]
    assert len(cd) > 0 and len(idx) + len(cd) == op.ndof
    assert np.abs(K0[np.ix_(idx, cd)]).max() == 0.0
    # unloaded: the torsion block's only zero mode is the rigid rotation about the axis, u_phi = R
    Kc = harmonic_operator(M, 0).matrix(np.zeros(M.n), 0.0).toarray()[np.ix_(cd, cd)]
    lam = np.linalg.eigvalsh(Kc)
    rot = op.to_vector(np.stack([0 * M.X[:, 0], 0 * M.X[:, 0], M.X[:, 0]], axis=1))[cd]
    assert np.linalg.norm(Kc @ rot) <= 1e-10 * lam[-1] * np.linalg.norm(rot)
    assert abs(lam[0]) <= 1e-10 * lam[-1] and lam[1] > 1e-4 * lam[-1]


def test_band_assembly_equals_the_sparse_matrix():
    M = _model(2)
    u = _state(M, 7)
    for n in (1, 2):
        op = harmonic_operator(M, n)
        K = op.matrix(u, 0.4).toarray()
        ab = op.band(u, 0.4)
        B = np.zeros_like(K)
        for k in range(ab.shape[1]):
            i = np.arange(K.shape[0] - k)
            B[i + k, i] = ab[i, k]
            B[i, i + k] = ab[i, k]
        assert np.abs(B - K).max() <= 1e-12 * np.abs(K).max()


def test_axis_conditions():
    """n = 1: b = 0 and c = -a on the axis; n >= 2: a = b = c = 0 there; n = 0: a = c = 0."""
    M = _model(2)
    ax = M.mesh.node_sets["axis"]
    op1, op2, op0 = harmonic_operator(M, 1), harmonic_operator(M, 2), harmonic_operator(M, 0)
    d1 = op1.layout.dofmap[ax]
    assert np.all(d1[:, 1] < 0) and np.all(d1[:, 0] >= 0) and np.all(d1[:, 2] == d1[:, 0])
    assert np.all(op1.layout.coef[ax, 2] == -1.0)
    assert np.all(op2.layout.dofmap[ax] < 0)
    assert np.all(op0.layout.dofmap[ax][:, [0, 2]] < 0) and np.all(op0.layout.dofmap[ax][:, 1] >= 0)
    # the tie survives a round trip
    v = np.random.default_rng(0).standard_normal(op1.ndof)
    A = op1.to_nodal(v)
    assert np.allclose(A[ax, 2], -A[ax, 0]) and np.allclose(op1.to_vector(A), v)


def test_one_element_pass_serves_every_harmonic_n_ge_1():
    """The check assembles the element matrices once per state (``parts``, a polynomial in n) for
    all harmonics; an operator refuses parts made for other phi-averages (n = 0)."""
    M = _model(2)
    u = _state(M, 3)
    parts = harmonic_operator(M, 1).parts(u)
    for n in (1, 2, 4):
        op = harmonic_operator(M, n)
        assert np.array_equal(op.band(u, 0.4, parts), op.band(u, 0.4))
        assert op.inertia(u, 0.4, parts=parts) == op.inertia(u, 0.4)
    with pytest.raises(ValueError, match="phi-averages"):
        harmonic_operator(M, 0).inertia(u, 0.4, parts=parts)


def _reference_gauge(op: HarmonicOperator, u: np.ndarray) -> np.ndarray:
    """The gauge by its definition: the rigid modes scaled to a largest entry of 1, combined into
    those vanishing on the fixed amplitudes, their pivot columns as dof vectors."""
    modes = rigid_modes(op.model, u)
    modes /= np.abs(modes).reshape(2, -1).max(axis=1)[:, None, None]
    fixed = op.fixed.copy()
    fixed[op.tied, 2] = False
    C = modes[:, fixed].T
    _, s, vt = np.linalg.svd(C, full_matrices=True)
    null = vt[int(np.sum(s > 1e-8 * max(1.0, s[0]))):].T
    if null.shape[1] == 0:
        return np.zeros(0, np.int64)
    A = np.stack([op.to_vector(np.tensordot(null[:, j], modes, axes=1)) for j in range(null.shape[1])])
    return np.sort(pivot_columns(A))


@pytest.mark.parametrize("order", [1, 2])
def test_gauge_dofs_are_the_pivots_of_the_admissible_rigid_modes(order):
    M = _model(order)
    seen = set()
    for free_body in (True, False):
        op = HarmonicOperator(M, 1, free_body)
        for seed in range(5):
            u = _state(M, 40 + seed)
            g = op.gauge_dofs(u)
            assert np.array_equal(g, _reference_gauge(op, u))
            seen.add(len(g))
    assert len(harmonic_operator(M, 2).gauge_dofs(u)) == 0
    assert 2 in seen
