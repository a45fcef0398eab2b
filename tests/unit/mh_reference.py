"""Test oracle: the element pass of :func:`snapjump_kernels.mh_element.mh_elements` as it was
before the tangent was restructured (2026-11-27): one element at a time, the ``B_k^T D_kl B_l``
blocks node pair by node pair through the sparse B. The straightforward reference that
``tests/unit/test_multiharmonic_kernel.py`` compares the fast kernel with (bit for bit). Not part
of the product (JIT-compiled, not cached: its numba cache would not see a change of the kernels
it calls).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.mh_basis import dof_offset as _offset
from snapjump_kernels.mh_basis import harmonic_ndof as _ndof_k
from snapjump_kernels.mh_basis import node_b as _node_b
from snapjump_kernels.mh_material import gent3, imperfect_point


@njit(inline="always")
def _db_cols(D: np.ndarray, bx: float, by: float, bn: float, n: float, out: np.ndarray) -> None:
    """``out (9, 3) = D (9x9) @ B`` of one node and harmonic ``n`` (the sparse B of :func:`snapjump_kernels.mh_basis.node_b`)."""
    nbn = n * bn
    for c in range(9):
        out[c, 0] = D[c, 0] * bx + D[c, 1] * by + D[c, 4] * bn - D[c, 5] * nbn
        out[c, 1] = D[c, 2] * bx + D[c, 3] * by - D[c, 8] * nbn
        out[c, 2] = D[c, 4] * nbn - D[c, 5] * bn + D[c, 6] * bx + D[c, 7] * by


@njit(inline="always")
def _bt_db(bx: float, by: float, bn: float, n: float, DB: np.ndarray, nk: int, nl: int, K: np.ndarray,
           oa: int, ob: int) -> None:
    """``K[oa:oa+nk, ob:ob+nl] += B^T DB`` for one node's sparse B (harmonic ``n``)."""
    nbn = n * bn
    for j in range(nl):
        K[oa, ob + j] += bx * DB[0, j] + by * DB[1, j] + bn * DB[4, j] - nbn * DB[5, j]
        K[oa + 1, ob + j] += bx * DB[2, j] + by * DB[3, j] - nbn * DB[8, j]
        if nk > 2:
            K[oa + 2, ob + j] += nbn * DB[4, j] - bn * DB[5, j] + bx * DB[6, j] + by * DB[7, j]


