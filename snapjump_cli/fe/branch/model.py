"""The nonlinear multi-harmonic model: the actuator's 3D deformation as a Fourier series on the 2D mesh.

:class:`MultiHarmonicModel` is the problem interface of :mod:`snapjump_cli.fe.continuation` (as
:class:`snapjump_cli.fe.axisym.model.Model` is) for displacements

    u_r = sum_k a_k cos n_k phi,   u_z = sum_k b_k cos n_k phi,   u_phi = sum_{k>=1} c_k sin n_k phi

on the axisymmetric model's mesh, element and cavity, with the harmonics ``n_k`` (``0`` first,
then e.g. the multiples of a critical harmonic ``n_c``). This subspace (mirror-symmetric about
``phi = 0``; with the multiples of ``n_c`` only, also ``2 pi / n_c``-periodic) is invariant
under the equations, and it holds the branch that bifurcates from harmonic ``n_c`` (equivariant
branching lemma): a trace that starts in it stays in it. The kernels are
:mod:`snapjump_kernels.mh_element` (energy, residual, tangent) and :mod:`snapjump_kernels.mh_cavity` (the exact 3D cavity volume).

Constraints per harmonic are those of :class:`snapjump_cli.fe.stability.harmonics.HarmonicOperator`: ``n = 0``
keeps the axisymmetric model's own (so that with the harmonic 0 alone this *is* that model, to
round-off); for ``n >= 1`` the axis conditions of a single-valued displacement (``n = 1``:
``b = 0``, ``c = -a``; ``n >= 2``: all zero) and, for a supported cap, its supports. The rigid
modes of harmonic 1 of a free body (translation across the axis, tilt) are exact symmetries of
the nonlinear problem; each is removed by fixing one amplitude of harmonic 1 (``gauge``, as the
harmonic check chooses them), which selects one member of each family of equivalent states.

Units are the axisymmetric model's (lengths / L, stresses / S). The path measures are
``(V, p, w)``, ``w`` the vertical displacement of the model's pole node: on the axis every
harmonic ``n >= 1`` vanishes, so it is the pole's own displacement.
"""
from __future__ import annotations

import logging
import sys
import time

import numpy as np

from snapjump_cli.fe.limits import check_time
from snapjump_cli.mesh.data import number_dofs
from snapjump_cli.fe.axisym.model import BorderedSolver, Linearization
from snapjump_cli.fe.branch.block import HarmonicBlock, harmonic_block
from snapjump_cli.fe.branch.layout import component_index
from snapjump_kernels.calls import (
    band_of_maps,
    bordered_factor_upto,
    mh_assemble_band,
    mh_cavity,
    mh_elements,
    scatter_band,
    scatter_vector,
)

log = logging.getLogger(__name__)

__all__ = ["MultiHarmonicModel", "component_index", "transfer"]


def _refs_of_a_pooled_array() -> int:
    """``sys.getrefcount`` of an array held only by a list, read as the pool reads it."""
    pool = [np.zeros(1)]
    return sys.getrefcount(pool[0])


#: ``sys.getrefcount(pool[i])`` of an array that only the list ``pool`` holds
_FREE_REFS = _refs_of_a_pooled_array()


def transfer(src: "MultiHarmonicModel", dst: "MultiHarmonicModel", u: np.ndarray, strict: bool = True) -> np.ndarray:
    """A state of ``src`` as a free vector of ``dst`` on the same mesh: the nodal amplitudes of the
    harmonics both keep, zero in those only ``dst`` keeps; with ``strict`` every harmonic of ``src``
    must be kept by ``dst`` (else the ones ``dst`` does not keep are dropped: a restriction)."""
    A = src.amplitudes(u)
    B = np.zeros((A.shape[0], dst.nc))
    for k, n in enumerate(src.hn):
        kd = int(np.searchsorted(dst.hn, n))
        if kd >= len(dst.hn) or dst.hn[kd] != n:
            if strict:
                raise ValueError(f"harmonic {int(n)} of the branch is not kept by the full model")
            continue
        w = 2 if n == 0 else 3
        B[:, component_index(kd, 0):component_index(kd, 0) + w] = A[:, component_index(k, 0):component_index(k, 0) + w]
    return dst.free_vector(B)


