"""Mesh + materials -> the small problem interface the continuation needs.

The model works in scaled units (docs/physics.md, pitfall e): lengths / ``L`` (the inner cap radius),
stresses / ``S`` (the inner cap's shear modulus), so energies are in ``S L^3`` and volumes in
``L^3``. Unknowns are the free displacement dofs ``u`` (constrained dofs are zero and dropped)
and the cavity pressure ``p``.

Interface used by :mod:`snapjump_cli.fe.continuation` (nothing about meshes leaks through it):

* ``n`` - number of free dofs
* ``linearize(u, p)`` - one assembly: the residual ``R = f_int(u) - p dV/du`` and, on demand,
  the factorisation of the bordered matrix ``[[K_T, dR/dp], [c_u^T, c_p]]`` (``None`` if the
  iterate left the material domain: a failed iterate, docs/physics.md, pitfall c)
* ``measures(u, p)`` - the path measures ``zeta = (V, p, w)`` (cavity volume, pressure, pole
  displacement) with their derivatives; the arc length is measured in this space
* ``energy(u)`` - the strain energy

Linear solvers. The free dofs are numbered along the structure (Cuthill-McKee from the inner
cap's lower pole, :func:`snapjump_cli.mesh.data.cuthill_mckee`, the node order of the meshes of
:func:`snapjump_cli.mesh.build.mesh_scene`), so the symmetric ``K_T`` is banded. It is factorised
by a numba band LDL^T (:mod:`snapjump_kernels.banded`, which also gives the number of negative
eigenvalues), and the border is handled by block elimination with one step of iterative
refinement on the full bordered system (accurate next to limit points, where ``K_T`` is nearly
singular).
"""
from __future__ import annotations

import logging
import time

import numpy as np

from snapjump_cli.fe.limits import check_time
from snapjump_cli.mesh.data import Mesh, cuthill_mckee, fixed_dofs, number_dofs
from snapjump_kernels.calls import (
    assemble,
    bordered_factor,
    bordered_solve,
    cavity_assemble,
    element_tables,
    envelope_extents,
    evaluate,
    newton_correct,
    pressure_mass_inverse,
    quadrature_jacobians,
    reference_geometry,
)

log = logging.getLogger(__name__)

__all__ = ["Model", "Linearization"]


class Linearization:
    """Residual at ``(u, p)`` with the (lazily factorised) tangent of one assembly.

    ``V`` is the cavity volume (scaled, with the offset); ``data`` is ``None`` when the state was
    evaluated without its stiffness (``Model.linearize(..., stiffness=False)``).
    """

    def __init__(self, model: "Model", u, p, R, g, data, V=float("nan"), E=float("nan"), aux=None, H=None):
        self.model, self.u, self.p, self.R, self.g, self.data, self.V = model, u, p, R, g, data, V
        self.E = E  # strain energy
        self.aux = aux  # element pressures kappa M^-1 g(u), (ne, np), when evaluated with them
        self._H = H  # their derivative with respect to the element dofs, (ne, np, 2 nen)

    def aux_dir(self, x: np.ndarray) -> np.ndarray:
        """Linearised change of the element pressures for a displacement change ``x`` (free dofs)."""
        xe = np.where(self.model.edofs >= 0, x[np.maximum(self.model.edofs, 0)], 0.0)
        return np.einsum("ekj,ej->ek", self._H, xe)

    def factor(self, c_u: np.ndarray, c_p: float, shift: "float | np.ndarray" = 0.0,
               max_negative: int = -1) -> "BorderedSolver | None":
        """Factorise ``[[K_T + diag(shift), -dV/du], [c_u^T, c_p]]``; ``None`` if it is singular.

        A positive ``shift`` (a scalar, or one value per dof) turns a Newton step into an
        implicit gradient-flow (pseudo-time) step, used by the volume-constrained energy descent.
        ``max_negative >= 0``: ``None`` as well, without factorising the rest of the band, once
        ``K_T + diag(shift)`` has more negative pivots than that (a model whose factorisation can
        stop there; the axisymmetric model factorises it all and decides the same way).
        """
        data = self.data
        if np.any(shift):
            buffer = self.model.band_buffer()  # a reused band (no fresh pages to fault in), if the model keeps any
            if buffer is not None:
                data = buffer.reshape(-1)
                np.copyto(data, self.data)
            else:
                data = data.copy()
            data[self.model.diag_pos] += shift
        return self.model._factor(data, -self.g, c_u, c_p, max_negative)

    def stiffness(self) -> "scipy.sparse.csr_matrix":
        """``K_T`` alone (n x n, CSR)."""
        m = self.model
        return band_csr(self.data.reshape(m.n, m.kl + 1))

    def diag_abs(self) -> np.ndarray:
        """``|diag K_T|`` per dof (a Jacobi metric for ``shift``)."""
        return np.abs(self.data[self.model.diag_pos])


