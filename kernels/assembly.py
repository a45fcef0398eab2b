"""Element loops for the axisymmetric mixed Gent solid: energy, residual, tangent into CSR.

Formulation (documented here once): a three-field Hu-Washizu element with discontinuous
pressure and dilatation fields in the span of the element's pressure basis ``Np`` (Q4: P0,
i.e. mean dilatation; Q9: P1 = [1, xi, eta]). Eliminating both fields at element level with the
volumetric energy ``kappa/2 (theta - 1)^2`` gives the reduced element energy::

    Pi_e(u) = sum_q W_q psi_iso(f_q)  +  kappa/2 g^T M^-1 g,
    g_k = sum_q W_q Np_qk (J_q - 1),   M_kl = sum_q W_q Np_qk Np_ql,

whose gradient and Hessian are exact (the element pressure is ``p = kappa M^-1 g`` evaluated at
the quadrature points).

Mixed linearisation (optional, ``p_geo``): the tangent may take the element pressure from an
outside estimate instead of ``kappa M^-1 g(u)`` in its geometric term ``p d2J``. This is the
Newton matrix of the three-field problem with the pressure as an unknown (its right-hand side,
with the dilatation and pressure eliminated, is the same residual). At a predicted state the
pressure ``kappa M^-1 g(u)`` carries ``kappa`` times the predictor's volume error (hundreds of
times the true pressure), and a tangent built on it costs a Newton iteration; the pressure carried
along the path does not (docs/numerics.md, "Newton on the mixed element"). ``kappa = bulk_ratio * mu`` makes the rubber incompressible to
``|J - 1| ~ p / kappa``; the constraint is imposed on the projected dilatation only, so the
element does not lock. ``W_q = w_q det(J0) 2 pi R_q`` carries the axisymmetric weighting: it is
formed in :func:`reference_geometry` and nowhere else.

All arrays in, all arrays out; free-dof indices of -1 denote constrained (zero) dofs.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.cavity import cavity_assemble
from snapjump_kernels.element_lanes import assemble_lanes
from snapjump_kernels.element_plain import assemble_plain
from snapjump_kernels.kinematics import deformation


@njit(cache=True)
def reference_geometry(X, conn, dN_ref, N_ref, wq):
    """Reference-configuration quadrature data of every element.

    Returns
    -------
    dNdX : (ne, nq, nen, 2) shape-function gradients w.r.t. (R, Z)
    Rq : (ne, nq) reference radius at the quadrature points
    Wq : (ne, nq) integration weights ``w_q det(J0) 2 pi R_q`` (volume of revolution)
    min_det : smallest Jacobian determinant found (<= 0 means an inverted element)
    """
    ne, nen = conn.shape
    nq = wq.shape[0]
    dNdX = np.empty((ne, nq, nen, 2))
    Rq = np.empty((ne, nq))
    Wq = np.empty((ne, nq))
    min_det = np.inf
    for e in range(ne):
        for q in range(nq):
            j00 = 0.0
            j01 = 0.0
            j10 = 0.0
            j11 = 0.0
            R = 0.0
            for a in range(nen):
                xa = X[conn[e, a], 0]
                ya = X[conn[e, a], 1]
                j00 += dN_ref[q, a, 0] * xa
                j01 += dN_ref[q, a, 1] * xa
                j10 += dN_ref[q, a, 0] * ya
                j11 += dN_ref[q, a, 1] * ya
                R += N_ref[q, a] * xa
            det = j00 * j11 - j01 * j10
            if det < min_det:
                min_det = det
            # inverse of [[dR/dxi, dR/deta], [dZ/dxi, dZ/deta]]
            i00 = j11 / det
            i01 = -j01 / det
            i10 = -j10 / det
            i11 = j00 / det
            for a in range(nen):
                dNdX[e, q, a, 0] = dN_ref[q, a, 0] * i00 + dN_ref[q, a, 1] * i10
                dNdX[e, q, a, 1] = dN_ref[q, a, 0] * i01 + dN_ref[q, a, 1] * i11
            Rq[e, q] = R
            Wq[e, q] = wq[q] * det * 2.0 * np.pi * R
    return dNdX, Rq, Wq, min_det


@njit(cache=True)
def pressure_mass_inverse(Wq, Np):
    """``M^-1`` per element, ``M_kl = sum_q W_q Np_qk Np_ql``; shape (ne, np, np)."""
    ne, nq = Wq.shape
    npr = Np.shape[1]
    Minv = np.empty((ne, npr, npr))
    for e in range(ne):
        M = np.zeros((npr, npr))
        for q in range(nq):
            for k in range(npr):
                for m in range(npr):
                    M[k, m] += Wq[e, q] * Np[q, k] * Np[q, m]
        Minv[e] = np.linalg.inv(M)
    return Minv


@njit(cache=True)
def assemble(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, f_out, data_out,
             p_geo, pb_out, H_out):
    """Strain energy, and for ``want >= 1`` the internal force, for ``want >= 2`` the tangent.

    Parameters
    ----------
    u : (n, 2) nodal displacements
    conn : (ne, nen) connectivity; mat : (ne,) material index into ``mu``, ``jm``, ``kappa``
    dNdX, Rq, Wq : from :func:`reference_geometry`; N_ref (nq, nen); Np (nq, np); Minv (ne, np, np)
    edofs : (ne, 2 nen) free-dof index of each element dof, -1 if constrained
    epos : (ne, 2 nen, 2 nen) position of each element matrix entry in ``data_out``, -1 if not
        stored (constrained, or the upper triangle of a symmetric band storage)
    want : 0 energy, 1 + residual, 2 + tangent
    f_out, data_out : accumulated into (zero them before the call)
    p_geo : (ne, np) element pressures for the tangent's geometric term, or shape (0, np): the
        element's own ``kappa M^-1 g(u)`` (the exact Hessian of the reduced energy)
    pb_out : (ne, np) filled with ``kappa M^-1 g(u)`` per element, or shape (0, np): not wanted
    H_out : (ne, np, 2 nen) filled (``want >= 2``) with ``kappa M^-1 G``, the derivative of the
        element pressure with respect to the element dofs, or shape (0, np, 2 nen): not wanted

    Returns
    -------
    (energy, ok, max_dilatation)
        ``ok`` is False if any quadrature point left the Gent domain (a failed iterate; the other
        outputs are then incomplete); ``max_dilatation`` is the largest ``|theta - 1|`` of the
        projected (constrained) dilatation.

    Notes
    -----
    The Q9 element with 3x3 points and the P1 pressure (the grid's) goes through
    :func:`assemble_lanes`, compiled for these sizes as constants; every other element table
    (Q4/P0) through the plain element-by-element loop :func:`assemble_plain`, which compiles in a
    fraction of the time (a lanes version for Q4 added ~20 s to the cold compile for a mesh the
    sweeps do not use). Both compute the energy, force, ``pb_out`` and ``H_out`` in the same order
    (the same floating-point result, bit for bit); the stiffness's sums are ordered differently
    (it differs by round-off).
    """
    nen = conn.shape[1]
    nq = Wq.shape[1]
    npr = Np.shape[1]
    if nen == 9 and nq == 9 and npr == 3:
        return assemble_lanes(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want,
                               f_out, data_out, p_geo, pb_out, H_out, 9, 9, 3)
    return assemble_plain(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, f_out,
                           data_out, p_geo, pb_out, H_out)


@njit(cache=True)
def quadrature_jacobians(u, conn, dNdX, N_ref, Rq):
    """``J`` at every quadrature point, shape (ne, nq) (a diagnostic: volume preservation)."""
    ne = conn.shape[0]
    nq = Rq.shape[1]
    out = np.empty((ne, nq))
    f = np.empty(5)
    for e in range(ne):
        for q in range(nq):
            deformation(u, conn[e], dNdX[e, q], N_ref[q], Rq[e, q], f)
            out[e, q] = (f[0] * f[3] - f[1] * f[2]) * f[4]
    return out


@njit(cache=True, inline="always")
def nodal_displacements(u, dofmap):
    """The (n_nodes, 2) displacements of the free-dof vector ``u`` (``dofmap[node, component]``:
    free dof or -1 for a constrained, zero one)."""
    nn = dofmap.shape[0]
    U = np.zeros((nn, 2))
    for a in range(nn):
        for c in range(2):
            k = dofmap[a, c]
            if k >= 0:
                U[a, c] = u[k]
    return U


@njit(cache=True)
def evaluate(u, dofmap, X, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos,
             edges, edge_dofs, edge_pos, p, want, R_out, g_out, data_out, p_geo, pb_out, H_out):
    """One evaluation of the pressurised solid at the free-dof displacement ``u`` (one call).

    Scatters ``u`` to the nodes (``dofmap[node, component]``: free dof or -1), assembles the
    element energy, force and (``want >= 2``) stiffness (:func:`assemble`), then the cavity volume,
    its gradient ``g = dV/du`` and (``want >= 2``) the load stiffness ``-p d2V/du2``
    (:func:`snapjump_kernels.cavity.cavity_assemble`). Fills ``R_out = f_int - p g``, ``g_out``
    and ``data_out`` (zeroed by the caller); ``p_geo``, ``pb_out``, ``H_out`` as in :func:`assemble`.

    Returns
    -------
    (energy, ok, V) : the strain energy, False outside the material domain, the cavity volume
        (without any offset)
    """
    U = nodal_displacements(u, dofmap)
    E, ok, _ = assemble(U, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, R_out,
                        data_out, p_geo, pb_out, H_out)
    V = cavity_assemble(X + U, edges, edge_dofs, edge_pos, -p, max(want, 1), g_out, data_out)
    for i in range(R_out.shape[0]):
        R_out[i] -= p * g_out[i]
    return E, ok, V


@njit(cache=True)
def cavity_state(u, dofmap, X, edges, edge_dofs, edge_pos, g_out):
    """Cavity volume (without any offset) at the free-dof displacement ``u``; fills ``g_out`` with
    ``dV/du`` (zeroed here). The cavity part of :func:`evaluate` alone (no element pass)."""
    U = nodal_displacements(u, dofmap)
    g_out[:] = 0.0
    return cavity_assemble(X + U, edges, edge_dofs, edge_pos, 0.0, np.int64(1), g_out, np.zeros(1))