class _MixedLinearization(Linearization):
    """A :class:`~snapjump_cli.fe.axisym.model.Linearization` with the element pressures of every
    phi point (``aux``, ``(ne, nphi, np)``) and their derivative (``(ne, nphi, np, nd)``)."""

    def aux_dir(self, x: np.ndarray) -> np.ndarray:
        """Linearised change of the element pressures for a displacement change ``x`` (free dofs)."""
        m = self.model
        xe = np.where(m.edofs >= 0, m.ecoef * x[np.maximum(m.edofs, 0)], 0.0)
        return np.einsum("ejkd,ed->ejk", self._H, xe)


class MultiHarmonicModel:
    """A truncated Fourier series of harmonics ``hn`` on an axisymmetric :class:`~snapjump_cli.fe.axisym.model.Model`.

    Parameters
    ----------
    model : the axisymmetric model (mesh, materials, scales, constraints)
    hn : the harmonics kept, starting with 0 (e.g. ``[0, 1, 2]`` or ``[0, 2, 4]``)
    n_phi : intervals of the phi rule on ``[0, pi / hn[1]]`` (default ``2 K_max + 2``, ``K_max``
        the highest harmonic in units of ``hn[1]``: exact for the quadratic terms and the cavity)
    free_body : as in :class:`snapjump_cli.fe.stability.harmonics.HarmonicOperator` (default: a full actuator)
    gauge : ``(node, comp)`` amplitudes of harmonic 1 fixed to zero (removing the rigid modes)
    imperfection : ``(nn, nc)`` nodal amplitudes of an initial geometric imperfection (default
        none): the stress-free body is the perfect one displaced by them, and ``u`` is measured
        from it (:func:`snapjump_kernels.mh_material.imperfect_point`). They must satisfy the
        axis conditions of their harmonics (a mode of :class:`~snapjump_cli.fe.stability.harmonics.HarmonicOperator` does).
    """

    solver = "banded"
    #: band buffers kept for reuse (each ``n (kl + 1)`` doubles; more are allocated when all are in use)
    pool_size: int = 6

    def __init__(self, model, hn, n_phi: int | None = None, free_body: bool | None = None,
                 gauge: list[tuple[int, int]] = (), imperfection: np.ndarray | None = None) -> None:
        from snapjump_kernels.calls import phi_rule, point_gradients  # (JIT: numba imported on first call)

        hn = np.asarray(hn, np.int64)
        if hn.ndim != 1 or hn[0] != 0 or np.any(np.diff(hn) <= 0):
            raise ValueError(f"harmonics must start with 0 and increase, got {list(hn)}")
        self.base = model
        self.hn = hn
        self.gauge = [(int(a), int(c)) for a, c in gauge]
        self.L, self.S = model.L, model.S
        self.mesh = model.mesh
        self.X = model.X
        n1 = int(hn[1]) if len(hn) > 1 else 1
        if len(hn) > 1 and np.any(hn % n1):
            raise ValueError(f"harmonics must be multiples of the first one, got {list(hn)}")
        k_max = int(hn[-1] // n1) if len(hn) > 1 else 0
        if n_phi is None:
            n_phi = 2 * k_max + 2 if k_max > 0 else 0
        self.n_phi = int(n_phi)
        self.phis, self.wphi = phi_rule(n1, self.n_phi)
        mesh = model.mesh
        if free_body is None:
            free_body = mesh.scene == "design"
        self.free_body = bool(free_body)
        K = len(hn)
        self.nc = 2 + 3 * (K - 1)
        nn = model.X.shape[0]
        fixed = np.zeros((nn, self.nc), bool)
        fixed[:, :2] = model.fixed
        axis = np.asarray(mesh.node_sets["axis"], np.int64)
        dx = np.asarray(mesh.node_sets.get("dirichlet_x", np.zeros(0, np.int64)), np.int64)
        dy = np.asarray(mesh.node_sets.get("dirichlet_y", np.zeros(0, np.int64)), np.int64)
        tied = np.zeros(nn, bool)
        for k in range(1, K):
            o = component_index(k, 0)
            if not self.free_body:
                fixed[dx, o] = fixed[dx, o + 2] = True
                fixed[dy, o + 1] = True
            fixed[axis, o + 1] = True
            if hn[k] == 1:
                tied[axis] = ~fixed[axis, o]
                fixed[axis, o + 2] = True
            else:
                fixed[axis, o:o + 3] = True
        k1 = int(np.searchsorted(hn, 1))
        for node, comp in gauge:
            if k1 >= K or hn[k1] != 1:
                raise ValueError("a gauge fixes amplitudes of harmonic 1, which is not kept")
            fixed[node, component_index(k1, comp)] = True
            if comp == 0:
                tied[node] = False
        self.fixed = fixed
        key = np.where(model.dofmap >= 0, model.dofmap, np.iinfo(np.int64).max).min(axis=1)
        order = np.argsort(key, kind="stable")
        dofmap, ndof = number_dofs(order, fixed)
        coef = np.ones((nn, self.nc))
        if k1 < K and hn[k1] == 1:
            o = component_index(k1, 0)
            dofmap[tied, o + 2] = dofmap[tied, o]
            coef[tied, o + 2] = -1.0
        self.dofmap, self.coef, self.n = dofmap, coef, ndof
        conn, edges = model.conn, model.edges
        self.edofs = np.ascontiguousarray(dofmap[conn].reshape(conn.shape[0], -1))
        self.ecoef = np.ascontiguousarray(coef[conn].reshape(conn.shape[0], -1))
        self.gdofs = np.ascontiguousarray(dofmap[edges].reshape(edges.shape[0], -1))
        self.gcoef = np.ascontiguousarray(coef[edges].reshape(edges.shape[0], -1))
        self.kl, self.band_ext = band_of_maps((self.edofs, self.gdofs), ndof)
        self.diag_pos = np.arange(ndof) * (self.kl + 1)
        self.pole_node = model.pole_node
        self.pole_dof = int(dofmap[model.pole_node, 1])
        self.V_offset = model.V_offset
        self.A_imp = np.zeros((nn, self.nc))
        self.Fi = np.zeros((0, 1, 1, 3, 3))
        self.Jimp = np.zeros((0, 1, 1))
        self.Minvp = np.zeros((0, 1, 1, 1))
        if imperfection is not None:
            A_imp = np.asarray(imperfection, float)
            if A_imp.shape != (nn, self.nc):
                raise ValueError(f"imperfection must have shape {(nn, self.nc)}, got {A_imp.shape}")
            self.A_imp = np.ascontiguousarray(A_imp)
            F0 = point_gradients(self.A_imp, model.conn, model.dNdX, model.N_ref, model.Rq, hn, self.phis)
            self.Jimp = np.ascontiguousarray(np.linalg.det(F0))
            if np.any(self.Jimp <= 0.0):
                raise ValueError("the imperfection folds the body (det F0 <= 0 somewhere): lower its amplitude")
            self.Fi = np.ascontiguousarray(np.linalg.inv(F0))
            # the imperfect body's pressure mass per element and phi point: sum_q W_q Jimp Np Np^T
            Mp = np.einsum("eq,eqj,qk,ql->ejkl", model.Wq, self.Jimp, model.Np, model.Np)
            self.Minvp = np.ascontiguousarray(np.linalg.inv(Mp))
        self.n_assemblies = self.n_residuals = self.n_factorizations = self.n_block_assemblies = 0
        self.n_given_up = 0  # factorisations given up at a negative pivot (``_factor``'s ``max_negative``)
        self.t_assembly = self.t_factor = 0.0
        self._pool: list[np.ndarray] = []
        self._sel_all = np.ones(K, dtype=np.bool_)
        self._blocks: dict = {}

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_pool"] = []  # buffers, not state
        return state

    def release_buffers(self) -> None:
        """Drop the reused band buffers (a followed branch of design B, ``N = 4``, keeps 4 of
        ~15 MB while the model lives); they are allocated again when needed."""
        self._pool.clear()

    def band_buffer(self) -> np.ndarray:
        """A band array ``(n, kl + 1)`` that nothing else refers to, zero outside the envelope
        ``band_ext`` (its envelope holds anything: the kernels that fill it write all of it).

        A buffer of the pool is free when the pool holds the only reference to it: a
        :class:`~snapjump_cli.fe.axisym.model.Linearization` or a
        :class:`~snapjump_cli.fe.axisym.model.BorderedSolver` still using it holds it or a view of it
        (a view refers to it as its base), so a band in use is never handed out again. Reusing
        the buffers saves allocating, zeroing and faulting in ~15 MB per assembly and
        factorisation (design B, ``N = 4``)."""
        pool = self._pool
        for i in range(len(pool)):
            if sys.getrefcount(pool[i]) <= _FREE_REFS:
                return pool[i]
        ab = np.zeros((self.n, self.kl + 1))
        if len(pool) < self.pool_size:
            pool.append(ab)
        return ab

    # ---- vectors -------------------------------------------------------------------------------
    def amplitudes(self, u: np.ndarray) -> np.ndarray:
        """Free-dof vector -> nodal amplitudes ``(nn, nc)`` (zeros where fixed, ties applied)."""
        A = np.zeros(self.dofmap.shape)
        m = self.dofmap >= 0
        A[m] = u[self.dofmap[m]] * self.coef[m]
        return A

    def total_amplitudes(self, u: np.ndarray) -> np.ndarray:
        """Nodal amplitudes of the displacement from the *perfect* reference (the imperfection
        plus :meth:`amplitudes`)."""
        return self.amplitudes(u) + self.A_imp

    def free_vector(self, A: np.ndarray) -> np.ndarray:
        """Nodal amplitudes ``(nn, nc)`` -> free-dof vector (fixed entries dropped; a tied ``c``
        is represented by its ``a``)."""
        u = np.zeros(self.n)
        m = (self.dofmap >= 0) & (self.coef > 0)
        u[self.dofmap[m]] = np.asarray(A)[m]
        return u

    def embed(self, u_axi: np.ndarray, modes: dict[int, np.ndarray] | None = None) -> np.ndarray:
        """The free vector of an axisymmetric state ``u_axi`` (of :attr:`base`) plus, optionally,
        harmonic amplitudes ``modes[n] = (nn, 3)`` (``a, b, c`` per node, as
        :meth:`snapjump_cli.fe.stability.harmonics.HarmonicOperator.to_nodal` gives them)."""
        A = np.zeros(self.dofmap.shape)
        A[:, :2] = self.base.full_displacement(u_axi)
        for n, Am in (modes or {}).items():
            k = int(np.searchsorted(self.hn, n))
            if k >= len(self.hn) or self.hn[k] != n:
                raise ValueError(f"harmonic {n} is not kept ({list(self.hn)})")
            o = component_index(k, 0)
            A[:, o:o + 3] = Am
        A[self.dofmap < 0] = 0.0
        return self.free_vector(A)

    def harmonic_part(self, u: np.ndarray, n: int) -> np.ndarray:
        """Nodal ``(a, b, c)`` of harmonic ``n`` (``(nn, 2)`` for ``n = 0``)."""
        A = self.amplitudes(u)
        k = int(np.searchsorted(self.hn, n))
        if k >= len(self.hn) or self.hn[k] != n:
            raise ValueError(f"harmonic {n} is not kept ({list(self.hn)})")
        o = component_index(k, 0)
        return A[:, o:o + (2 if n == 0 else 3)].copy()

    def section(self, u: np.ndarray, phi: float) -> np.ndarray:
        """Current ``(r, z)`` of every node in the meridian section at ``phi`` (scaled; ``r`` the
        radial coordinate of the material point's ring, i.e. ``R + u_r(phi)``; ``u_phi`` moves
        the point out of the section and is not shown; the imperfection is included)."""
        A = self.total_amplitudes(u)
        x = self.X.copy()
        for k, n in enumerate(self.hn):
            o = component_index(k, 0)
            x[:, 0] += A[:, o] * np.cos(n * phi)
            x[:, 1] += A[:, o + 1] * np.cos(n * phi)
        return x

    def positions(self, u: np.ndarray) -> np.ndarray:
        """The section at ``phi = 0`` (see :meth:`section`)."""
        return self.section(u, 0.0)

    # ---- evaluations ---------------------------------------------------------------------------
    def _no_aux(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Empty element-pressure arrays: the reduced linearisation, nothing kept."""
        npr, nphi = self.base.Np.shape[1], self.phis.shape[0]
        return np.zeros((0, nphi, npr)), np.zeros((0, nphi, npr)), np.zeros((0, nphi, npr, 0))

    def _evaluate(self, u: np.ndarray, p: float, want: int, aux_arrays=None):
        """Energy, residual, cavity volume and (``want >= 2``) the tangent: the elements' tangent is
        scattered into a reused band buffer as it is formed
        (:func:`snapjump_kernels.mh_element.mh_assemble_band`), the cavity's added after.
        ``aux_arrays``: ``(p_geo, pb_out, H_out)`` of the mixed linearisation (default: none)."""
        check_time()  # the design's CPU-time limit (snapjump_cli.fe.limits)
        t0 = time.perf_counter()
        M = self.base
        A = np.ascontiguousarray(self.total_amplitudes(u))
        ab = None
        if want >= 2:  # the elements' tangent scattered into a band as it is formed, the cavity's after
            ab = self.band_buffer()
            out = self._band_pass(A, p, ab, self.edofs, self.ecoef, self.band_ext, self._sel_all, self.gdofs,
                                  self.gcoef, aux_arrays)
            if out is None:
                return None
            E, re, Vf, ge = out
        else:
            E, ok, re, _ = mh_elements(A, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np,
                                        M.Minv, self.hn, self.phis, self.wphi, max(want, 0), self.Fi, self.Jimp,
                                        self.Minvp)
            if not ok:
                return None
            Vf, ge, _ = mh_cavity(M.X, A, M.edges, self.hn, self.phis, self.wphi, want)
        R = np.zeros(self.n)
        g = np.zeros(self.n)
        data = None
        if want >= 1:
            scatter_vector(re, self.edofs, self.ecoef, 1.0, R)
            scatter_vector(ge, self.gdofs, self.gcoef, 1.0, g)
            R -= p * g
        if want >= 2:
            data = ab.ravel()
            self.n_assemblies += 1
            self.t_assembly += time.perf_counter() - t0
        else:
            self.n_residuals += 1
        return E, R, g, Vf + self.V_offset, data

    def _band_pass(self, A: np.ndarray, p: float, ab: np.ndarray, edofs, ecoef, ext, sel, gdofs, gcoef,
                   aux_arrays=None):
        """The tangent of the harmonics ``sel`` at the nodal amplitudes ``A`` scattered into the band
        ``ab`` by the maps ``edofs, ecoef`` (elements) and ``gdofs, gcoef`` (the cavity's load
        stiffness, at pressure ``p``), envelope ``ext``: ``(E, re, V, ge)`` (the energy, element
        residuals, cavity volume without the offset and its element gradients), ``None`` outside
        the material domain."""
        M = self.base
        p_geo, pb_out, H_out = aux_arrays if aux_arrays is not None else self._no_aux()
        E, ok, re = mh_assemble_band(A, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np,
                                     M.Minv, self.hn, self.phis, self.wphi, self.Fi, self.Jimp, self.Minvp,
                                     edofs, ecoef, ext, ab, p_geo, pb_out, H_out, sel)
        if not ok:
            return None
        Vf, ge, He = mh_cavity(M.X, A, M.edges, self.hn, self.phis, self.wphi, 2)
        scatter_band(He, gdofs, gcoef, -float(p), ab)
        return E, re, Vf, ge

    def energy(self, u: np.ndarray) -> float:
        """Strain energy (scaled); ``nan`` outside the material domain."""
        out = self._evaluate(u, 0.0, 0)
        return out[0] if out is not None else float("nan")

    def energy_volume(self, u: np.ndarray) -> tuple[float, float] | None:
        """Strain energy and cavity volume (scaled, with the offset); ``None`` outside the domain."""
        out = self._evaluate(u, 0.0, 0)
        return (out[0], out[3]) if out is not None else None

    def volume(self, u: np.ndarray) -> float:
        """Cavity volume (scaled, with the offset)."""
        M = self.base
        V, _, _ = mh_cavity(M.X, np.ascontiguousarray(self.total_amplitudes(u)), M.edges, self.hn, self.phis, self.wphi, 0)
        return V + self.V_offset

    def residual(self, u: np.ndarray, p: float) -> np.ndarray | None:
        """``f_int(u) - p dV/du``; ``None`` outside the material domain."""
        out = self._evaluate(u, p, 1)
        return out[1] if out is not None else None

    def linearize(self, u: np.ndarray, p: float, stiffness: bool = True, aux: np.ndarray | None = None
                  ) -> Linearization | None:
        """Residual and (``stiffness``) the band tangent in one pass; ``None`` outside the domain.

        ``aux`` (ne, nphi, np): element pressures at every phi point for the tangent's geometric term
        (the mixed linearisation, :func:`snapjump_kernels.mh_element.mh_assemble_band`; a perfect
        body only). With the stiffness and a perfect body the result also carries the condensed
        element pressures at ``u`` (``.aux``) and ``.aux_dir``, as
        :meth:`snapjump_cli.fe.axisym.model.Model.linearize`'s does."""
        arrays = None
        mixed = stiffness and self.Fi.shape[0] == 0
        if mixed:
            ne, npr, nphi = self.base.conn.shape[0], self.base.Np.shape[1], self.phis.shape[0]
            p_geo = np.ascontiguousarray(aux, dtype=float) if aux is not None else np.zeros((0, nphi, npr))
            # (the element pass writes every entry of both outputs: not zeroed)
            arrays = (p_geo, np.empty((ne, nphi, npr)), np.empty((ne, nphi, npr, self.edofs.shape[1])))
        elif aux is not None:
            raise ValueError("the mixed linearisation needs a perfect body and the stiffness")
        out = self._evaluate(u, p, 2 if stiffness else 1, arrays)
        if out is None:
            return None
        E, R, g, V, data = out
        if not mixed:
            return Linearization(self, u, p, R, g, data, V, E)
        return _MixedLinearization(self, u, p, R, g, data, V, E, aux=arrays[1], H=arrays[2])

    def measures(self, u: np.ndarray, p: float, lin: Linearization | None = None):
        """Path measures ``(V, p, w)`` and their derivatives (as :meth:`snapjump_cli.fe.axisym.model.Model.measures`)."""
        dz = np.zeros((3, self.n))
        if lin is not None:
            V = lin.V
            dz[0] = lin.g
        else:
            M = self.base
            V, ge, _ = mh_cavity(M.X, np.ascontiguousarray(self.total_amplitudes(u)), M.edges, self.hn, self.phis,
                                 self.wphi, 1)
            V += self.V_offset
            scatter_vector(ge, self.gdofs, self.gcoef, 1.0, dz[0])
        dz[2, self.pole_dof] = 1.0
        return np.array([V, p, u[self.pole_dof]]), dz, np.array([0.0, 1.0, 0.0])

    def _factor(self, data, b, c_u, c_p, max_negative: int = -1) -> BorderedSolver | None:
        """The bordered band factorisation (as :func:`snapjump_cli.fe.axisym.model.factor_bordered`, whose
        factors it returns bit for bit), into a reused band buffer
        (:func:`snapjump_kernels.banded.bordered_factor_upto`); ``None`` where it is singular or,
        with ``max_negative >= 0``, as soon as it has more negative pivots than that (the rest of the
        band is not factorised; counted as a factorisation all the same, and in ``n_given_up``)."""
        t0 = time.perf_counter()
        n = self.n
        try:
            K = data.reshape(n, self.kl + 1)
            fac = self.band_buffer()
            ok, nneg, Kib, schur = bordered_factor_upto(K, self.band_ext, np.ascontiguousarray(b, dtype=float),
                                                        np.ascontiguousarray(c_u, dtype=float), float(c_p), fac,
                                                        int(max_negative))
            if not ok and 0 <= max_negative < nneg:  # given up there: counted, as a whole one was
                self.n_factorizations += 1
                self.n_given_up += 1
                return None
            if not ok or not np.isfinite(schur) or schur == 0.0:
                return None
            s = BorderedSolver(fac, K, b, c_u, float(c_p), n, nneg, self.band_ext, Kib, schur)
        finally:
            self.t_factor += time.perf_counter() - t0
        self.n_factorizations += 1
        return s

    def block_band(self, u: np.ndarray, p: float, harmonics) -> tuple[np.ndarray, HarmonicBlock] | None:
        """The diagonal block of the tangent at ``(u, p)`` of the harmonics ``harmonics`` (a
        :class:`~snapjump_cli.fe.branch.block.HarmonicBlock`, made once per set and kept), as its
        lower band ``(block.n, block.kl + 1)``: only that block's rows are formed. It is the block
        of :meth:`linearize`'s tangent (the condensed element pressures), entry for entry; where
        ``u`` couples the harmonics to the others it is not the whole story. ``None`` outside the
        material domain. Counted in ``n_block_assemblies``."""
        key = tuple(sorted(int(n) for n in harmonics))
        block = self._blocks.get(key)
        if block is None:
            block = self._blocks[key] = harmonic_block(self, key)
        check_time()
        A = np.ascontiguousarray(self.total_amplitudes(u))
        ab = np.zeros((block.n, block.kl + 1))
        if self._band_pass(A, p, ab, block.edofs, block.ecoef, block.ext, block.sel, block.gdofs, block.gcoef) is None:
            return None
        self.n_block_assemblies += 1
        return ab, block

    def stiffness_matrix(self, u: np.ndarray, p: float):
        """The tangent alone (scipy CSR), for tests and eigenvalues."""
        return self.linearize(u, p).stiffness()
