"""The second variation of the multi-harmonic solid in the mirror-antisymmetric directions.

A state of the multi-harmonic model (:mod:`snapjump_kernels.mh_basis`) is mirror-symmetric about
``phi = 0``. The perturbations of the other symmetry class, antisymmetric about ``phi = 0``::

    du_r = sum_k a'_k sin n_k phi,   du_z = sum_k b'_k sin n_k phi,   du_phi = sum_k c'_k cos n_k phi

(for ``n_0 = 0`` only ``c'_0``, the torsion ``du_phi = c'_0``), decouple from the symmetric ones in
the second variation at such a state (the cross terms are odd in phi). Their gradient has the
9 components of :mod:`snapjump_kernels.mh_basis` with the trigonometric factors swapped (``sin n
phi`` on the first five, ``cos n phi`` on the last four) and the B matrix of harmonic ``n`` is
:func:`~snapjump_kernels.mh_basis.node_b` with ``n`` replaced by ``-n`` (``du_r,phi = n a' cos``,
``du_phi,phi = -n c' sin``, ``du_z,phi = n b' cos``).

The matrices below are the second derivatives, in those amplitudes, of the energy and volume of
:func:`snapjump_kernels.mh_element.mh_elements` and :func:`snapjump_kernels.mh_cavity.mh_cavity`
for the same phi rule (the state's gradient, stress, tangent and element pressures as the element
pass forms them): the integrand of the second variation is even in phi (the isotropic law is
invariant under the reflection, which flips the last four components of the state and all of the
perturbation's up to the sign of the first five), so the rule on ``[0, pi]`` (harmonics
``0, 1, ..., N``) is the trapezoidal rule over the whole circle.

Element dof order: node by node, per node ``3 K`` amplitudes ``(a'_k, b'_k, c'_k)`` of every
harmonic ``k`` in turn (``a'_0, b'_0`` included: their rows and columns are zero; the caller fixes
them). JIT-compiled (not in the ahead-of-time build). Arrays in, arrays out.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.cavity import edge_shape
from snapjump_kernels.mh_basis import harmonic_gradients, node_b
from snapjump_kernels.mh_cavity import _GP, _GW, _cavity_point
from snapjump_kernels.mh_material import gent3, imperfect_point


@njit(cache=True)
def mirror_trig(hn: np.ndarray, phis: np.ndarray) -> tuple:
    """The trig tables ``(t, ta)`` ``(nphi, K, 9)``: the state's (``cos n_k phi_j`` on the components
    ``c < 5``, ``sin`` on the others) and the antisymmetric perturbation's (swapped)."""
    nphi = phis.shape[0]
    K = hn.shape[0]
    t = np.empty((nphi, K, 9))
    ta = np.empty((nphi, K, 9))
    for j in range(nphi):
        for k in range(K):
            cs = np.cos(hn[k] * phis[j])
            sn = np.sin(hn[k] * phis[j])
            for c in range(9):
                t[j, k, c] = cs if c < 5 else sn
                ta[j, k, c] = sn if c < 5 else cs
    return t, ta


