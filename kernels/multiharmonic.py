"""Nonlinear multi-harmonic (Fourier) mixed Gent solid: energy, residual and tangent.

The displacement of the 2D mesh's solid of revolution is a truncated Fourier series in the
circumferential angle phi, in the subspace that is mirror-symmetric about ``phi = 0``::

    u_r = sum_k a_k(R, Z) cos n_k phi,   u_z = sum_k b_k(R, Z) cos n_k phi,
    u_phi = sum_{k >= 1} c_k(R, Z) sin n_k phi,                 (n_0 = 0: no torsion)

with the harmonics ``n_k`` of ``hn`` (``hn[0] = 0``). The nodal unknowns are stored node by node,
``[a_0, b_0, a_1, b_1, c_1, a_2, ...]`` (``nc = 2 + 3 (K - 1)`` per node, ``K = len(hn)``).

The full 3D deformation gradient (rows r, phi, z; columns R, Phi, Z) at ``phi`` is::

    F = | 1 + u_r,R             (u_r,phi - u_phi) / R          u_r,Z     |
        | u_phi,R               1 + (u_r + u_phi,phi) / R      u_phi,Z   |
        | u_z,R                 u_z,phi / R                    1 + u_z,Z |

stored as the 9-vector ``v = [F_rR, F_rZ, F_zR, F_zZ, F_phiPhi | F_rPhi, F_phiR, F_phiZ, F_zPhi]``:
the first five carry ``cos n phi`` (the axisymmetric components of :mod:`snapjump_kernels.gent`),
the last four ``sin n phi``. The energy is the phi-average (times the ``2 pi R`` weight that
``Wq`` carries) of the mixed element's reduced energy evaluated with the 3D ``F`` at every phi
point of a trapezoidal rule on ``[0, pi / n_1]`` (the fields are even in phi and, with harmonics
that are multiples of ``n_1``, ``2 pi / n_1``-periodic)::

    Pi = sum_j w_j [ sum_q W_q psi_iso(F_q(phi_j)) + kappa/2 g_j^T M^-1 g_j ],
    g_j = sum_q W_q Np_q (J_q(phi_j) - 1)

so the pressure and the dilatation are eliminated at every phi point, as the axisymmetric element
does (:mod:`snapjump_kernels.assembly`). Gradient and Hessian are exact for that quadrature; they
are formed through the phi-moments of the pointwise stress and tangent, ``sum_j w_j t_k(phi_j)
s(phi_j)`` and ``sum_j w_j t_k t_l D(phi_j)`` (``t = cos`` or ``sin`` by component), contracted with
the phi-independent nodal B matrices of each harmonic.

The cavity volume is the exact 3D flux ``V = -1/2 int int (x, y, 0) . (x_s x x_phi) ds dphi``
(docs/harmonics.md, section 4), a cubic polynomial of the amplitudes, integrated exactly when the
rule has more than ``3 K_max / 2`` intervals.

Arrays in, arrays out.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.gent import gent_scalars
from snapjump_kernels.cavity import edge_shape

_GP = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GW = np.array([5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0])
# (row, column) of each of the 9 components in the 3x3 matrix
_ROW = np.array([0, 0, 2, 2, 1, 0, 1, 1, 2])
_COL = np.array([0, 2, 0, 2, 1, 1, 0, 2, 1])
# component of each (row, column) of the 3x3 matrix
_IDX = np.array([[0, 5, 1], [6, 4, 7], [2, 8, 3]])


@njit(cache=True)
def phi_rule(n1: int, m: int) -> tuple:
    """Trapezoidal rule on ``[0, pi / n1]`` with ``m`` intervals (``m + 1`` points; one point of
    weight 1 for ``m = 0``): the points and the weights of the phi-average, summing to 1."""
    if m == 0:
        return np.zeros(1), np.ones(1)
    phis = np.empty(m + 1)
    w = np.empty(m + 1)
    for j in range(m + 1):
        phis[j] = j * np.pi / (n1 * m)
        w[j] = 1.0 / m
    w[0] *= 0.5
    w[m] *= 0.5
    return phis, w


@njit(cache=True)
def _offset(k: int) -> int:
    return 0 if k == 0 else 2 + 3 * (k - 1)


@njit(cache=True)
def _ndof_k(k: int) -> int:
    return 2 if k == 0 else 3


@njit(cache=True)
def _node_b(bx: float, by: float, bn: float, n: float, B: np.ndarray) -> None:
    """Dense 9 x 3 B of one node and harmonic ``n`` (columns a, b, c)."""
    B[:, :] = 0.0
    B[0, 0] = bx
    B[1, 0] = by
    B[4, 0] = bn
    B[5, 0] = -n * bn
    B[2, 1] = bx
    B[3, 1] = by
    B[8, 1] = -n * bn
    B[4, 2] = n * bn
    B[5, 2] = -bn
    B[6, 2] = bx
    B[7, 2] = by


@njit(cache=True, inline="always")
def _db_cols(D: np.ndarray, bx: float, by: float, bn: float, n: float, out: np.ndarray) -> None:
    """``out (9, 3) = D (9x9) @ B`` of one node and harmonic ``n`` (the sparse B of :func:`_node_b`)."""
    nbn = n * bn
    for c in range(9):
        out[c, 0] = D[c, 0] * bx + D[c, 1] * by + D[c, 4] * bn - D[c, 5] * nbn
        out[c, 1] = D[c, 2] * bx + D[c, 3] * by - D[c, 8] * nbn
        out[c, 2] = D[c, 4] * nbn - D[c, 5] * bn + D[c, 6] * bx + D[c, 7] * by


@njit(cache=True, inline="always")
def _bt_db(bx: float, by: float, bn: float, n: float, DB: np.ndarray, nk: int, nl: int, K: np.ndarray,
           oa: int, ob: int) -> None:
    """``K[oa:oa+nk, ob:ob+nl] += B^T DB`` for one node's sparse B (harmonic ``n``)."""
    nbn = n * bn
    for j in range(nl):
        K[oa, ob + j] += bx * DB[0, j] + by * DB[1, j] + bn * DB[4, j] - nbn * DB[5, j]
        K[oa + 1, ob + j] += bx * DB[2, j] + by * DB[3, j] - nbn * DB[8, j]
        if nk > 2:
            K[oa + 2, ob + j] += nbn * DB[4, j] - bn * DB[5, j] + bx * DB[6, j] + by * DB[7, j]


