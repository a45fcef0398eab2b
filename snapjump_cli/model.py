"""Mesh + materials -> the small problem interface the continuation needs.

The model works in scaled units (SPEC pitfall e): lengths / ``L`` (the inner cap radius),
stresses / ``S`` (the inner cap's shear modulus), so energies are in ``S L^3`` and volumes in
``L^3``. Unknowns are the free displacement dofs ``u`` (constrained dofs are zero and dropped)
and the cavity pressure ``p``.

Interface used by :mod:`snapjump_cli.continuation` (nothing about meshes leaks through it):

* ``n`` - number of free dofs
* ``residual(u, p)`` - ``f_int(u) - p dV/du`` or ``None`` if the iterate left the material domain
* ``dR_dp(u)`` - ``-dV/du``
* ``measures(u, p)`` - the path measures ``zeta = (V, p, w)`` (cavity volume, pressure, pole
  displacement) with their derivatives; the arc length is measured in this space
* ``factor_bordered(u, p, c_u, c_p)`` - factorises ``[[K_T, dR/dp], [c_u^T, c_p]]`` and returns an
  object with ``solve(rhs)``; ``c_u`` must vanish outside the cavity and pole dofs
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from snapjump_cli.meshdata import Mesh
from snapjump_kernels.assembly import assemble, pressure_mass_inverse, quadrature_jacobians, reference_geometry
from snapjump_kernels.cavity import cavity_assemble
from snapjump_kernels.elements import element_tables

log = logging.getLogger(__name__)

__all__ = ["Model", "MeasureIndex", "BorderedSolver"]


class MeasureIndex:
    """Indices into the measure vector ``zeta``."""

    V = 0
    P = 1
    W = 2


@dataclass
class BorderedSolver:
    """A factorised bordered matrix; ``solve(rhs)`` accepts (n+1,) or (n+1, k) right-hand sides."""

    lu: object
    n: int

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self.lu.solve(np.asarray(rhs, dtype=float))


class Model:
    """An axisymmetric mixed-Gent solid with a fluid cavity under volume control.

    Parameters
    ----------
    mesh : the meshed scene
    mu : shear modulus per material index [Pa]
    J_m : Gent parameter per material index
    bulk_ratio : ``kappa / mu`` of the volumetric penalty
    L, S : length and stress scales (SI) used to non-dimensionalise
    pole_node : node whose vertical displacement is the path measure ``w``
        (default: ``mesh.node_sets["pole_upper"]``)
    """

    def __init__(
        self,
        mesh: Mesh,
        mu: np.ndarray,
        J_m: np.ndarray,
        bulk_ratio: float,
        L: float,
        S: float,
        pole_node: int | None = None,
    ) -> None:
        self.mesh = mesh
        self.L = float(L)
        self.S = float(S)
        self.X = np.ascontiguousarray(mesh.nodes / self.L)
        self.conn = np.ascontiguousarray(mesh.elements.astype(np.int64))
        self.mat = np.ascontiguousarray(mesh.material.astype(np.int64))
        self.mu = np.asarray(mu, float) / self.S
        self.jm = np.asarray(J_m, float)
        self.kappa = bulk_ratio * self.mu
        tab = element_tables(mesh.order)
        self.N_ref = np.ascontiguousarray(tab.N)
        self.Np = np.ascontiguousarray(tab.Np)
        self.dNdX, self.Rq, self.Wq, min_det = reference_geometry(self.X, self.conn, tab.dN, tab.N, tab.w)
        if not min_det > 0:
            raise ValueError(f"mesh has a non-positive element Jacobian (min det = {min_det:.3g})")
        self.Minv = pressure_mass_inverse(self.Wq, self.Np)
        self.edges = np.ascontiguousarray(mesh.edge_sets["cavity"].astype(np.int64))
        self.V_offset = mesh.cavity_volume_offset / self.L**3

        # ---- dofs ------------------------------------------------------------------------------
        nn = self.X.shape[0]
        fixed = np.zeros((nn, 2), bool)
        fixed[mesh.node_sets["axis"], 0] = True
        fixed[mesh.node_sets.get("dirichlet_x", np.zeros(0, int)), 0] = True
        fixed[mesh.node_sets.get("dirichlet_y", np.zeros(0, int)), 1] = True
        self.fixed = fixed
        dofmap = -np.ones((nn, 2), np.int64)
        free = ~fixed.ravel()
        dofmap.ravel()[free] = np.arange(free.sum())
        self.dofmap = dofmap
        self.n = int(free.sum())
        self.free_mask = free
        if pole_node is None:
            pole_node = int(np.atleast_1d(mesh.node_sets["pole_upper"])[0])
        self.pole_node = pole_node
        self.pole_dof = int(dofmap[pole_node, 1])
        if self.pole_dof < 0:
            raise ValueError("the pole node's vertical dof is constrained")

        # ---- CSR pattern of the bordered matrix (n + 1) -----------------------------------------
        n1 = self.n + 1
        edofs = dofmap[self.conn].reshape(self.conn.shape[0], -1)  # (ne, 2 nen)
        self.edofs = np.ascontiguousarray(edofs)
        nd = edofs.shape[1]
        rows = np.repeat(edofs, nd, axis=1).ravel()
        cols = np.tile(edofs, (1, nd)).ravel()
        keep = (rows >= 0) & (cols >= 0)
        gdofs = np.unique(dofmap[np.unique(self.edges)].ravel())
        gdofs = gdofs[gdofs >= 0]
        bdofs = np.union1d(gdofs, [self.pole_dof])
        self.border_dofs = bdofs
        br = np.concatenate([bdofs, np.full(len(bdofs), self.n), [self.n]])
        bc = np.concatenate([np.full(len(bdofs), self.n), bdofs, [self.n]])
        keys = np.unique(np.concatenate([rows[keep] * n1 + cols[keep], br * n1 + bc]))
        self.csr_rows = keys // n1
        self.csr_cols = keys % n1
        self.indptr = np.searchsorted(self.csr_rows, np.arange(n1 + 1)).astype(np.int64)
        self.indices = self.csr_cols.astype(np.int64)
        self.nnz = len(keys)

        def pos(r, c):
            k = r * n1 + c
            p = np.searchsorted(keys, k)
            p = np.where((r >= 0) & (c >= 0), p, -1)
            return p

        ep = pos(np.repeat(edofs, nd, axis=1), np.tile(edofs, (1, nd)))
        self.epos = np.ascontiguousarray(ep.reshape(self.conn.shape[0], nd, nd).astype(np.int64))
        edge_dofs = dofmap[self.edges].reshape(self.edges.shape[0], -1)
        self.edge_dofs = np.ascontiguousarray(edge_dofs)
        nde = edge_dofs.shape[1]
        gp = pos(np.repeat(edge_dofs, nde, axis=1), np.tile(edge_dofs, (1, nde)))
        self.edge_pos = np.ascontiguousarray(gp.reshape(self.edges.shape[0], nde, nde).astype(np.int64))
        self.col_pos = pos(bdofs, np.full(len(bdofs), self.n))
        self.row_pos = pos(np.full(len(bdofs), self.n), bdofs)
        self.corner_pos = int(pos(np.array([self.n]), np.array([self.n]))[0])
        self.n_assemblies = 0
        self.n_factorizations = 0
        self.t_assembly = 0.0
        self.t_factor = 0.0

    # ---- displacement bookkeeping --------------------------------------------------------------
    def full_displacement(self, u: np.ndarray) -> np.ndarray:
        """Free-dof vector -> (n_nodes, 2) displacement array."""
        U = np.zeros(self.X.shape)
        U.ravel()[self.free_mask] = u
        return U

    def positions(self, u: np.ndarray) -> np.ndarray:
        """Current node positions (scaled)."""
        return self.X + self.full_displacement(u)

    # ---- evaluations ---------------------------------------------------------------------------
    def _eval(self, u, p, want, data=None):
        import time

        t0 = time.perf_counter()
        U = self.full_displacement(u)
        f = np.zeros(self.n)
        if data is None:
            data = np.zeros(1)
        E, ok, _ = assemble(
            U, self.conn, self.mat, self.mu, self.jm, self.kappa, self.dNdX, self.N_ref, self.Rq, self.Wq,
            self.Np, self.Minv, self.edofs, self.epos, want, f, data,
        )
        g = np.zeros(self.n)
        V = cavity_assemble(self.X + U, self.edges, self.edge_dofs, self.edge_pos, -p, want, g, data)
        self.n_assemblies += 1
        self.t_assembly += time.perf_counter() - t0
        return E, ok, f, g, V + self.V_offset

    def energy(self, u: np.ndarray) -> float:
        """Total strain energy (scaled); ``nan`` outside the material domain."""
        E, ok, *_ = self._eval(u, 0.0, 0)
        return E if ok else float("nan")

    def volume(self, u: np.ndarray) -> float:
        """Cavity volume (scaled)."""
        return self._eval(u, 0.0, 0)[4]

    def residual(self, u: np.ndarray, p: float) -> np.ndarray | None:
        """``f_int(u) - p dV/du``; ``None`` if the iterate left the material domain."""
        E, ok, f, g, V = self._eval(u, p, 1)
        if not ok:
            return None
        return f - p * g

    def internal_force(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """``(f_int, dV/du)``, or ``None`` outside the material domain."""
        E, ok, f, g, V = self._eval(u, 0.0, 1)
        return (f, g) if ok else None

    def dR_dp(self, u: np.ndarray) -> np.ndarray:
        return -self._eval(u, 0.0, 1)[3]

    def measures(self, u: np.ndarray, p: float):
        """Path measures ``zeta = (V, p, w)`` and their derivatives.

        Returns
        -------
        zeta : (3,) ; dzeta_du : (3, n) ; dzeta_dp : (3,)
        """
        E, ok, f, g, V = self._eval(u, p, 0)
        g = np.zeros(self.n)
        cavity_assemble(self.positions(u), self.edges, self.edge_dofs, self.edge_pos, 0.0, 1, g, np.zeros(1))
        dz = np.zeros((3, self.n))
        dz[0] = g
        dz[2, self.pole_dof] = 1.0
        return np.array([V, p, u[self.pole_dof]]), dz, np.array([0.0, 1.0, 0.0])

    def tangent_data(self, u: np.ndarray, p: float):
        """CSR values of ``K_T = d(f_int - p dV/du)/du`` (border entries zero), ``dV/du``, ok."""
        data = np.zeros(self.nnz)
        E, ok, f, g, V = self._eval(u, p, 2, data)
        return data, g, ok

    def factor_bordered(self, u: np.ndarray, p: float, c_u: np.ndarray, c_p: float) -> BorderedSolver | None:
        """Factorise ``[[K_T, -dV/du], [c_u^T, c_p]]``; ``None`` outside the material domain."""
        import time

        data, g, ok = self.tangent_data(u, p)
        if not ok:
            return None
        bd = self.border_dofs
        data[self.col_pos] = -g[bd]
        data[self.row_pos] = c_u[bd]
        data[self.corner_pos] = c_p
        t0 = time.perf_counter()
        A = sp.csc_matrix(sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n + 1, self.n + 1)))
        try:
            lu = spla.splu(A, permc_spec="COLAMD")
        except RuntimeError:  # exactly singular
            return None
        self.n_factorizations += 1
        self.t_factor += time.perf_counter() - t0
        return BorderedSolver(lu, self.n)

    def stiffness_matrix(self, u: np.ndarray, p: float) -> sp.csr_matrix:
        """``K_T`` alone (n x n), for stability checks and tests."""
        data, g, ok = self.tangent_data(u, p)
        A = sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n + 1, self.n + 1))
        return A[: self.n, : self.n].tocsr()

    def jacobians(self, u: np.ndarray) -> np.ndarray:
        """``J`` at every quadrature point (volume preservation diagnostic)."""
        return quadrature_jacobians(self.full_displacement(u), self.conn, self.dNdX, self.N_ref, self.Rq)
