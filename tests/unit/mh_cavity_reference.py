"""Test oracle: the cavity kernel that :mod:`snapjump_kernels.mh_cavity` replaced (its Hessian summed
over every phi point as ``L^T (d2v L)`` with the dense 8 x nd map ``L``), kept to check the
phi-moment form against. The cavity volume of the multi-harmonic surface: the exact 3D flux
``V = -1/2 int int (x, y, 0) . (x_s x x_phi) ds dphi`` (docs/harmonics.md, section 4), a cubic
polynomial of the amplitudes (:mod:`snapjump_kernels.mh_basis`), integrated exactly when the phi
rule has more than ``3 K_max / 2`` intervals, with its gradient and Hessian per edge.

"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.cavity import edge_shape
from snapjump_kernels.mh_basis import dof_offset
from snapjump_kernels.mh_cavity import _GP, _GW, _cavity_point


@njit(cache=True)
def mh_cavity_reference(X, A, edges, hn, phis, wphi, want):
    """:func:`snapjump_kernels.mh_cavity.mh_cavity` (the same arguments and results) as it was formed
    before: every phi point's dense ``L^T (d2v L)``."""
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
                        o = a * nc + dof_offset(k)
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