@njit(cache=True)
def gent3(v: np.ndarray, mu: float, jm: float, want: int, dpsi: np.ndarray, d2psi: np.ndarray, dJ: np.ndarray,
          d2J: np.ndarray) -> tuple:
    """Isochoric Gent energy of a full 3D deformation gradient (the 9-vector ``v``) with its first
    (``want >= 1``) and second (``want >= 2``) derivatives, and ``J`` with its derivatives.

    Returns ``(ok, psi, J)``; ``ok`` is False outside the Gent domain (or ``J <= 0``).
    """
    F = np.empty((3, 3))
    for c in range(9):
        F[_ROW[c], _COL[c]] = v[c]
    J = (F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]) - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
         + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]))
    # cofactor dJ/dF_iA
    for c in range(9):
        i = _ROW[c]
        A = _COL[c]
        i1 = (i + 1) % 3
        i2 = (i + 2) % 3
        A1 = (A + 1) % 3
        A2 = (A + 2) % 3
        dJ[c] = F[i1, A1] * F[i2, A2] - F[i1, A2] * F[i2, A1]
    if want >= 2:
        for c in range(9):
            i = _ROW[c]
            A = _COL[c]
            for d in range(9):
                j = _ROW[d]
                B = _COL[d]
                if i == j or A == B:
                    d2J[c, d] = 0.0
                else:
                    k = 3 - i - j
                    C = 3 - A - B
                    s1 = 1.0 if (j - i) % 3 == 1 else -1.0
                    s2 = 1.0 if (B - A) % 3 == 1 else -1.0
                    d2J[c, d] = s1 * s2 * F[k, C]
    if J <= 0.0:
        return False, 0.0, J
    I1 = 0.0
    for c in range(9):
        I1 += v[c] * v[c]
    ok, psi, cc, a, b = gent_scalars(J, I1, mu, jm)
    if not ok:
        return False, 0.0, J
    if want >= 1:
        cJ = (2.0 / 3.0) * cc / J
        dI = np.empty(9)
        for c in range(9):
            dI[c] = 2.0 * cc * v[c] - cJ * I1 * dJ[c]
            dpsi[c] = a * dI[c]
        if want >= 2:
            t = (10.0 / 9.0) * cc / (J * J) * I1
            for c in range(9):
                for d in range(c, 9):
                    d2 = -cJ * (2.0 * v[c] * dJ[d] + 2.0 * v[d] * dJ[c]) + t * dJ[c] * dJ[d] - cJ * I1 * d2J[c, d]
                    if c == d:
                        d2 += 2.0 * cc
                    val = a * d2 + b * dI[c] * dI[d]
                    d2psi[c, d] = val
                    d2psi[d, c] = val
    return True, psi, J


