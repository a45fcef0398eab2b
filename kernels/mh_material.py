"""The 3D Gent law of the multi-harmonic solid: the isochoric energy of a full 3D deformation
gradient (:func:`gent3`, on the scalars of :func:`snapjump_kernels.gent.gent_scalars`, shared with
the axisymmetric element) and of an imperfect body (:func:`imperfect_point`).

The gradient is the 9-vector of :mod:`snapjump_kernels.mh_basis`. JIT-compiled (not in the
ahead-of-time build). Arrays in, arrays out.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.gent import gent_scalars
from snapjump_kernels.mh_basis import COL, IDX, ROW


@njit(cache=True)
def gent3(v: np.ndarray, mu: float, jm: float, want: int, dpsi: np.ndarray, d2psi: np.ndarray, dJ: np.ndarray,
          d2J: np.ndarray) -> tuple:
    """Isochoric Gent energy of a full 3D deformation gradient (the 9-vector ``v``) with its first
    (``want >= 1``) and second (``want >= 2``) derivatives, and ``J`` with its derivatives.

    Returns ``(ok, psi, J)``; ``ok`` is False outside the Gent domain (or ``J <= 0``).
    """
    F = np.empty((3, 3))
    for c in range(9):
        F[ROW[c], COL[c]] = v[c]
    J = (F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]) - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
         + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]))
    # cofactor dJ/dF_iA
    for c in range(9):
        i = ROW[c]
        A = COL[c]
        i1 = (i + 1) % 3
        i2 = (i + 2) % 3
        A1 = (A + 1) % 3
        A2 = (A + 2) % 3
        dJ[c] = F[i1, A1] * F[i2, A2] - F[i1, A2] * F[i2, A1]
    if want >= 2:
        for c in range(9):
            i = ROW[c]
            A = COL[c]
            for d in range(9):
                j = ROW[d]
                B = COL[d]
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
        i = ROW[c]
        B = COL[c]
        s = 0.0
        for A in range(3):
            s += v[IDX[i, A]] * Fi[A, B]
        ve[c] = s
    ok, psi, J = gent3(ve, mu, jm, want, dpe, d2pe, dJe, d2Je)
    if not ok or Jimp <= 0.0:
        return False, 0.0, J
    # T[c, d] = delta(row c, row d) Fi[col d, col c] (dpsi_e is stale unless want >= 1: unused then)
    for d in range(9):
        j = ROW[d]
        A = COL[d]
        s1 = 0.0
        s2 = 0.0
        for B in range(3):
            c = IDX[j, B]
            s1 += dpe[c] * Fi[A, B]
            s2 += dJe[c] * Fi[A, B]
        dpsi[d] = Jimp * s1
        dJ[d] = Jimp * s2
    if want >= 2:
        for d in range(9):
            j = ROW[d]
            A = COL[d]
            for d2 in range(9):
                j2 = ROW[d2]
                A2 = COL[d2]
                s1 = 0.0
                s2 = 0.0
                for B in range(3):
                    c = IDX[j, B]
                    fa = Fi[A, B]
                    for B2 in range(3):
                        c2 = IDX[j2, B2]
                        f = fa * Fi[A2, B2]
                        s1 += d2pe[c, c2] * f
                        s2 += d2Je[c, c2] * f
                d2psi[d, d2] = Jimp * s1
                d2J[d, d2] = Jimp * s2
    return True, Jimp * psi, J
