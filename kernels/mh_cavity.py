"""The cavity volume of the multi-harmonic surface: the exact 3D flux
``V = -1/2 int int (x, y, 0) . (x_s x x_phi) ds dphi`` (docs/harmonics.md, section 4), a cubic
polynomial of the amplitudes (:mod:`snapjump_kernels.mh_basis`), integrated exactly when the phi
rule has more than ``3 K_max / 2`` intervals, with its gradient and Hessian per edge.

Each of the integrand's eight arguments ``y_r`` (:func:`_cavity_point`) is, in the amplitudes of
an edge, a sum over nodes and harmonics of ``S_r(node) T_r(k, phi) A[node, k, c_r]``: a shape
value (``N`` or ``dN/ds``) times a trigonometric factor, on one component ``c_r``. The gradient
and the Hessian are therefore formed from their phi-moments, ``sum_j w_j dv_r(phi_j) T_r(k, phi_j)``
and ``sum_j w_j d2v_rs(phi_j) T_r(k, phi_j) T_s(l, phi_j)`` for the non-zero ``d2v_rs`` only, and
spread over the nodes once per Gauss point (the Hessian of every phi point as a dense
``L^T d2v L``, the form this replaced, cost ~15x the flops; ``tests/unit/mh_cavity_reference.py``).

JIT-compiled (not in the ahead-of-time build). Arrays in, arrays out.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.cavity import edge_shape
from snapjump_kernels.mh_basis import dof_offset

_GP = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GW = np.array([5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0])


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


#: the component (a, b, c) that each argument ``y_r`` of :func:`_cavity_point` depends on, and
#: whether its shape value is ``N`` (0) or ``dN/ds`` (1)
_COMP = np.array([0, 0, 0, 2, 2, 2, 1, 1])
_SHAPE = np.array([0, 1, 0, 0, 1, 0, 1, 0])
#: the non-zero entries ``(r, s)`` of the integrand's Hessian (:func:`_cavity_point`), both orders
_PAIRS = np.array([(0, 0), (3, 3), (0, 4), (4, 0), (0, 7), (7, 0), (0, 6), (6, 0), (0, 5), (5, 0), (1, 3), (3, 1),
                   (1, 7), (7, 1), (2, 3), (3, 2), (2, 6), (6, 2), (3, 6), (6, 3), (3, 7), (7, 3), (4, 7), (7, 4),
                   (5, 6), (6, 5)], dtype=np.int64)


@njit(cache=True)
def _trig_factors(hn: np.ndarray, phis: np.ndarray) -> np.ndarray:
    """``T[r, j, k]``: the factor of harmonic ``k`` at ``phi_j`` in the argument ``y_r``: ``cos``,
    ``cos``, ``-n sin``, ``sin``, ``sin``, ``n cos``, ``cos``, ``-n sin`` for ``r = 0..7``."""
    K, nphi = hn.shape[0], phis.shape[0]
    T = np.empty((8, nphi, K))
    for j in range(nphi):
        for k in range(K):
            n = float(hn[k])
            cs = np.cos(n * phis[j])
            sn = np.sin(n * phis[j])
            T[0, j, k] = cs
            T[1, j, k] = cs
            T[2, j, k] = -n * sn
            T[3, j, k] = sn
            T[4, j, k] = sn
            T[5, j, k] = n * cs
            T[6, j, k] = cs
            T[7, j, k] = -n * sn
    return T


@njit(cache=True)
def mh_cavity(X: np.ndarray, A: np.ndarray, edges: np.ndarray, hn: np.ndarray, phis: np.ndarray,
              wphi: np.ndarray, want: int):
    """The cavity volume of the multi-harmonic surface (the 3D flux, without the offset) with its
    gradient and Hessian per edge in the edge dofs ``(node, component)`` of the layout.

    Parameters
    ----------
    X : (nn, 2) reference positions (scaled); A : (nn, nc) amplitudes; edges : (m, 2|3) oriented
        cavity edges as in :mod:`snapjump_kernels.cavity`; hn, phis, wphi : as in :func:`snapjump_kernels.mh_element.mh_elements`

    Returns
    -------
    (V, ge, He) : the volume, (m, nen nc) gradients, (m, nen nc, nen nc) Hessians (``want``: 0, 1, 2)
    """
    m, nen = edges.shape
    K = hn.shape[0]
    nc = 2 + 3 * (K - 1)
    nd = nen * nc
    nphi = phis.shape[0]
    npair = _PAIRS.shape[0]
    ge = np.zeros((m, nd))
    He = np.zeros((m, nd, nd)) if want >= 2 else np.zeros((0, nd, nd))
    T = _trig_factors(hn, phis)
    N = np.empty(nen)
    dN = np.empty(nen)
    Sh = np.empty((2, nen))  # the shape values N, dN/ds of the nodes
    y = np.empty(8)
    dv = np.empty(8)
    d2v = np.empty((8, 8))
    Ae = np.zeros((8, nen, K))  # the amplitude of argument r's component, per node and harmonic
    Yk = np.empty((8, K))  # sum over the nodes of S_r(node) A[node, k, c_r]
    gm = np.empty((8, K))  # the gradient's phi-moments
    Hm = np.empty((npair, K, K))  # the Hessian's phi-moments
    V = 0.0
    for e in range(m):
        for r in range(8):
            c = _COMP[r]
            for a in range(nen):
                node = edges[e, a]
                for k in range(K):
                    Ae[r, a, k] = A[node, dof_offset(k) + c] if (c < 2 or k > 0) else 0.0
        for q in range(3):
            edge_shape(_GP[q], nen, N, dN)
            for a in range(nen):
                Sh[0, a] = N[a]
                Sh[1, a] = dN[a]
            y0 = 0.0
            y1 = 0.0
            y6 = 0.0
            for a in range(nen):
                node = edges[e, a]
                y0 += N[a] * X[node, 0]
                y1 += dN[a] * X[node, 0]
                y6 += dN[a] * X[node, 1]
            for r in range(8):
                sr = Sh[_SHAPE[r]]
                for k in range(K):
                    s = 0.0
                    for a in range(nen):
                        s += sr[a] * Ae[r, a, k]
                    Yk[r, k] = s
            if want >= 1:
                gm[:, :] = 0.0
            if want >= 2:
                Hm[:, :, :] = 0.0
            for j in range(nphi):
                w = 2.0 * np.pi * _GW[q] * wphi[j]
                for r in range(8):
                    s = 0.0
                    for k in range(K):
                        s += T[r, j, k] * Yk[r, k]
                    y[r] = s
                y[0] += y0
                y[1] += y1
                y[6] += y6
                V += w * _cavity_point(y, want, dv, d2v)
                if want >= 1:
                    for r in range(8):
                        wd = w * dv[r]
                        for k in range(K):
                            gm[r, k] += wd * T[r, j, k]
                if want >= 2:
                    for pp in range(npair):
                        r = _PAIRS[pp, 0]
                        r2 = _PAIRS[pp, 1]
                        wd = w * d2v[r, r2]
                        for k in range(K):
                            wk = wd * T[r, j, k]
                            for l in range(K):
                                Hm[pp, k, l] += wk * T[r2, j, l]
            if want >= 1:
                for r in range(8):
                    c = _COMP[r]
                    sr = Sh[_SHAPE[r]]
                    for a in range(nen):
                        for k in range(K):
                            if c < 2 or k > 0:
                                ge[e, a * nc + dof_offset(k) + c] += sr[a] * gm[r, k]
            if want >= 2:
                for pp in range(npair):
                    r = _PAIRS[pp, 0]
                    r2 = _PAIRS[pp, 1]
                    c = _COMP[r]
                    c2 = _COMP[r2]
                    sr = Sh[_SHAPE[r]]
                    sr2 = Sh[_SHAPE[r2]]
                    for a in range(nen):
                        for b in range(nen):
                            f = sr[a] * sr2[b]
                            for k in range(K):
                                if c == 2 and k == 0:
                                    continue
                                i = a * nc + dof_offset(k) + c
                                for l in range(K):
                                    if c2 == 2 and l == 0:
                                        continue
                                    He[e, i, b * nc + dof_offset(l) + c2] += f * Hm[pp, k, l]
    return V, ge, He