@njit(cache=True)
def imperfect_point(v: np.ndarray, Fi: np.ndarray, Jimp: float, mu: float, jm: float, want: int, dpsi: np.ndarray,
                    d2psi: np.ndarray, dJ: np.ndarray, d2J: np.ndarray, ve: np.ndarray, dpe: np.ndarray,
                    d2pe: np.ndarray, dJe: np.ndarray, d2Je: np.ndarray) -> tuple:
    """:func:`gent3` of an imperfect body, in the total gradient ``v`` (from the perfect reference).

    The imperfect body is stress-free in the configuration ``F0`` of the perfect reference; with
    ``Fi = F0^-1`` and ``Jimp = det F0`` its elastic gradient is ``Fe = F Fi``, its energy per unit
    perfect-reference volume ``Jimp psi(Fe)``. Returns ``(ok, Jimp psi, det Fe)`` with the
    derivatives in ``v``: ``dpsi = Jimp T^T dpsi_e``, ``d2psi = Jimp T^T d2psi_e T``,
    ``dJ = Jimp T^T dJ_e``, ``d2J = Jimp T^T d2J_e T`` (``T`` the linear map ``v -> ve``, i.e.
    ``Fe[i, B] = sum_A F[i, A] Fi[A, B]``), so that the caller's volume integrals of ``psi`` and of
    ``J - 1`` (weighted by ``Jimp``) are those over the imperfect body. ``ve, dpe, d2pe, dJe, d2Je``
    are work arrays.
    """
    for c in range(9):
        i = _ROW[c]
        B = _COL[c]
        s = 0.0
        for A in range(3):
            s += v[_IDX[i, A]] * Fi[A, B]
        ve[c] = s
    ok, psi, J = gent3(ve, mu, jm, want, dpe, d2pe, dJe, d2Je)
    if not ok or Jimp <= 0.0:
        return False, 0.0, J
    # T[c, d] = delta(row c, row d) Fi[col d, col c] (dpsi_e is stale unless want >= 1: unused then)
    for d in range(9):
        j = _ROW[d]
        A = _COL[d]
        s1 = 0.0
        s2 = 0.0
        for B in range(3):
            c = _IDX[j, B]
            s1 += dpe[c] * Fi[A, B]
            s2 += dJe[c] * Fi[A, B]
        dpsi[d] = Jimp * s1
        dJ[d] = Jimp * s2
    if want >= 2:
        for d in range(9):
            j = _ROW[d]
            A = _COL[d]
            for d2 in range(9):
                j2 = _ROW[d2]
                A2 = _COL[d2]
                s1 = 0.0
                s2 = 0.0
                for B in range(3):
                    c = _IDX[j, B]
                    fa = Fi[A, B]
                    for B2 in range(3):
                        c2 = _IDX[j2, B2]
                        f = fa * Fi[A2, B2]
                        s1 += d2pe[c, c2] * f
                        s2 += d2Je[c, c2] * f
                d2psi[d, d2] = Jimp * s1
                d2J[d, d2] = Jimp * s2
    return True, Jimp * psi, J


@njit(cache=True, inline="always")
def harmonic_gradients(A: np.ndarray, conn: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray,
                       hn: np.ndarray, e: int, q: int, Gk: np.ndarray) -> None:
    """The harmonic gradients ``Gk (K, 9) = sum_a B_{k,a} A_{a,k}`` of element ``e`` at quadrature
    point ``q`` (the 9 components of the module docstring, without the trigonometric factor)."""
    nen = conn.shape[1]
    K = hn.shape[0]
    R = Rq[e, q]
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


@njit(cache=True)
def point_gradients(A: np.ndarray, conn: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray,
                    hn: np.ndarray, phis: np.ndarray) -> np.ndarray:
    """The 3x3 gradient ``I + grad u`` of the amplitudes ``A`` at every quadrature and phi point,
    ``(ne, nq, nphi, 3, 3)`` (rows r, phi, z; columns R, Phi, Z), as :func:`mh_elements` forms it."""
    ne, nen = conn.shape
    nq = Rq.shape[1]
    K = hn.shape[0]
    nphi = phis.shape[0]
    out = np.zeros((ne, nq, nphi, 3, 3))
    Gk = np.empty((K, 9))
    for e in range(ne):
        for q in range(nq):
            harmonic_gradients(A, conn, dNdX, N_ref, Rq, hn, e, q, Gk)
            for j in range(nphi):
                for c in range(9):
                    s = 0.0
                    for k in range(K):
                        n = float(hn[k])
                        s += (np.cos(n * phis[j]) if c < 5 else np.sin(n * phis[j])) * Gk[k, c]
                    out[e, q, j, _ROW[c], _COL[c]] = s
                out[e, q, j, 0, 0] += 1.0
                out[e, q, j, 1, 1] += 1.0
                out[e, q, j, 2, 2] += 1.0
    return out


