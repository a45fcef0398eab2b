"""The multi-harmonic (Fourier) displacement: its layout, phi rule and gradients.

The displacement of the 2D mesh's solid of revolution is a truncated Fourier series in the
circumferential angle phi, in the subspace that is mirror-symmetric about ``phi = 0``::

    u_r = sum_k a_k(R, Z) cos n_k phi,   u_z = sum_k b_k(R, Z) cos n_k phi,
    u_phi = sum_{k >= 1} c_k(R, Z) sin n_k phi,                 (n_0 = 0: no torsion)

with the harmonics ``n_k`` of ``hn`` (``hn[0] = 0``). The nodal unknowns are stored node by node,
``[a_0, b_0, a_1, b_1, c_1, a_2, ...]`` (``nc = 2 + 3 (K - 1)`` per node, ``K = len(hn)``;
:func:`dof_offset`, :func:`harmonic_ndof`).

The full 3D deformation gradient (rows r, phi, z; columns R, Phi, Z) at ``phi`` is::

    F = | 1 + u_r,R             (u_r,phi - u_phi) / R          u_r,Z     |
        | u_phi,R               1 + (u_r + u_phi,phi) / R      u_phi,Z   |
        | u_z,R                 u_z,phi / R                    1 + u_z,Z |

stored as the 9-vector ``v = [F_rR, F_rZ, F_zR, F_zZ, F_phiPhi | F_rPhi, F_phiR, F_phiZ, F_zPhi]``
(:data:`ROW`, :data:`COL`, :data:`IDX`): the first five carry ``cos n phi`` (the axisymmetric
components of :mod:`snapjump_kernels.gent`), the last four ``sin n phi``. A node's B matrix
(:func:`node_b`) maps its amplitudes of one harmonic to these components.

The other modules of the multi-harmonic solid: :mod:`snapjump_kernels.mh_material` (the 3D Gent
law), :mod:`snapjump_kernels.mh_element` (energy, residual and tangent of the elements),
:mod:`snapjump_kernels.mh_cavity` (the exact 3D cavity volume). JIT-compiled (not in the
ahead-of-time build). Arrays in, arrays out.
"""
from __future__ import annotations

import numpy as np
from numba import njit

# (row, column) of each of the 9 components in the 3x3 matrix
ROW = np.array([0, 0, 2, 2, 1, 0, 1, 1, 2])
COL = np.array([0, 2, 0, 2, 1, 1, 0, 2, 1])
# component of each (row, column) of the 3x3 matrix
IDX = np.array([[0, 5, 1], [6, 4, 7], [2, 8, 3]])


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
def dof_offset(k: int) -> int:
    return 0 if k == 0 else 2 + 3 * (k - 1)


@njit(cache=True)
def harmonic_ndof(k: int) -> int:
    return 2 if k == 0 else 3


@njit(cache=True)
def node_b(bx: float, by: float, bn: float, n: float, B: np.ndarray) -> None:
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
            o = dof_offset(k)
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
    ``(ne, nq, nphi, 3, 3)`` (rows r, phi, z; columns R, Phi, Z), as :func:`snapjump_kernels.mh_element.mh_elements` forms it."""
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
                    out[e, q, j, ROW[c], COL[c]] = s
                out[e, q, j, 0, 0] += 1.0
                out[e, q, j, 1, 1] += 1.0
                out[e, q, j, 2, 2] += 1.0
    return out