@njit(cache=True, error_model="numpy")
def mirror_elements(A: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
                    kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
                    Np: np.ndarray, Minv: np.ndarray, hn: np.ndarray, phis: np.ndarray, wphi: np.ndarray,
                    Fi: np.ndarray, Jimp: np.ndarray, Minvp: np.ndarray) -> tuple:
    """Element matrices of the antisymmetric second variation of the mixed Gent solid at the
    mirror-symmetric state ``A``.

    Parameters
    ----------
    A : (nn, nc) the state's total nodal amplitudes, layout of :mod:`snapjump_kernels.mh_basis`
    conn ... Minvp : as in :func:`snapjump_kernels.mh_element.mh_elements`

    Returns
    -------
    (ok, Ke) : False if some point left the Gent domain; ``Ke (ne, 3 K nen, 3 K nen)`` (module
        docstring's dof order): ``sum_j w_j [sum_q B'_q(phi_j)^T W_q (d2psi + p_q d2J) B'_q(phi_j)
        + kappa G'_j^T M^-1 G'_j]``, ``G'_j = sum_q W_q Np_q dJ_q(phi_j)^T B'_q(phi_j)``
    """
    ne, nen = conn.shape
    nq = Wq.shape[1]
    npr = Np.shape[1]
    K = hn.shape[0]
    nda = 3 * K
    nd = nen * nda
    nphi = phis.shape[0]
    t, ta = mirror_trig(hn, phis)
    Ke = np.zeros((ne, nd, nd))
    imperfect = Fi.shape[0] > 0
    Gk = np.empty((K, 9))
    v = np.empty(9)
    dpsi = np.zeros(9)
    d2psi = np.zeros((9, 9))
    dJ = np.zeros(9)
    d2J = np.zeros((9, 9))
    ve = np.empty(9)
    dpe = np.zeros(9)
    d2pe = np.zeros((9, 9))
    dJe = np.zeros(9)
    d2Je = np.zeros((9, 9))
    dJq = np.empty((nq, nphi, 9))
    Dq = np.empty((nq, nphi, 9, 9))
    d2Jq = np.empty((nq, nphi, 9, 9))
    g = np.empty((nphi, npr))
    pel = np.empty((nphi, npr))
    Bq = np.empty((nq, nen, K, 9, 3))
    Dt = np.empty((9, 9))
    DB = np.empty((9, nen * 3))
    Gj = np.empty((npr, nd))
    Hj = np.empty((npr, nd))
    for e in range(ne):
        m_ = mat[e]
        mu_e = mu[m_]
        jm_e = jm[m_]
        ka = kappa[m_]
        Kel = Ke[e]
        g[:, :] = 0.0
        # the state at every quadrature and phi point (as the element pass forms it)
        for q in range(nq):
            harmonic_gradients(A, conn, dNdX, N_ref, Rq, hn, e, q, Gk)
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
                if imperfect:
                    ok, psi, J = imperfect_point(v, Fi[e, q, j], Jimp[e, q, j], mu_e, jm_e, 2, dpsi, d2psi, dJ,
                                                 d2J, ve, dpe, d2pe, dJe, d2Je)
                else:
                    ok, psi, J = gent3(v, mu_e, jm_e, 2, dpsi, d2psi, dJ, d2J)
                if not ok:
                    return False, Ke
                for c in range(9):
                    dJq[q, j, c] = dJ[c]
                    for d in range(9):
                        Dq[q, j, c, d] = W * d2psi[c, d]
                        d2Jq[q, j, c, d] = d2J[c, d]
                jw = Jimp[e, q, j] if imperfect else 1.0
                for k2 in range(npr):
                    g[j, k2] += W * jw * Np[q, k2] * (J - 1.0)
            R = Rq[e, q]
            for a in range(nen):
                bx = dNdX[e, q, a, 0]
                by = dNdX[e, q, a, 1]
                bn = N_ref[q, a] / R
                for k in range(K):
                    node_b(bx, by, bn, -float(hn[k]), Bq[q, a, k])
        # the element pressures at every phi point, and their geometric term W p d2J
        for j in range(nphi):
            Mi = Minvp[e, j] if imperfect else Minv[e]
            for k2 in range(npr):
                s = 0.0
                for l2 in range(npr):
                    s += Mi[k2, l2] * g[j, l2]
                pel[j, k2] = ka * s
        for q in range(nq):
            W = Wq[e, q]
            for j in range(nphi):
                pq = 0.0
                for k2 in range(npr):
                    pq += Np[q, k2] * pel[j, k2]
                pw = W * pq
                for c in range(9):
                    for d in range(9):
                        Dq[q, j, c, d] += pw * d2Jq[q, j, c, d]
        # the elastic part, harmonic pair by pair (k <= l): phi-moments of D with the perturbation's
        # trig factors, then B'_k^T Dt B'_l per point
        for k in range(K):
            for l in range(k, K):
                for q in range(nq):
                    for c in range(9):
                        for d in range(9):
                            s = 0.0
                            for j in range(nphi):
                                s += wphi[j] * ta[j, k, c] * ta[j, l, d] * Dq[q, j, c, d]
                            Dt[c, d] = s
                    for c in range(9):
                        for b in range(nen):
                            Bl = Bq[q, b, l]
                            for i2 in range(3):
                                s = 0.0
                                for d in range(9):
                                    s += Dt[c, d] * Bl[d, i2]
                                DB[c, 3 * b + i2] = s
                    for a in range(nen):
                        Bk = Bq[q, a, k]
                        for i in range(3):
                            row = a * nda + 3 * k + i
                            for b in range(nen):
                                for i2 in range(3):
                                    s = 0.0
                                    for c in range(9):
                                        s += Bk[c, i] * DB[c, 3 * b + i2]
                                    Kel[row, b * nda + 3 * l + i2] += s
        # the lower blocks (l < k) are the transposes of the upper ones
        for a in range(nen):
            for k in range(K):
                for i in range(3):
                    row = a * nda + 3 * k + i
                    for b in range(nen):
                        for l in range(k + 1, K):
                            for i2 in range(3):
                                col = b * nda + 3 * l + i2
                                Kel[col, row] = Kel[row, col]
        # the volumetric constraint: sum_j w_j kappa G'_j^T M^-1 G'_j
        for j in range(nphi):
            Gj[:, :] = 0.0
            for q in range(nq):
                W = Wq[e, q]
                for k in range(K):
                    for a in range(nen):
                        Bk = Bq[q, a, k]
                        for i in range(3):
                            s = 0.0
                            for c in range(9):
                                s += dJq[q, j, c] * ta[j, k, c] * Bk[c, i]
                            col = a * nda + 3 * k + i
                            for k2 in range(npr):
                                Gj[k2, col] += W * Np[q, k2] * s
            Mi = Minvp[e, j] if imperfect else Minv[e]
            for k2 in range(npr):
                for x in range(nd):
                    s = 0.0
                    for l2 in range(npr):
                        s += Mi[k2, l2] * Gj[l2, x]
                    Hj[k2, x] = wphi[j] * ka * s
            for x in range(nd):
                for y in range(nd):
                    s = 0.0
                    for k2 in range(npr):
                        s += Gj[k2, x] * Hj[k2, y]
                    Kel[x, y] += s
    return True, Ke


