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

from snapjump_kernels.banded import dot_any_order
from snapjump_kernels.cavity import cavity_assemble
from snapjump_kernels.gent import gent_iso


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


@njit(cache=True, inline="always")
def _deformation(u, conn_e, dNdX_eq, N_q, R_q, f):
    f[0] = 1.0
    f[1] = 0.0
    f[2] = 0.0
    f[3] = 1.0
    ur = 0.0
    for a in range(conn_e.shape[0]):
        n = conn_e[a]
        f[0] += u[n, 0] * dNdX_eq[a, 0]
        f[1] += u[n, 0] * dNdX_eq[a, 1]
        f[2] += u[n, 1] * dNdX_eq[a, 0]
        f[3] += u[n, 1] * dNdX_eq[a, 1]
        ur += u[n, 0] * N_q[a]
    f[4] = 1.0 + ur / R_q


@njit(cache=True, inline="always")
def _bt_vec(dNdX_eq, N_q, R_q, v, out):
    """out += B^T v for the 5-component vector ``v`` (B maps element dofs to f)."""
    for a in range(dNdX_eq.shape[0]):
        out[2 * a] += dNdX_eq[a, 0] * v[0] + dNdX_eq[a, 1] * v[1] + N_q[a] / R_q * v[4]
        out[2 * a + 1] += dNdX_eq[a, 0] * v[2] + dNdX_eq[a, 1] * v[3]


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
        ``ok`` is False if any quadrature point left the Gent domain (a failed iterate);
        ``max_dilatation`` is the largest ``|theta - 1|`` of the projected (constrained) dilatation.
    """
    ne, nen = conn.shape
    nq = Wq.shape[1]
    npr = Np.shape[1]
    nd = 2 * nen
    f, dpsi, d2psi, dJq, d2Jq, fe, Ke, G, H, g, pb, Bt, DBt, D, sv, bt = _work_arrays(nq, npr, nd)
    energy = 0.0
    maxdev = 0.0
    use_geo = p_geo.shape[0] == ne
    keep_pb = pb_out.shape[0] == ne
    keep_H = H_out.shape[0] == ne
    for e in range(ne):
        m_ = mat[e]
        mu_e = mu[m_]
        jm_e = jm[m_]
        ka = kappa[m_]
        g[:] = 0.0
        # pass 1: kinematics, isochoric energy and its derivatives, projected dilatation g
        for q in range(nq):
            _deformation(u, conn[e], dNdX[e, q], N_ref[q], Rq[e, q], f)
            ok, psi, J = gent_iso(f, mu_e, jm_e, want, dpsi[q], d2psi[q], dJq[q], d2Jq[q])
            if not ok:
                return energy, False, maxdev
            W = Wq[e, q]
            energy += W * psi
            for k in range(npr):
                g[k] += W * Np[q, k] * (J - 1.0)
        # volumetric part: pbar = kappa M^-1 g, energy kappa/2 g^T M^-1 g
        for k in range(npr):
            s = 0.0
            for m in range(npr):
                s += Minv[e, k, m] * g[m]
            pb[k] = ka * s
            energy += 0.5 * g[k] * pb[k]
            if keep_pb:
                pb_out[e, k] = pb[k]
        # projected dilatation theta - 1 = p / kappa at the quadrature points (what is constrained)
        for q in range(nq):
            th = 0.0
            for k in range(npr):
                th += Np[q, k] * pb[k]
            dev = abs(th) / ka
            if dev > maxdev:
                maxdev = dev
        if want == 0:
            continue
        # pass 2: stress and tangent with the element pressure at each point
        fe[:] = 0.0
        if want >= 2:
            G[:, :] = 0.0
        for q in range(nq):
            W = Wq[e, q]
            pq = 0.0
            pg = 0.0
            for k in range(npr):
                pq += Np[q, k] * pb[k]
                pg += Np[q, k] * (p_geo[e, k] if use_geo else pb[k])
            for k in range(5):
                sv[k] = W * (dpsi[q, k] + pq * dJq[q, k])
            _bt_vec(dNdX[e, q], N_ref[q], Rq[e, q], sv, fe)
            if want >= 2:
                bt[:] = 0.0
                _bt_vec(dNdX[e, q], N_ref[q], Rq[e, q], dJq[q], bt)
                for k in range(npr):
                    s = W * Np[q, k]
                    for j in range(nd):
                        G[k, j] += s * bt[j]
                for k in range(5):
                    for m in range(5):
                        D[k, m] = W * (d2psi[q, k, m] + pg * d2Jq[q, k, m])
                _stack_b_db(dNdX[e, q], N_ref[q], Rq[e, q], D, 5 * q, Bt, DBt)
        if want >= 2:
            _volumetric_columns(Minv[e], ka, G, H, 5 * nq, Bt, DBt)
            for i in range(nd):  # Ke = sum over the points of B^T D B, + kappa G^T M^-1 G (lower)
                bi = Bt[i]
                for j in range(i + 1):
                    Ke[i, j] = dot_any_order(bi, DBt[j])
            if keep_H:
                H_out[e] = H
        _scatter(edofs[e], epos[e], fe, Ke, want, f_out, data_out)
    return energy, True, maxdev


@njit(cache=True, inline="always")
def _work_arrays(nq, npr, nd):
    """Scratch arrays of :func:`assemble` for elements with ``nq`` quadrature points, ``npr``
    pressure modes and ``nd`` dofs: ``f, dpsi, d2psi, dJq, d2Jq, fe, Ke, G, H, g, pb, Bt, DBt, D, sv, bt``
    (``Bt``, ``DBt``: see :func:`_stack_b_db`)."""
    f = np.empty(5)
    dpsi = np.zeros((nq, 5))
    d2psi = np.zeros((nq, 5, 5))
    dJq = np.empty((nq, 5))
    d2Jq = np.empty((nq, 5, 5))
    fe = np.empty(nd)
    Ke = np.empty((nd, nd))
    G = np.empty((npr, nd))
    H = np.empty((npr, nd))
    g = np.empty(npr)
    pb = np.empty(npr)
    Bt = np.zeros((nd, 5 * nq + npr))  # its structural zeros are never overwritten (_stack_b_db)
    DBt = np.empty((nd, 5 * nq + npr))
    D = np.empty((5, 5))
    sv = np.empty(5)
    bt = np.empty(nd)
    return f, dpsi, d2psi, dJq, d2Jq, fe, Ke, G, H, g, pb, Bt, DBt, D, sv, bt


@njit(cache=True, inline="always")
def _volumetric_columns(Minv_e, ka, G, H, c0, Bt, DBt):
    """``H = kappa M^-1 G`` (the element pressures' derivative), and ``G``, ``H`` as the columns
    ``c0 ..`` of ``Bt`` and ``DBt``: their row products then add ``kappa G^T M^-1 G = G^T H``."""
    npr, nd = G.shape
    for k in range(npr):
        for j in range(nd):
            s = 0.0
            for m in range(npr):
                s += Minv_e[k, m] * G[m, j]
            H[k, j] = ka * s
    for k in range(npr):
        for i in range(nd):
            Bt[i, c0 + k] = G[k, i]
            DBt[i, c0 + k] = H[k, i]


@njit(cache=True, inline="always")
def _stack_b_db(dNdX_eq, N_q, R_q, D, c, Bt, DBt):
    """One quadrature point's columns ``c .. c + 4`` of ``Bt = B^T`` and ``DBt = (D B)^T``
    (B sparse: rows 0, 1, 4 for a u_r dof, rows 2, 3 for a u_z dof). With every point's columns
    side by side, the element stiffness is the row products ``Ke[i, j] = Bt[i] . DBt[j]``: dot
    products ~50 long, which vectorise, where accumulating ``B^T D B`` point by point ran
    triangular loops 1-18 long (the element pass 15-20 % faster; the sums are reordered, so the
    stiffness changes by round-off). Only ``B``'s non-zeros are written: its zeros in ``Bt`` are
    those :func:`_work_arrays` allocated."""
    nen = dNdX_eq.shape[0]
    for a in range(nen):
        bx = dNdX_eq[a, 0]
        by = dNdX_eq[a, 1]
        bn = N_q[a] / R_q
        r = Bt[2 * a]  # B's zeros in these columns stay as _work_arrays set them
        z = Bt[2 * a + 1]
        r[c] = bx
        r[c + 1] = by
        r[c + 4] = bn
        z[c + 2] = bx
        z[c + 3] = by
        dr = DBt[2 * a]
        dz = DBt[2 * a + 1]
        for k in range(5):
            dr[c + k] = D[k, 0] * bx + D[k, 1] * by + D[k, 4] * bn
            dz[c + k] = D[k, 2] * bx + D[k, 3] * by


@njit(cache=True, inline="always")
def _scatter(edofs_e, epos_e, fe, Ke, want, f_out, data_out):
    """Add an element's force ``fe`` (and for ``want >= 2`` its stiffness; ``Ke`` holds the lower
    triangle of a symmetric matrix) into ``f_out`` and ``data_out`` (``edofs_e``, ``epos_e``: the
    element's rows of ``edofs`` and ``epos``)."""
    for i in range(fe.shape[0]):
        di = edofs_e[i]
        if di < 0:
            continue
        f_out[di] += fe[i]
        if want >= 2:
            for j in range(i + 1):
                v = Ke[i, j]
                pij = epos_e[i, j]
                if pij >= 0:
                    data_out[pij] += v
                if j != i:
                    pji = epos_e[j, i]
                    if pji >= 0:
                        data_out[pji] += v


@njit(cache=True)
def quadrature_jacobians(u, conn, dNdX, N_ref, Rq):
    """``J`` at every quadrature point, shape (ne, nq) (a diagnostic: volume preservation)."""
    ne = conn.shape[0]
    nq = Rq.shape[1]
    out = np.empty((ne, nq))
    f = np.empty(5)
    for e in range(ne):
        for q in range(nq):
            _deformation(u, conn[e], dNdX[e, q], N_ref[q], Rq[e, q], f)
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
    return cavity_assemble(X + U, edges, edge_dofs, edge_pos, 0.0, 1, g_out, np.zeros(1))
