"""The element-by-element pass of :func:`snapjump_kernels.assembly.assemble` for any element table
(the reference of :func:`snapjump_kernels.element_lanes.assemble_lanes`, and the pass of the
elements it is not compiled for); the formulation is in :mod:`snapjump_kernels.assembly`."""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.banded import dot_any_order
from snapjump_kernels.gent import gent_iso
from snapjump_kernels.kinematics import deformation


@njit(cache=True, inline="always")
def _bt_vec(dNdX_eq, N_q, R_q, v, out):
    """out += B^T v for the 5-component vector ``v`` (B maps element dofs to f)."""
    for a in range(dNdX_eq.shape[0]):
        out[2 * a] += dNdX_eq[a, 0] * v[0] + dNdX_eq[a, 1] * v[1] + N_q[a] / R_q * v[4]
        out[2 * a + 1] += dNdX_eq[a, 0] * v[2] + dNdX_eq[a, 1] * v[3]


@njit(cache=True)
def assemble_plain(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, f_out, data_out,
             p_geo, pb_out, H_out):
    """:func:`assemble` element by element, for any element table (the reference of
    :func:`assemble_lanes`, and the pass of the elements it is not compiled for)."""
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
            deformation(u, conn[e], dNdX[e, q], N_ref[q], Rq[e, q], f)
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
        _scatter_element(edofs[e], epos[e], fe, Ke, want, f_out, data_out)
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
def _scatter_element(edofs_e, epos_e, fe, Ke, want, f_out, data_out):
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