@njit(cache=True)
def _pair_weights(t: np.ndarray, wphi: np.ndarray, K: int) -> np.ndarray:
    """``WT[p, j, 9 c + d] = (w_j t_k(phi_j, c)) t_l(phi_j, d)`` for the harmonic pairs
    ``p = (k, l)``, ``k <= l`` (``k`` outer): the weights of the phi-moments of the tangent,
    ``Dt_kl = sum_j WT[p, j] * D(phi_j)`` (``t`` is ``cos`` for the components ``c < 5``, ``sin``
    after)."""
    nphi = t.shape[0]
    WT = np.empty((K * (K + 1) // 2, nphi, 81))
    p = 0
    for k in range(K):
        for l in range(k, K):
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
                for c in range(9):
                    for d in range(9):
                        if c < 5:
                            WT[p, j, 9 * c + d] = wcc if d < 5 else wcs
                        else:
                            WT[p, j, 9 * c + d] = wsc if d < 5 else wss
            p += 1
    return WT


@njit(cache=True, error_model="numpy")
def _elastic_tangent(Dq: np.ndarray, WT: np.ndarray, bxq: np.ndarray, byq: np.ndarray, bnq: np.ndarray,
                     hn: np.ndarray, upto: int, Dtp: np.ndarray, DB: np.ndarray, Kh: np.ndarray) -> None:
    """The elastic tangent ``sum_q B_k^T Dt_kl B_l`` of one element, harmonic pair by pair
    (``k <= l``), into ``Kh`` in the *harmonic-major* element order: dof ``(k, i, a)`` (harmonic,
    component a/b/c, node) at ``nen offset(k) + i nen + a``, so that the columns of every harmonic
    ``l >= k`` are contiguous and the rows below run over all of them (126 - 18 k columns for
    ``K = 5`` on Q9; LLVM vectorises them).

    Phase 3 (``upto >= 3``): the phi-moments ``Dtp[p, q] = sum_j WT[p, j] Dq[q, j]`` (flat 81).
    Phase 4 (``upto >= 4``): per harmonic ``k`` and point, ``DB = Dt_kl B_l`` of every node and
    every ``l >= k`` side by side (``DB[c, nen offset(l) - nen offset(k) + i nen + b]``), then the
    rows ``B_k^T DB`` of every node of harmonic ``k`` over all of them (a node's B is sparse: its
    columns a, b, c have 4, 3 and 4 non-zeros). Every entry receives the terms of the points in
    the order of ``q``, each summed as in
    :func:`snapjump_kernels.multiharmonic_reference.mh_elements_reference` (the same terms in the
    same order, bit for bit; the rows of 2026-11-27 ran over one pair's 18 or 27 columns).

    ``Dq (nq, nphi, 9, 9)`` the pointwise ``W (d2psi + p d2J)``; ``bxq, byq, bnq (nq, nen)`` the
    node values ``dN/dR, dN/dZ, N / R`` at each point; ``Dtp (npair, nq, 81)``, ``DB (9, nen nc)``
    work arrays.
    """
    nq, nphi = Dq.shape[0], Dq.shape[1]
    nen = bxq.shape[1]
    K = hn.shape[0]
    nd = Kh.shape[0]
    Df = Dq.reshape(nq, nphi, 81)
    npair = K * (K + 1) // 2
    for p in range(npair):
        for q in range(nq):
            acc = Dtp[p, q]
            for x in range(81):
                acc[x] = 0.0
            for j in range(nphi):
                w = WT[p, j]
                dq = Df[q, j]
                for x in range(81):
                    acc[x] += w[x] * dq[x]
    if upto <= 3:
        return
    Kh[:, :] = 0.0
    for k in range(K):
        nk = _ndof_k(k)
        fk = float(hn[k])
        r0 = nen * _offset(k)
        m = nd - r0  # the columns of every harmonic l >= k: contiguous in the harmonic-major order
        for q in range(nq):
            bx = bxq[q]
            by = byq[q]
            bn = bnq[q]
            for l in range(k, K):
                p = _pair_index(k, l, K)
                nl = _ndof_k(l)
                fl = float(hn[l])
                c0 = nen * _offset(l) - r0
                D = Dtp[p, q]
                for c in range(9):
                    d0 = D[9 * c]
                    d1 = D[9 * c + 1]
                    d2 = D[9 * c + 2]
                    d3 = D[9 * c + 3]
                    d4 = D[9 * c + 4]
                    d5 = D[9 * c + 5]
                    d6 = D[9 * c + 6]
                    d7 = D[9 * c + 7]
                    d8 = D[9 * c + 8]
                    ra = DB[c, c0:c0 + nen]
                    for b in range(nen):
                        ra[b] = d0 * bx[b] + d1 * by[b] + d4 * bn[b] - d5 * (fl * bn[b])
                    rb = DB[c, c0 + nen:c0 + 2 * nen]
                    for b in range(nen):
                        rb[b] = d2 * bx[b] + d3 * by[b] - d8 * (fl * bn[b])
                    if nl > 2:
                        rc = DB[c, c0 + 2 * nen:c0 + 3 * nen]
                        for b in range(nen):
                            rc[b] = d4 * (fl * bn[b]) - d5 * bn[b] + d6 * bx[b] + d7 * by[b]
            D0 = DB[0, :m]
            D1 = DB[1, :m]
            D2 = DB[2, :m]
            D3 = DB[3, :m]
            D4 = DB[4, :m]
            D5 = DB[5, :m]
            D6 = DB[6, :m]
            D7 = DB[7, :m]
            D8 = DB[8, :m]
            for a in range(nen):
                bxa = bx[a]
                bya = by[a]
                bna = bn[a]
                nbna = fk * bna
                row = Kh[r0 + a, r0:nd]
                for x in range(m):
                    row[x] += bxa * D0[x] + bya * D1[x] + bna * D4[x] - nbna * D5[x]
                row = Kh[r0 + nen + a, r0:nd]
                for x in range(m):
                    row[x] += bxa * D2[x] + bya * D3[x] - nbna * D8[x]
                if nk > 2:
                    row = Kh[r0 + 2 * nen + a, r0:nd]
                    for x in range(m):
                        row[x] += nbna * D4[x] - bna * D5[x] + bxa * D6[x] + bya * D7[x]


@njit(cache=True, inline="always")
def _pair_index(k: int, l: int, K: int) -> int:
    """Index of the harmonic pair ``(k, l)``, ``k <= l``, in the order ``k`` outer, ``l`` inner."""
    return k * K - k * (k - 1) // 2 + (l - k)


@njit(cache=True, error_model="numpy")
def _volumetric_tangent(e: int, dJq: np.ndarray, t: np.ndarray, Wq: np.ndarray, Np: np.ndarray, Minv: np.ndarray,
                        Minvp: np.ndarray, imperfect: bool, wphi: np.ndarray, ka: float, bxq: np.ndarray,
                        byq: np.ndarray, bnq: np.ndarray, hn: np.ndarray, Gv: np.ndarray, Hv: np.ndarray,
                        KL: np.ndarray, tmp: np.ndarray, Ke: np.ndarray) -> None:
    """Add the volumetric-constraint stiffness ``sum_j w_j kappa G_j^T M^-1 G_j`` of element ``e``
    to its node-major tangent ``Ke`` (both triangles, each entry's terms in the order of
    :func:`snapjump_kernels.multiharmonic_reference.mh_elements_reference`). ``G_j`` is formed from
    the sparse B (``B^T (dJ t)`` per node) and ``H_j = w_j kappa M^-1 G_j`` for every phi point
    first; then each row ``i`` of the upper triangle receives the terms ``G_j[:, i]^T H_j`` of
    every point in turn (``j`` in order, each summed over the pressure dofs from 0), the row
    staying in the L1 cache (it was one pass over the whole element matrix per phi point). The
    lower triangle is accumulated transposed in ``KL`` (rows contiguous) and written back at the
    end. ``Gv, Hv (nphi, npr, nd)``, ``KL (nd, nd)``, ``tmp (nd,)`` are work arrays."""
    nd = Ke.shape[0]
    nq, nphi = dJq.shape[0], dJq.shape[1]
    npr = Np.shape[1]
    K = hn.shape[0]
    nen = bxq.shape[1]
    nc = 2 + 3 * (K - 1)
    for i in range(nd):
        for jj in range(i + 1, nd):
            KL[i, jj] = Ke[jj, i]
    for j in range(nphi):
        Gj = Gv[j]
        Gj[:, :] = 0.0
        for q in range(nq):
            W = Wq[e, q]
            for k in range(K):
                n = float(hn[k])
                y0 = dJq[q, j, 0] * t[j, k, 0]
                y1 = dJq[q, j, 1] * t[j, k, 1]
                y2 = dJq[q, j, 2] * t[j, k, 2]
                y3 = dJq[q, j, 3] * t[j, k, 3]
                y4 = dJq[q, j, 4] * t[j, k, 4]
                y5 = dJq[q, j, 5] * t[j, k, 5]
                y6 = dJq[q, j, 6] * t[j, k, 6]
                y7 = dJq[q, j, 7] * t[j, k, 7]
                y8 = dJq[q, j, 8] * t[j, k, 8]
                for a in range(nen):
                    bx = bxq[q, a]
                    by = byq[q, a]
                    bn = bnq[q, a]
                    o = a * nc + _offset(k)
                    s0 = y0 * bx + y1 * by + y4 * bn + y5 * (-n * bn)
                    s1 = y2 * bx + y3 * by + y8 * (-n * bn)
                    for k2 in range(npr):
                        wn = W * Np[q, k2]
                        Gj[k2, o] += wn * s0
                        Gj[k2, o + 1] += wn * s1
                    if k > 0:
                        s2 = y4 * (n * bn) + y5 * (-bn) + y6 * bx + y7 * by
                        for k2 in range(npr):
                            Gj[k2, o + 2] += W * Np[q, k2] * s2
        Mi = Minvp[e, j] if imperfect else Minv[e]
        Hj = Hv[j]
        for k2 in range(npr):
            for i in range(nd):
                s = 0.0
                for l2 in range(npr):
                    s += Mi[k2, l2] * Gj[l2, i]
                Hj[k2, i] = wphi[j] * ka * s
    # row by row, every phi point's rank-npr term in turn (the row stays in the L1 cache); each
    # entry receives the terms of the points in the order of j, each summed over k2 from 0
    for i in range(nd):
        ru = Ke[i, i:]
        rl = KL[i, i:]  # KL[i, i] is not written back
        w = nd - i
        for j in range(nphi):
            if npr == 3:
                g0 = Gv[j, 0, i]
                g1 = Gv[j, 1, i]
                g2 = Gv[j, 2, i]
                h0 = Hv[j, 0, i:]
                h1 = Hv[j, 1, i:]
                h2 = Hv[j, 2, i:]
                for x in range(w):
                    tv = 0.0
                    tv += g0 * h0[x]
                    tv += g1 * h1[x]
                    tv += g2 * h2[x]
                    ru[x] += tv
                    rl[x] += tv
            else:
                tv = tmp[:w]
                for x in range(w):
                    tv[x] = 0.0
                for k2 in range(npr):
                    gi = Gv[j, k2, i]
                    h = Hv[j, k2, i:]
                    for x in range(w):
                        tv[x] += gi * h[x]
                for x in range(w):
                    ru[x] += tv[x]
                    rl[x] += tv[x]
    for i in range(nd):
        for jj in range(i + 1, nd):
            Ke[jj, i] = KL[i, jj]


@njit(cache=True)
def mh_elements(A: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
                kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
                Np: np.ndarray, Minv: np.ndarray, hn: np.ndarray, phis: np.ndarray, wphi: np.ndarray,
                want: int, Fi: np.ndarray, Jimp: np.ndarray, Minvp: np.ndarray):
    """See :func:`mh_elements_phases` (all phases)."""
    return mh_elements_phases(A, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, hn, phis, wphi, want, Fi,
                              Jimp, Minvp, 5)


@njit(cache=True)
def mh_elements_phases(A: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
                       kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
                       Np: np.ndarray, Minv: np.ndarray, hn: np.ndarray, phis: np.ndarray, wphi: np.ndarray,
                       want: int, Fi: np.ndarray, Jimp: np.ndarray, Minvp: np.ndarray, upto: int):
    """Energy, element residuals and element tangents of the multi-harmonic solid.

    Parameters
    ----------
    A : (nn, nc) nodal amplitudes (scaled displacements), layout of the module docstring
    conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv : as in
        :func:`snapjump_kernels.assembly.assemble`
    hn : (K,) harmonic numbers, ``hn[0] = 0``
    phis, wphi : the phi rule (:func:`phi_rule`)
    want : 0 energy, 1 and residuals, 2 and tangents
    Fi, Jimp : an initial geometric imperfection (empty arrays: none). ``Fi (ne, nq, nphi, 3, 3)``
        is the inverse of the imperfection's deformation gradient ``F0`` (perfect reference ->
        stress-free imperfect body) at every point and ``Jimp = det F0``. ``A`` is then the total
        displacement from the perfect reference (imperfection included); the elastic gradient is
        ``F F0^-1`` and every volume integral carries ``Jimp`` (:func:`imperfect_point`)
    Minvp : ``(ne, nphi, np, np)`` with an imperfection: the inverse pressure mass matrices of the
        imperfect body at every phi point (``sum_q W_q Jimp Np Np^T``), used instead of ``Minv``
    upto : the last phase run (for profiling, ``bench/follow_profile.py``; 5 = all): 1 the pointwise
        material law, 2 the pressures, energy and residual, 3 the phi-moments of the tangent, 4 the
        ``B_k^T D_kl B_l`` blocks, 5 the mirror and the volumetric-constraint stiffness

    Returns
    -------
    (E, ok, re, Ke) : the energy, False if some point left the Gent domain, the element residuals
        (ne, nen nc) and tangents (ne, nen nc, nen nc; empty unless ``want >= 2``)
    """
    return _mh_pass(A, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, hn, phis, wphi, want, Fi, Jimp,
                    Minvp, upto, False, np.zeros((0, 0), np.int64), np.zeros((0, 0)), np.zeros((0, 0)))


@njit(cache=True)
def _mh_pass(A: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
             kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
             Np: np.ndarray, Minv: np.ndarray, hn: np.ndarray, phis: np.ndarray, wphi: np.ndarray,
             want: int, Fi: np.ndarray, Jimp: np.ndarray, Minvp: np.ndarray, upto: int, fused: bool,
             edofs: np.ndarray, ecoef: np.ndarray, ab: np.ndarray):
    """The element pass of :func:`mh_elements_phases`; with ``fused`` (and ``want >= 2``) each
    element's tangent is scattered into the band ``ab`` as soon as it is formed (as
    :func:`snapjump_kernels.harmonics.scatter_band` with factor 1 would, element by element) and
    not kept: the returned ``Ke`` is then one element's work array."""
    ne, nen = conn.shape
    nq = Wq.shape[1]
    npr = Np.shape[1]
    K = hn.shape[0]
    nc = 2 + 3 * (K - 1)
    nd = nen * nc
    nphi = phis.shape[0]
    re = np.zeros((ne, nd))
    fuse = fused and want >= 2
    Ke = np.zeros(((1 if fuse else ne), nd, nd)) if want >= 2 else np.zeros((0, nd, nd))
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
    Gv = np.empty((nphi, npr, nd))
    Hv = np.empty((nphi, npr, nd))
    bq = np.empty((nen, 3))
    hk = np.empty(nd, np.int64)  # harmonic index of each element dof
    # the tangent's work arrays (docstring of _elastic_tangent)
    npair = K * (K + 1) // 2
    WT = _pair_weights(t, wphi, K) if want >= 2 else np.empty((0, nphi, 81))
    Dtp = np.empty((npair, nq, 81))
    DB = np.empty((9, nd))
    Kh = np.zeros((nd, nd))
    KL = np.empty((nd, nd))
    tmp = np.empty(nd)
    bxq = np.empty((nq, nen))
    byq = np.empty((nq, nen))
    bnq = np.empty((nq, nen))
    hperm = np.empty(nd, np.int64)  # node-major element dof of each harmonic-major one
    for k in range(K):
        for dof in range(_ndof_k(k)):
            for a in range(nen):
                hperm[nen * _offset(k) + dof * nen + a] = a * nc + _offset(k) + dof
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
        if upto <= 1:
            continue
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
            # the node values of B at this point, by node (contiguous over the nodes)
            for a in range(nen):
                bxq[q, a] = bq[a, 0]
                byq[q, a] = bq[a, 1]
                bnq[q, a] = bq[a, 2]
            if want < 2 or upto <= 2:
                continue
            # the tangent's pointwise D with the pressure part, W (d2psi + p d2J)
            for j in range(nphi):
                pq = 0.0
                for k2 in range(npr):
                    pq += Np[q, k2] * pel[j, k2]
                pw = W * pq
                for c in range(9):
                    for d in range(9):
                        Dq[q, j, c, d] += pw * d2Jq[q, j, c, d]
        if want < 2 or upto <= 2:
            continue
        _elastic_tangent(Dq, WT, bxq, byq, bnq, hn, upto, Dtp, DB, Kh)
        if upto <= 3:
            continue
        # harmonic-major blocks -> node-major Ke; the blocks of harmonics k < l were formed once:
        # their transposes are the (l, k) blocks (as the element dofs' harmonics say)
        Ke_e = Ke[0] if fuse else Ke[e]
        for r in range(nd):
            pr = hperm[r]
            kr = hk[pr]
            for c in range(nd):
                pc = hperm[c]
                if kr <= hk[pc]:
                    Ke_e[pr, pc] = Kh[r, c]
        for i in range(nd):
            for jj in range(nd):
                if hk[i] < hk[jj]:
                    Ke_e[jj, i] = Ke_e[i, jj]
        if upto <= 4:
            continue
        _volumetric_tangent(e, dJq, t, Wq, Np, Minv, Minvp, imperfect, wphi, ka, bxq, byq, bnq, hn, Gv, Hv, KL,
                            tmp, Ke_e)
        if fuse and upto >= 5:
            _scatter_element(Ke_e, edofs[e], ecoef[e], ab)
    return E, True, re, Ke


@njit(cache=True, inline="always")
def _scatter_element(Ke: np.ndarray, dofs: np.ndarray, coef: np.ndarray, ab: np.ndarray) -> None:
    """``ab += P^T Ke P`` of one element into the lower band (the terms of
    :func:`snapjump_kernels.harmonics.scatter_band` with factor 1, in its order)."""
    nd = dofs.shape[0]
    for i in range(nd):
        di = dofs[i]
        if di < 0:
            continue
        ci = coef[i] * 1.0
        row = Ke[i]
        for j in range(nd):
            dj = dofs[j]
            if dj < 0 or dj > di:
                continue
            ab[dj, di - dj] += ci * coef[j] * row[j]


@njit(cache=True)
def mh_assemble_band(A: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
                     kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
                     Np: np.ndarray, Minv: np.ndarray, hn: np.ndarray, phis: np.ndarray, wphi: np.ndarray,
                     Fi: np.ndarray, Jimp: np.ndarray, Minvp: np.ndarray, edofs: np.ndarray, ecoef: np.ndarray,
                     ext: np.ndarray, ab: np.ndarray):
    """Energy, element residuals and the tangent scattered into the lower band ``ab`` in one pass.

    ``ab``'s envelope (``ab[j, :ext[j] + 1]``) is zeroed first (entries outside it are neither
    read nor written: a band that was zero there stays so); then every element's tangent is
    added as it is formed: the same band, bit for bit, as :func:`mh_elements` (``want = 2``)
    followed by :func:`snapjump_kernels.harmonics.scatter_band` (factor 1), without the
    ``(ne, nd, nd)`` element matrices in memory.

    Returns
    -------
    (E, ok, re) : as :func:`mh_elements`; ``ab`` holds the elements' tangent (undefined if not ``ok``)
    """
    n = ab.shape[0]
    for j in range(n):
        col = ab[j, :ext[j] + 1]
        for x in range(col.size):
            col[x] = 0.0
    E, ok, re, _ = _mh_pass(A, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, hn, phis, wphi, 2, Fi,
                            Jimp, Minvp, 5, True, edofs, ecoef, ab)
    return E, ok, re


@njit(cache=True)
def _cavity_point(y: np.ndarray, want: int, dv: np.ndarray, d2v: np.ndarray) -> float:
    """``v = -P / 2`` of the flux integrand in ``y = (rho, rho_s, rho_phi, sig, sig_s, sig_phi,
    zeta_s, zeta_phi)``, ``P = rho sig_s zeta_phi - rho zeta_s (rho + sig_phi) + sig zeta_s (rho_phi
    - sig) - sig rho_s zeta_phi``, with its gradient and Hessian."""
    r, rs, rp, s, ss, sp, zs, zp = y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7]
    P = r * ss * zp - r * zs * (r + sp) + s * zs * (rp - s) - s * rs * zp
    if want >= 1:
        dv[0] = ss * zp - 2.0 * r * zs - zs * sp
        dv[1] = -s * zp
        dv[2] = s * zs
        dv[3] = zs * rp - 2.0 * s * zs - rs * zp
        dv[4] = r * zp
        dv[5] = -r * zs
        dv[6] = -r * r - r * sp + s * rp - s * s
        dv[7] = r * ss - s * rs
        for i in range(8):
            dv[i] *= -0.5
    if want >= 2:
        d2v[:, :] = 0.0
        d2v[0, 0] = -2.0 * zs
        d2v[0, 4] = zp
        d2v[0, 7] = ss
        d2v[0, 6] = -2.0 * r - sp
        d2v[0, 5] = -zs
        d2v[1, 3] = -zp
        d2v[1, 7] = -s
        d2v[2, 3] = zs
        d2v[2, 6] = s
        d2v[3, 3] = -2.0 * zs
        d2v[3, 6] = rp - 2.0 * s
        d2v[3, 7] = -rs
        d2v[4, 7] = r
        d2v[5, 6] = -r
        for i in range(8):
            for k in range(i + 1, 8):
                if d2v[i, k] != 0.0:
                    d2v[k, i] = d2v[i, k]
                elif d2v[k, i] != 0.0:
                    d2v[i, k] = d2v[k, i]
        for i in range(8):
            for k in range(8):
                d2v[i, k] *= -0.5
    return -0.5 * P


@njit(cache=True)
def mh_cavity(X: np.ndarray, A: np.ndarray, edges: np.ndarray, hn: np.ndarray, phis: np.ndarray,
              wphi: np.ndarray, want: int):
    """The cavity volume of the multi-harmonic surface (the 3D flux, without the offset) with its
    gradient and Hessian per edge in the edge dofs ``(node, component)`` of the layout.

    Parameters
    ----------
    X : (nn, 2) reference positions (scaled); A : (nn, nc) amplitudes; edges : (m, 2|3) oriented
        cavity edges as in :mod:`snapjump_kernels.cavity`; hn, phis, wphi : as in :func:`mh_elements`

    Returns
    -------
    (V, ge, He) : the volume, (m, nen nc) gradients, (m, nen nc, nen nc) Hessians (``want``: 0, 1, 2)
    """
    m, nen = edges.shape
    K = hn.shape[0]
    nc = 2 + 3 * (K - 1)
    nd = nen * nc
    nphi = phis.shape[0]
    ge = np.zeros((m, nd))
    He = np.zeros((m, nd, nd)) if want >= 2 else np.zeros((0, nd, nd))
    N = np.empty(nen)
    dN = np.empty(nen)
    y = np.empty(8)
    dv = np.empty(8)
    d2v = np.empty((8, 8))
    Lm = np.zeros((8, nd))
    HL = np.empty((8, nd))
    V = 0.0
    for e in range(m):
        for q in range(3):
            edge_shape(_GP[q], nen, N, dN)
            for j in range(nphi):
                w = 2.0 * np.pi * _GW[q] * wphi[j]
                Lm[:, :] = 0.0
                y[:] = 0.0
                for a in range(nen):
                    node = edges[e, a]
                    y[0] += N[a] * X[node, 0]
                    y[1] += dN[a] * X[node, 0]
                    y[6] += dN[a] * X[node, 1]
                    for k in range(K):
                        n = float(hn[k])
                        cs = np.cos(n * phis[j])
                        sn = np.sin(n * phis[j])
                        o = a * nc + _offset(k)
                        Lm[0, o] = N[a] * cs
                        Lm[1, o] = dN[a] * cs
                        Lm[2, o] = -n * N[a] * sn
                        Lm[6, o + 1] = dN[a] * cs
                        Lm[7, o + 1] = -n * N[a] * sn
                        if k > 0:
                            Lm[3, o + 2] = N[a] * sn
                            Lm[4, o + 2] = dN[a] * sn
                            Lm[5, o + 2] = n * N[a] * cs
                # y = y_ref + L A_e
                for r in range(8):
                    s = 0.0
                    for a in range(nen):
                        node = edges[e, a]
                        for i in range(nc):
                            s += Lm[r, a * nc + i] * A[node, i]
                    y[r] += s
                V += w * _cavity_point(y, want, dv, d2v)
                if want >= 1:
                    for i in range(nd):
                        s = 0.0
                        for r in range(8):
                            s += dv[r] * Lm[r, i]
                        ge[e, i] += w * s
                if want >= 2:
                    for r in range(8):
                        for i in range(nd):
                            s = 0.0
                            for r2 in range(8):
                                s += d2v[r, r2] * Lm[r2, i]
                            HL[r, i] = s
                    for i in range(nd):
                        for i2 in range(nd):
                            s = 0.0
                            for r in range(8):
                                s += Lm[r, i] * HL[r, i2]
                            He[e, i, i2] += w * s
    return V, ge, He


@njit(cache=True)
def scatter_vector(ve: np.ndarray, dofs: np.ndarray, coef: np.ndarray, factor: float, out: np.ndarray) -> np.ndarray:
    """``out += factor * sum_e P_e^T ve_e`` (``dofs`` -1: constrained; ``coef`` as in
    :func:`snapjump_kernels.harmonics.scatter_band`)."""
    ne, nd = dofs.shape
    for e in range(ne):
        for i in range(nd):
            d = dofs[e, i]
            if d >= 0:
                out[d] += factor * coef[e, i] * ve[e, i]
    return out