def band_csr(ab: np.ndarray) -> "scipy.sparse.csr_matrix":
    """The symmetric matrix whose lower band is ``ab (n, kl + 1)`` (``A[j + k, j] = ab[j, k]``) as
    scipy CSR."""
    import scipy.sparse as sp

    n, w = ab.shape
    L = sp.diags([ab[: n - k, k] for k in range(w)], [-k for k in range(w)], shape=(n, n), format="csr")
    return (L + sp.triu(L.T, 1)).tocsr()


class BorderedSolver:
    """Solves the bordered system ``[[K, b], [c^T, d]] [x; y] = [r; s]``.

    ``fac`` is the band LDL^T of ``K`` (``K`` kept for the refinement step).
    """

    def __init__(self, fac, K, b, c, d, n, n_negative=-1, ext=None, Kib=None, schur=None):
        self.fac, self.K, self.b, self.c, self.d, self.n = fac, K, b, c, d, n
        self.n_negative = n_negative  # negative eigenvalues of K
        self.ext = ext  # envelope column extents of the band
        self.Kib, self.schur = Kib, schur  # K^-1 b and d - c^T K^-1 b

    def solve(self, rhs: np.ndarray, refine: bool = True) -> np.ndarray:
        """Solution of the bordered system for one right-hand side ``[r; s]`` (length n + 1),
        with (``refine``) one step of iterative refinement on the full bordered system."""
        rhs = np.asarray(rhs, dtype=float)
        return bordered_solve(self.fac, self.K, self.ext, self.b, self.c, self.d, self.Kib, self.schur, rhs, refine)


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
        if pole_node is None:
            pole_node = int(np.atleast_1d(mesh.node_sets["pole_upper"])[0])
        self.pole_node = pole_node

        self._number_dofs(mesh.node_sets)
        self._storage_pattern()
        self.n_assemblies = 0  # evaluations with the stiffness
        self.n_residuals = 0  # evaluations of the energy / residual only
        self.n_factorizations = 0
        self.t_assembly = 0.0
        self.t_residual = 0.0
        self.t_factor = 0.0
        self.t_newton = 0.0  # in the compiled corrector (assembly, factorisation and solves together)

    # ---- dofs and the storage of K_T -----------------------------------------------------------
    def _number_dofs(self, node_sets: dict) -> None:
        """Free dofs numbered along the structure (Cuthill-McKee from the lower pole):
        ``dofmap``, ``n``, the free-entry bookkeeping and the pole's dof."""
        pole_node = self.pole_node
        nn = self.X.shape[0]
        fixed = fixed_dofs(nn, node_sets)
        self.fixed = fixed
        start = int(np.atleast_1d(node_sets.get("pole_lower", [pole_node]))[0])
        order = cuthill_mckee(nn, self.conn, start)  # the identity on a mesh from mesh_scene
        dofmap, k = number_dofs(order, fixed)
        self.dofmap = dofmap
        self.n = k
        free = ~fixed.ravel()
        self.free_mask = free
        self._free_index = dofmap.ravel()[free]  # free dof number of each free entry of U.ravel()
        self.pole_dof = int(dofmap[pole_node, 1])
        if self.pole_dof < 0:
            raise ValueError("the pole node's vertical dof is constrained")

    def _storage_pattern(self) -> None:
        """Element and cavity dof tables, the band and its envelope (and for SuperLU the CSR pattern
        of the bordered matrix), and the position of every element (and cavity) matrix entry in the
        assembled data array."""
        dofmap = self.dofmap
        edofs = dofmap[self.conn].reshape(self.conn.shape[0], -1)
        self.edofs = np.ascontiguousarray(edofs)
        edge_dofs = dofmap[self.edges].reshape(self.edges.shape[0], -1)
        self.edge_dofs = np.ascontiguousarray(edge_dofs)
        nd, nde = edofs.shape[1], edge_dofs.shape[1]
        ri, ci = np.repeat(edofs, nd, axis=1), np.tile(edofs, (1, nd))
        rg, cg = np.repeat(edge_dofs, nde, axis=1), np.tile(edge_dofs, (1, nde))
        valid = (ri >= 0) & (ci >= 0)
        self.kl = int(np.abs(ri - ci)[valid].max()) if valid.any() else 0
        n = self.n
        # the envelope of K_T (elements and the cavity's load stiffness): the LDL^T works inside it
        vg = (rg >= 0) & (cg >= 0)
        self.band_ext = envelope_extents(np.concatenate([ri[valid], rg[vg]]), np.concatenate([ci[valid], cg[vg]]),
                                         n, self.kl)

        def band_pos(r, c):  # lower band only, stored (n, kl + 1): A[i, j] -> [j, i - j]
            p = c * (self.kl + 1) + (r - c)
            return np.where((r >= 0) & (c >= 0) & (r >= c), p, -1)

        pos = band_pos
        self.epos = np.ascontiguousarray(pos(ri, ci).reshape(self.conn.shape[0], nd, nd).astype(np.int64))
        self.edge_pos = np.ascontiguousarray(pos(rg, cg).reshape(self.edges.shape[0], nde, nde).astype(np.int64))
        self.ndata = (self.kl + 1) * n
        ar = np.arange(n)
        self.diag_pos = pos(ar, ar)

    # ---- displacement bookkeeping --------------------------------------------------------------
    def full_displacement(self, u: np.ndarray) -> np.ndarray:
        """Free-dof vector -> (n_nodes, 2) displacement array."""
        U = np.zeros(self.X.shape)
        U.ravel()[self.free_mask] = u[self._free_index]
        return U

    def free_vector(self, U: np.ndarray) -> np.ndarray:
        """(n_nodes, 2) array -> free-dof vector (constrained entries dropped)."""
        u = np.zeros(self.n)
        u[self._free_index] = np.asarray(U).ravel()[self.free_mask]
        return u

    def positions(self, u: np.ndarray) -> np.ndarray:
        """Current node positions (scaled)."""
        return self.X + self.full_displacement(u)

    # ---- evaluations ---------------------------------------------------------------------------
    def _no_aux(self):
        """Empty element-pressure arrays: the reduced linearisation, nothing kept."""
        npr, nd = self.Np.shape[1], self.edofs.shape[1]
        return np.zeros((0, npr)), np.zeros((0, npr)), np.zeros((0, npr, nd))

    def _evaluate(self, u, p, want, aux_arrays=None):
        """One pass of :func:`snapjump_kernels.assembly.evaluate` (``want`` 0 energy, 1 residual,
        2 stiffness): ``(E, ok, R, g, V, data)`` with ``V`` including the offset; ``aux_arrays``:
        ``(p_geo, pb_out, H_out)`` of the mixed linearisation (default: none)."""
        check_time()  # the design's CPU-time limit (snapjump_cli.fe.limits)
        t0 = time.perf_counter()
        data = np.zeros(self.ndata if want >= 2 else 1)
        R = np.zeros(self.n)
        g = np.zeros(self.n)
        p_geo, pb_out, H_out = aux_arrays if aux_arrays is not None else self._no_aux()
        E, ok, V = evaluate(u, self.dofmap, self.X, self.conn, self.mat, self.mu, self.jm, self.kappa, self.dNdX,
                            self.N_ref, self.Rq, self.Wq, self.Np, self.Minv, self.edofs, self.epos, self.edges,
                            self.edge_dofs, self.edge_pos, p, want, R, g, data, p_geo, pb_out, H_out)
        if want >= 2:
            self.n_assemblies += 1
            self.t_assembly += time.perf_counter() - t0
        else:
            self.n_residuals += 1
            self.t_residual += time.perf_counter() - t0
        return E, ok, R, g, V + self.V_offset, data

    def energy(self, u: np.ndarray) -> float:
        """Total strain energy (scaled); ``nan`` outside the material domain."""
        E, ok, *_ = self._evaluate(u, 0.0, 0)
        return E if ok else float("nan")

    def volume(self, u: np.ndarray) -> float:
        """Cavity volume (scaled)."""
        return self.measures(u, 0.0)[0][0]

    def residual(self, u: np.ndarray, p: float) -> np.ndarray | None:
        """``f_int(u) - p dV/du``; ``None`` if the iterate left the material domain."""
        E, ok, R, g, V, _ = self._evaluate(u, p, 1)
        return R if ok else None

    def internal_force(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """``(f_int, dV/du)``, or ``None`` outside the material domain."""
        E, ok, R, g, V, _ = self._evaluate(u, 0.0, 1)
        return (R, g) if ok else None

    def linearize(self, u: np.ndarray, p: float, stiffness: bool = True, aux: np.ndarray | None = None
                  ) -> Linearization | None:
        """Residual and tangent from one assembly; ``None`` outside the material domain.

        ``stiffness=False`` evaluates the residual, ``dV/du`` and ``V`` only (about a fifth of the
        cost; no ``factor``). ``aux`` (ne, np): element pressures for the tangent's geometric term
        (the mixed linearisation, :func:`snapjump_kernels.assembly.assemble`); with the stiffness
        the result also carries the element pressures at ``u`` (``.aux``) and ``.aux_dir``."""
        arrays = None
        if stiffness:
            npr, nd = self.Np.shape[1], self.edofs.shape[1]
            ne = self.conn.shape[0]
            p_geo = np.ascontiguousarray(aux, dtype=float) if aux is not None else np.zeros((0, npr))
            arrays = (p_geo, np.zeros((ne, npr)), np.zeros((ne, npr, nd)))
        E, ok, R, g, V, data = self._evaluate(u, p, 2 if stiffness else 1, arrays)
        if not ok:
            return None
        if not stiffness:
            return Linearization(self, u, p, R, g, None, V, E)
        return Linearization(self, u, p, R, g, data, V, E, aux=arrays[1], H=arrays[2])

    def newton(self, u: np.ndarray, p: float, scales: np.ndarray, tol: float, max_newton: int,
               target: tuple[int, float] | None = None, riks: tuple | None = None, aux: np.ndarray | None = None,
               tol_inc: float = 0.0, theta_max: float = 0.5) -> tuple[Linearization, int] | None:
        """The continuation's Newton corrector in one compiled call (:mod:`snapjump_kernels.corrector`).

        ``scales`` are those of the path measures ``(V, p, w)``; the constraint is ``target =
        (k, value)`` (``zeta_k = value``) or ``riks = (z0, t_z, t_u, u_ref, ds, alpha2)``; ``aux``
        the element pressures to start the mixed linearisation from; ``tol_inc > 0`` the error
        test (Riks), with which Newton stops when a correction above ``tol_inc`` exceeds ``theta_max``
        times the one before. Returns the linearisation at the accepted state (its stiffness assembled; with
        ``riks`` also the tangent system's solution ``tangent_x``, its inertia ``tangent_inertia``
        and the element pressures' change along it ``daux_x``) and the iterations, or ``None`` if
        Newton failed.
        """
        check_time()
        t0 = time.perf_counter()
        if riks is not None:
            z0, t_z, t_u, u_ref, ds, alpha2 = riks
            k, val = -1, 0.0
        else:
            k, val = target
            z0 = t_z = np.zeros(3)
            t_u = u_ref = np.zeros(self.n)
            ds, alpha2 = 0.0, 0.0
        p_geo = np.ascontiguousarray(aux, dtype=float) if aux is not None else np.zeros((0, self.Np.shape[1]))
        ok, it, n_fac, u1, p1, R, g, data, V, E, p_el, xt, n_neg, schur, dp_el = newton_correct(
            np.ascontiguousarray(u, dtype=float), float(p), int(k), float(val), np.asarray(z0, float),
            np.asarray(t_z, float), np.ascontiguousarray(t_u, dtype=float), np.ascontiguousarray(u_ref, dtype=float),
            float(ds), float(alpha2), np.asarray(scales, float), float(tol), int(max_newton), self.pole_dof,
            float(self.V_offset), self.kl, self.band_ext, self.dofmap, self.X, self.conn, self.mat, self.mu,
            self.jm, self.kappa, self.dNdX, self.N_ref, self.Rq, self.Wq, self.Np, self.Minv, self.edofs, self.epos,
            self.edges, self.edge_dofs, self.edge_pos, p_geo, float(tol_inc), float(theta_max))
        self.n_assemblies += it + 1
        self.n_factorizations += n_fac
        self.t_newton += time.perf_counter() - t0
        if not ok:
            return None
        if np.isnan(E):  # accepted by the error test: the corrected iterate, cavity evaluated only
            lin = Linearization(self, u1, p1, None, g, None, V, E, aux=p_el)
        else:
            lin = Linearization(self, u1, p1, R, g, data, V, E, aux=p_el)
        if riks is not None:
            lin.tangent_x, lin.tangent_inertia, lin.daux_x = xt, (n_neg, schur), dp_el
        return lin, it

    def energy_volume(self, u: np.ndarray) -> tuple[float, float] | None:
        """Strain energy and cavity volume (scaled, with the offset) from one energy-only pass;
        ``None`` outside the material domain (exactly where :meth:`linearize` gives ``None``)."""
        E, ok, R, g, V, _ = self._evaluate(u, 0.0, 0)
        return (E, V) if ok else None

    def measure_rates(self, lin: Linearization, v: np.ndarray, q: float) -> tuple[np.ndarray, np.ndarray]:
        """The path measures ``(V, p, w)`` at the evaluated state ``lin`` and their change along
        ``(v, q)``: ``(g . v, q, v_pole)`` (:meth:`measures` without forming ``d zeta / du``)."""
        pole = self.pole_dof
        return (np.array([lin.V, lin.p, lin.u[pole]]),
                np.array([float(lin.g @ v), float(q), float(v[pole])]))

    def measures(self, u: np.ndarray, p: float, lin: Linearization | None = None):
        """Path measures ``zeta = (V, p, w)`` and their derivatives (cavity only: cheap; free
        when ``lin``, an evaluation at the same ``u``, is given).

        Returns
        -------
        zeta : (3,) ; dzeta_du : (3, n) ; dzeta_dp : (3,)
        """
        dz = np.zeros((3, self.n))
        if lin is not None:
            V = lin.V
            dz[0] = lin.g
        else:
            V = cavity_assemble(self.positions(u), self.edges, self.edge_dofs, self.edge_pos, 0.0, 1, dz[0],
                                np.zeros(1)) + self.V_offset
        dz[2, self.pole_dof] = 1.0
        return np.array([V, p, u[self.pole_dof]]), dz, np.array([0.0, 1.0, 0.0])

    def band_buffer(self) -> np.ndarray | None:
        """A band array to reuse for a shifted copy of a linearisation's band (the multi-harmonic
        model keeps a pool of them); ``None``: this model keeps none (a fresh copy is made)."""
        return None

    def _factor(self, data, b, c_u, c_p, max_negative: int = -1) -> BorderedSolver | None:
        s = factor_bordered(self, data, b, c_u, c_p)
        return None if s is not None and 0 <= max_negative < s.n_negative else s

    def stiffness_matrix(self, u: np.ndarray, p: float) -> "scipy.sparse.csr_matrix":
        """``K_T`` alone (n x n, CSR), for stability checks and tests."""
        return self.linearize(u, p).stiffness()

    def max_dilatation(self, u: np.ndarray) -> float:
        """Largest ``|theta - 1|`` of the projected dilatation, the incompressibility error of the
        mixed element (``theta = 1 + p / kappa``)."""
        U = self.full_displacement(u)
        E, ok, dev = assemble(
            U, self.conn, self.mat, self.mu, self.jm, self.kappa, self.dNdX, self.N_ref, self.Rq, self.Wq,
            self.Np, self.Minv, self.edofs, self.epos, 0, np.zeros(self.n), np.zeros(1), *self._no_aux(),
        )
        return dev if ok else float("nan")

    def jacobians(self, u: np.ndarray) -> np.ndarray:
        """``J`` at every quadrature point (volume preservation diagnostic)."""
        return quadrature_jacobians(self.full_displacement(u), self.conn, self.dNdX, self.N_ref, self.Rq)


def factor_bordered(owner, data: np.ndarray, b: np.ndarray, c_u: np.ndarray, c_p: float) -> BorderedSolver | None:
    """The bordered band factorisation of a problem's tangent ``data`` (lower band, ``owner.n`` x
    ``owner.kl + 1``, envelope ``owner.band_ext``), counted and timed in ``owner.n_factorizations``
    and ``owner.t_factor``; ``None`` if it is singular. Shared by :class:`Model` and
    :class:`snapjump_cli.fe.branch.model.MultiHarmonicModel`."""
    t0 = time.perf_counter()
    n = owner.n
    try:
        K = data.reshape(n, owner.kl + 1)
        ok, nneg, fac, Kib, schur = bordered_factor(K, owner.band_ext, b, c_u, float(c_p))
        if not ok or not np.isfinite(schur) or schur == 0.0:
            return None
        s = BorderedSolver(fac, K, b, c_u, float(c_p), n, nneg, owner.band_ext, Kib, schur)
    except RuntimeError:  # exactly singular
        return None
    finally:
        owner.t_factor += time.perf_counter() - t0
    owner.n_factorizations += 1
    return s