@njit
def mh_elements_reference(A: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
                          kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
                          Np: np.ndarray, Minv: np.ndarray, hn: np.ndarray, phis: np.ndarray, wphi: np.ndarray,
                          want: int, Fi: np.ndarray, Jimp: np.ndarray, Minvp: np.ndarray):
    """Energy, element residuals and element tangents of the multi-harmonic solid.

    Parameters
    ----------
    A : (nn, nc) nodal amplitudes (scaled displacements), layout of the module docstring
    conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv : as in
        :func:`snapjump_kernels.assembly.assemble`
    hn : (K,) harmonic numbers, ``hn[0] = 0``
    phis, wphi : the phi rule (:func:`snapjump_kernels.mh_basis.phi_rule`)
    want : 0 energy, 1 and residuals, 2 and tangents
    Fi, Jimp : an initial geometric imperfection (empty arrays: none). ``Fi (ne, nq, nphi, 3, 3)``
        is the inverse of the imperfection's deformation gradient ``F0`` (perfect reference ->
        stress-free imperfect body) at every point and ``Jimp = det F0``. ``A`` is then the total
        displacement from the perfect reference (imperfection included); the elastic gradient is
        ``F F0^-1`` and every volume integral carries ``Jimp`` (:func:`imperfect_point`)
    Minvp : ``(ne, nphi, np, np)`` with an imperfection: the inverse pressure mass matrices of the
        imperfect body at every phi point (``sum_q W_q Jimp Np Np^T``), used instead of ``Minv``

    Returns
    -------
    (E, ok, re, Ke) : the energy, False if some point left the Gent domain, the element residuals
        (ne, nen nc) and tangents (ne, nen nc, nen nc; empty unless ``want >= 2``)
    """
    ne, nen = conn.shape
    nq = Wq.shape[1]
    npr = Np.shape[1]
    K = hn.shape[0]
    nc = 2 + 3 * (K - 1)
    nd = nen * nc
    nphi = phis.shape[0]
    re = np.zeros((ne, nd))
    Ke = np.zeros((ne, nd, nd)) if want >= 2 else np.zeros((0, nd, nd))
    # trig table t[j, k, c]: cos n_k phi_j for c < 5, sin for c >= 5
    t = np.empty((nphi, K, 9))
    for j in range(nphi):
        for k in range(K):
            cs = np.cos(hn[k] * phis[j])
            sn = np.sin(hn[k] * phis[j])
            for c in range(9):
                t[j, k, c] = cs if c < 5 else sn
    E = 0.0
    Gk = np.empty((K, 9))
    v = np.empty(9)
    dpsi = np.zeros(9)
    d2psi = np.zeros((9, 9))
    dJ = np.zeros(9)
    d2J = np.zeros((9, 9))
    # per element and phi point
    Jq = np.empty((nq, nphi))
    Sq = np.empty((nq, nphi, 9))  # W (dpsi) at each point (the pressure part added after)
    dJq = np.empty((nq, nphi, 9))
    Dq = np.empty((nq, nphi, 9, 9)) if want >= 2 else np.empty((0, 0, 9, 9))
    d2Jq = np.empty((nq, nphi, 9, 9)) if want >= 2 else np.empty((0, 0, 9, 9))
    g = np.empty((nphi, npr))
    pel = np.empty((nphi, npr))
    Bn = np.empty((nen, K, 9, 3))
    S = np.empty((K, 9))
    Dt = np.empty((9, 9))
    DB = np.empty((nen, 9, 3))
    Gv = np.empty((npr, nd))
    Hv = np.empty((npr, nd))
    bq = np.empty((nen, 3))
    hk = np.empty(nd, np.int64)  # harmonic index of each element dof
    imperfect = Fi.shape[0] > 0
    ve = np.empty(9)
    dpe = np.zeros(9)
    d2pe = np.zeros((9, 9))
    dJe = np.zeros(9)
    d2Je = np.zeros((9, 9))
    for a in range(nen):
        for k in range(K):
            for dof in range(_ndof_k(k)):
                hk[a * nc + _offset(k) + dof] = k
    for e in range(ne):
        m_ = mat[e]
        mu_e = mu[m_]
        jm_e = jm[m_]
        ka = kappa[m_]
        g[:, :] = 0.0
        for q in range(nq):
            R = Rq[e, q]
            # harmonic gradients G_k = sum_a B_{k,a} q_{a,k}
            Gk[:, :] = 0.0
            for a in range(nen):
                node = conn[e, a]
                bx = dNdX[e, q, a, 0]
                by = dNdX[e, q, a, 1]
                bn = N_ref[q, a] / R
                for k in range(K):
                    n = float(hn[k])
                    o = _offset(k)
                    ua = A[node, o]
                    ub = A[node, o + 1]
                    uc = A[node, o + 2] if k > 0 else 0.0
                    Gk[k, 0] += bx * ua
                    Gk[k, 1] += by * ua
                    Gk[k, 2] += bx * ub
                    Gk[k, 3] += by * ub
                    Gk[k, 4] += bn * (ua + n * uc)
                    Gk[k, 5] += -bn * (n * ua + uc)
                    Gk[k, 6] += bx * uc
                    Gk[k, 7] += by * uc
                    Gk[k, 8] += -n * bn * ub
            W = Wq[e, q]
            for j in range(nphi):
                for c in range(9):
                    s = 0.0
                    for k in range(K):
                        s += t[j, k, c] * Gk[k, c]
                    v[c] = s
                v[0] += 1.0
                v[3] += 1.0
                v[4] += 1.0
                wa = want if want < 2 else 2
                if imperfect:
                    ok, psi, J = imperfect_point(v, Fi[e, q, j], Jimp[e, q, j], mu_e, jm_e, wa, dpsi, d2psi, dJ,
                                                 d2J, ve, dpe, d2pe, dJe, d2Je)
                else:
                    ok, psi, J = gent3(v, mu_e, jm_e, wa, dpsi, d2psi, dJ, d2J)
                if not ok:
                    return E, False, re, Ke
                E += wphi[j] * W * psi
                Jq[q, j] = J
                for c in range(9):
                    Sq[q, j, c] = W * dpsi[c]
                    dJq[q, j, c] = dJ[c]
                if want >= 2:
                    for c in range(9):
                        for d in range(9):
                            Dq[q, j, c, d] = W * d2psi[c, d]
                            d2Jq[q, j, c, d] = d2J[c, d]
                jw = Jimp[e, q, j] if imperfect else 1.0
                for k2 in range(npr):
                    g[j, k2] += W * jw * Np[q, k2] * (J - 1.0)
        # element pressures at every phi point, the volumetric energy
        for j in range(nphi):
            Mi = Minvp[e, j] if imperfect else Minv[e]
            ev = 0.0
            for k2 in range(npr):
                s = 0.0
                for l2 in range(npr):
                    s += Mi[k2, l2] * g[j, l2]
                pel[j, k2] = ka * s
                ev += 0.5 * g[j, k2] * pel[j, k2]
            E += wphi[j] * ev
        if want < 1:
            continue
        for q in range(nq):
            R = Rq[e, q]
            for a in range(nen):
                bx = dNdX[e, q, a, 0]
                by = dNdX[e, q, a, 1]
                bn = N_ref[q, a] / R
                bq[a, 0] = bx
                bq[a, 1] = by
                bq[a, 2] = bn
                for k in range(K):
                    _node_b(bx, by, bn, float(hn[k]), Bn[a, k])
            W = Wq[e, q]
            # residual moments S_k = sum_j w_j t_k (W dpsi + W p dJ)
            S[:, :] = 0.0
            for j in range(nphi):
                pq = 0.0
                for k2 in range(npr):
                    pq += Np[q, k2] * pel[j, k2]
                for c in range(9):
                    sj = wphi[j] * (Sq[q, j, c] + W * pq * dJq[q, j, c])
                    for k in range(K):
                        S[k, c] += t[j, k, c] * sj
            for a in range(nen):
                for k in range(K):
                    o = a * nc + _offset(k)
                    for dof in range(_ndof_k(k)):
                        s = 0.0
                        for c in range(9):
                            s += Bn[a, k, c, dof] * S[k, c]
                        re[e, o + dof] += s
            if want < 2:
                continue
            # tangent: for each pair of harmonics k <= l the phi-moment of D, then B_k^T Dt B_l
            # (the B of a node is sparse: _db_cols / _bt_db), mirrored afterwards
            for j in range(nphi):
                pq = 0.0
                for k2 in range(npr):
                    pq += Np[q, k2] * pel[j, k2]
                pw = W * pq
                for c in range(9):
                    for d in range(9):
                        Dq[q, j, c, d] += pw * d2Jq[q, j, c, d]
            for k in range(K):
                nk = _ndof_k(k)
                fk = float(hn[k])
                for l in range(k, K):
                    fl = float(hn[l])
                    nl = _ndof_k(l)
                    Dt[:, :] = 0.0
                    for j in range(nphi):
                        wj = wphi[j]
                        ck = wj * t[j, k, 0]
                        sk = wj * t[j, k, 5]
                        cl = t[j, l, 0]
                        sl = t[j, l, 5]
                        wcc = ck * cl
                        wcs = ck * sl
                        wsc = sk * cl
                        wss = sk * sl
                        for c in range(5):
                            for d in range(5):
                                Dt[c, d] += wcc * Dq[q, j, c, d]
                            for d in range(5, 9):
                                Dt[c, d] += wcs * Dq[q, j, c, d]
                        for c in range(5, 9):
                            for d in range(5):
                                Dt[c, d] += wsc * Dq[q, j, c, d]
                            for d in range(5, 9):
                                Dt[c, d] += wss * Dq[q, j, c, d]
                    for b in range(nen):
                        _db_cols(Dt, bq[b, 0], bq[b, 1], bq[b, 2], fl, DB[b])
                    for a in range(nen):
                        oa = a * nc + _offset(k)
                        for b in range(nen):
                            ob = b * nc + _offset(l)
                            _bt_db(bq[a, 0], bq[a, 1], bq[a, 2], fk, DB[b], nk, nl, Ke[e], oa, ob)
        if want < 2:
            continue
        # the elastic blocks of harmonics k < l were formed once: their transposes are the (l, k) blocks
        for i in range(nd):
            for jj in range(nd):
                if hk[i] < hk[jj]:
                    Ke[e, jj, i] = Ke[e, i, jj]
        # volumetric constraint stiffness: sum_j w_j kappa G_j^T M^-1 G_j
        for j in range(nphi):
            Gv[:, :] = 0.0
            for q in range(nq):
                R = Rq[e, q]
                W = Wq[e, q]
                for a in range(nen):
                    bx = dNdX[e, q, a, 0]
                    by = dNdX[e, q, a, 1]
                    bn = N_ref[q, a] / R
                    for k in range(K):
                        _node_b(bx, by, bn, float(hn[k]), Bn[a, k])
                        o = a * nc + _offset(k)
                        for dof in range(_ndof_k(k)):
                            s = 0.0
                            for c in range(9):
                                s += dJq[q, j, c] * t[j, k, c] * Bn[a, k, c, dof]
                            for k2 in range(npr):
                                Gv[k2, o + dof] += W * Np[q, k2] * s
            Mi = Minvp[e, j] if imperfect else Minv[e]
            for k2 in range(npr):
                for i in range(nd):
                    s = 0.0
                    for l2 in range(npr):
                        s += Mi[k2, l2] * Gv[l2, i]
                    Hv[k2, i] = wphi[j] * ka * s
            for i in range(nd):
                for jj in range(i, nd):
                    s = 0.0
                    for k2 in range(npr):
                        s += Gv[k2, i] * Hv[k2, jj]
                    Ke[e, i, jj] += s
                    if jj != i:
                        Ke[e, jj, i] += s
    return E, True, re, Ke