@njit(cache=True)
def mirror_cavity(X: np.ndarray, A: np.ndarray, edges: np.ndarray, hn: np.ndarray, phis: np.ndarray,
                  wphi: np.ndarray) -> np.ndarray:
    """Per edge, the second derivative of the 3D cavity volume of
    :func:`snapjump_kernels.mh_cavity.mh_cavity` in the antisymmetric amplitudes at the state ``A``
    (``(m, 3 K nen, 3 K nen)``, the module docstring's dof order): ``rho = r + a' sin n phi``,
    ``sigma = c' cos n phi``, ``zeta = z + b' sin n phi`` in the flux integrand, whose Hessian at
    the state is contracted with them at every Gauss and phi point (the volume is cubic: the rule
    integrates it exactly as for the state)."""
    m, nen = edges.shape
    K = hn.shape[0]
    nda = 3 * K
    nde = nen * nda
    nphi = phis.shape[0]
    He = np.zeros((m, nde, nde))
    N = np.empty(nen)
    dN = np.empty(nen)
    y = np.empty(8)
    dv = np.empty(8)
    d2v = np.empty((8, 8))
    La = np.zeros((8, nde))
    HL = np.empty((8, nde))
    for e in range(m):
        for q in range(3):
            edge_shape(_GP[q], nen, N, dN)
            for j in range(nphi):
                w = 2.0 * np.pi * _GW[q] * wphi[j]
                y[:] = 0.0
                La[:, :] = 0.0
                for a in range(nen):
                    node = edges[e, a]
                    y[0] += N[a] * X[node, 0]
                    y[1] += dN[a] * X[node, 0]
                    y[6] += dN[a] * X[node, 1]
                    for k in range(K):
                        n = float(hn[k])
                        cs = np.cos(n * phis[j])
                        sn = np.sin(n * phis[j])
                        o = 0 if k == 0 else 2 + 3 * (k - 1)
                        ua = A[node, o]
                        ub = A[node, o + 1]
                        uc = A[node, o + 2] if k > 0 else 0.0
                        # the state (mh_cavity's y)
                        y[0] += N[a] * cs * ua
                        y[1] += dN[a] * cs * ua
                        y[2] += -n * N[a] * sn * ua
                        y[6] += dN[a] * cs * ub
                        y[7] += -n * N[a] * sn * ub
                        y[3] += N[a] * sn * uc
                        y[4] += dN[a] * sn * uc
                        y[5] += n * N[a] * cs * uc
                        # the antisymmetric perturbation
                        oa = a * nda + 3 * k
                        La[0, oa] = N[a] * sn
                        La[1, oa] = dN[a] * sn
                        La[2, oa] = n * N[a] * cs
                        La[6, oa + 1] = dN[a] * sn
                        La[7, oa + 1] = n * N[a] * cs
                        La[3, oa + 2] = N[a] * cs
                        La[4, oa + 2] = dN[a] * cs
                        La[5, oa + 2] = -n * N[a] * sn
                _cavity_point(y, 2, dv, d2v)
                for r in range(8):
                    for i in range(nde):
                        s = 0.0
                        for r2 in range(8):
                            s += d2v[r, r2] * La[r2, i]
                        HL[r, i] = s
                for i in range(nde):
                    for i2 in range(nde):
                        s = 0.0
                        for r in range(8):
                            s += La[r, i] * HL[r, i2]
                        He[e, i, i2] += w * s
    return He
