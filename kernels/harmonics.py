"""Fourier-harmonic tangent of the axisymmetric mixed Gent solid (semi-analytical FE, docs/harmonics.md).

At an axisymmetric state ``(u, p)`` the perturbation of harmonic ``n``::

    u_r = a(R, Z) cos n phi,   u_z = b(R, Z) cos n phi,   u_phi = c(R, Z) sin n phi

(three amplitudes per node, element dof order ``[a_0, b_0, c_0, a_1, ...]``) changes the nine
components of the 3D deformation gradient (rows r, phi, z; columns R, Phi, Z) by::

    cos n phi * df,  df = [a_R, a_Z, b_R, b_Z, (a + n c) / R]      (F_rR, F_rZ, F_zR, F_zZ, F_phiPhi)
    sin n phi * dh,  dh = [-(n a + c) / R, c_R, c_Z, -n b / R]     (F_rPhi, F_phiR, F_phiZ, F_zPhi)

The shear components ``h`` vanish in the axisymmetric state and the energy is even in them, so
``d2psi/df dh = 0`` there and the phi-average of the second variation splits into a ``cos^2`` part
(the axisymmetric five-component Hessian, exactly as in :mod:`snapjump_kernels.assembly`) and a
``sin^2`` part (the Hessian in ``h``). With the phi-averages ``wc = <cos^2>``, ``ws = <sin^2>``
(1/2 each for ``n >= 1``; 1 and 1 for ``n = 0``, where ``c`` is the torsion ``u_phi = c``), the
matrix returned is the exact second derivative of the 3D potential ``Pi = W - p V`` with respect
to the amplitudes::

    K_n = wc [sum_q B_f^T D_f B_f + kappa G^T M^-1 G]  +  ws sum_q B_h^T D_h B_h  -  p H_V,
    D_f = W_q (psi_ff + p_q J_ff),   D_h = W_q (psi_hh + p_q J_hh),
    G_k = sum_q W_q Np_qk dJ/df B_f,   p_q = kappa Np_q M^-1 g(u)

(the pressure/dilatation fields of the element are ``Np(R, Z)`` times any function of phi, so the
elimination holds at every phi; only their ``cos n phi`` part couples to harmonic ``n``).
``H_V`` is the Hessian of the cavity volume for harmonic ``n`` (:func:`harmonic_cavity_matrices`).

Arrays in, arrays out; no Python objects.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.kinematics import deformation
from snapjump_kernels.cavity import edge_shape
from snapjump_kernels.gent import gent_iso

_GP = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GW = np.array([5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0])


@njit(cache=True)
def shear_hessians(f: np.ndarray, mu: float, jm: float, psi_hh: np.ndarray, J_hh: np.ndarray) -> bool:
    """Hessians of the isochoric Gent energy and of ``J = det F`` in the four shear components
    ``h = [F_rPhi, F_phiR, F_phiZ, F_zPhi]`` at ``h = 0`` (an axisymmetric ``f``, as in
    :mod:`snapjump_kernels.gent`).

    With ``F = [[f0, h0, f1], [h1, f4, h2], [f2, h3, f3]]``, ``J`` is even in ``h``: ``dJ/dh = 0``
    and the only non-zero second derivatives are ``J_{h2 h3} = -f0``, ``J_{h0 h1} = -f3``,
    ``J_{h0 h2} = f2``, ``J_{h1 h3} = f1``. Hence ``dIbar/dh = 0`` and
    ``psi_hh = psi'(Ibar) (2 J^(-2/3) I - (2/3) J^(-5/3) I_1 J_hh)``.

    Returns False outside the Gent domain.
    """
    J_hh[:, :] = 0.0
    J_hh[2, 3] = J_hh[3, 2] = -f[0]
    J_hh[0, 1] = J_hh[1, 0] = -f[3]
    J_hh[0, 2] = J_hh[2, 0] = f[2]
    J_hh[1, 3] = J_hh[3, 1] = f[1]
    J = (f[0] * f[3] - f[1] * f[2]) * f[4]
    if J <= 0.0:
        return False
    I1 = 0.0
    for k in range(5):
        I1 += f[k] * f[k]
    c = J ** (-2.0 / 3.0)
    arg = 1.0 - (c * I1 - 3.0) / jm
    if arg <= 0.0:
        return False
    a = 0.5 * mu / arg
    cJ = (2.0 / 3.0) * c / J
    for k in range(4):
        for m in range(4):
            v = -cJ * I1 * J_hh[k, m]
            if k == m:
                v += 2.0 * c
            psi_hh[k, m] = a * v
    return True


@njit(cache=True)
def _node_b(dNdX_eq, N_q, R_q, n, bf):
    """The non-zero entries of ``B_f`` (5 x 3) and ``B_h`` (4 x 3) of every node at one point,
    ``bf[a] = [bx, by, bn, n bn]`` with ``bx, by = dN/dR, dN/dZ`` and ``bn = N / R``. Columns
    (a, b, c) of node a::

        B_f: a -> (bx, by, 0, 0, bn),  b -> (0, 0, bx, by, 0),  c -> (0, 0, 0, 0, n bn)
        B_h: a -> (-n bn, 0, 0, 0),    b -> (0, 0, 0, -n bn),   c -> (-bn, bx, by, 0)
    """
    for a in range(dNdX_eq.shape[0]):
        bf[a, 0] = dNdX_eq[a, 0]
        bf[a, 1] = dNdX_eq[a, 1]
        bf[a, 2] = N_q[a] / R_q
        bf[a, 3] = n * bf[a, 2]


@njit(cache=True)
def _db_f(D, bx, by, bn, nbn, out):
    """``out (5, 3) = D (5x5) @ B_f`` of one node."""
    for k in range(5):
        out[k, 0] = D[k, 0] * bx + D[k, 1] * by + D[k, 4] * bn
        out[k, 1] = D[k, 2] * bx + D[k, 3] * by
        out[k, 2] = D[k, 4] * nbn


@njit(cache=True)
def _db_h(D, bx, by, bn, nbn, out):
    """``out (4, 3) = D (4x4) @ B_h`` of one node."""
    for k in range(4):
        out[k, 0] = -D[k, 0] * nbn
        out[k, 1] = -D[k, 3] * nbn
        out[k, 2] = -D[k, 0] * bn + D[k, 1] * bx + D[k, 2] * by


@njit(cache=True)
def harmonic_element_matrices(U: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
                              kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
                              Np: np.ndarray, Minv: np.ndarray, n: int, wc: float, ws: float):
    """Element matrices of the strain-energy part of ``K_n`` (without the cavity load stiffness).

    Parameters
    ----------
    U : (nn, 2) nodal displacements of the axisymmetric state (scaled)
    conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv : as in
        :func:`snapjump_kernels.assembly.assemble`
    n : harmonic number (>= 0)
    wc, ws : phi-averages of ``cos^2 n phi`` and ``sin^2 n phi`` (1/2, 1/2 for ``n >= 1``)

    Returns
    -------
    (Ke, ok) : (ne, 3 nen, 3 nen) symmetric element matrices; ``ok`` False if a quadrature point
        lies outside the Gent domain
    """
    ne, nen = conn.shape
    nq = Wq.shape[1]
    npr = Np.shape[1]
    nd = 3 * nen
    fn = float(n)
    Ke = np.zeros((ne, nd, nd))
    f = np.empty(5)
    dpsi = np.zeros((nq, 5))
    d2psi = np.zeros((nq, 5, 5))
    dJq = np.zeros((nq, 5))
    d2Jq = np.zeros((nq, 5, 5))
    fq = np.zeros((nq, 5))
    psi_hh = np.empty((4, 4))
    J_hh = np.empty((4, 4))
    bf = np.empty((nen, 4))
    DBf = np.empty((nen, 5, 3))
    DBh = np.empty((nen, 4, 3))
    G = np.empty((npr, nd))
    H = np.empty((npr, nd))
    g = np.empty(npr)
    pb = np.empty(npr)
    Df = np.empty((5, 5))
    Dh = np.empty((4, 4))
    K = np.empty((nd, nd))
    for e in range(ne):
        m_ = mat[e]
        mu_e = mu[m_]
        jm_e = jm[m_]
        ka = kappa[m_]
        g[:] = 0.0
        for q in range(nq):
            # the axisymmetric deformation gradient f = [F_rR, F_rZ, F_zR, F_zZ, F_phiPhi]
            deformation(U, conn[e], dNdX[e, q], N_ref[q], Rq[e, q], f)
            for k in range(5):
                fq[q, k] = f[k]
            ok, psi, J = gent_iso(f, mu_e, jm_e, 2, dpsi[q], d2psi[q], dJq[q], d2Jq[q])
            if not ok:
                return Ke, False
            for k in range(npr):
                g[k] += Wq[e, q] * Np[q, k] * (J - 1.0)
        for k in range(npr):
            s = 0.0
            for m in range(npr):
                s += Minv[e, k, m] * g[m]
            pb[k] = ka * s
        G[:, :] = 0.0
        K[:, :] = 0.0
        for q in range(nq):
            W = Wq[e, q]
            pq = 0.0
            for k in range(npr):
                pq += Np[q, k] * pb[k]
            # cos^2 part: the axisymmetric Hessian in f with the element pressure;
            # sin^2 part: the Hessian in the shear components
            for k in range(5):
                for m in range(5):
                    Df[k, m] = wc * W * (d2psi[q, k, m] + pq * d2Jq[q, k, m])
            if not shear_hessians(fq[q], mu_e, jm_e, psi_hh, J_hh):
                return Ke, False
            for k in range(4):
                for m in range(4):
                    Dh[k, m] = ws * W * (psi_hh[k, m] + pq * J_hh[k, m])
            _node_b(dNdX[e, q], N_ref[q], Rq[e, q], fn, bf)
            for b in range(nen):
                _db_f(Df, bf[b, 0], bf[b, 1], bf[b, 2], bf[b, 3], DBf[b])
                _db_h(Dh, bf[b, 0], bf[b, 1], bf[b, 2], bf[b, 3], DBh[b])
            # lower node blocks: K_ab += B_f,a^T (D_f B_f,b) + B_h,a^T (D_h B_h,b)
            for a in range(nen):
                bx = bf[a, 0]
                by = bf[a, 1]
                bn = bf[a, 2]
                nbn = bf[a, 3]
                ia = 3 * a
                for b in range(a + 1):
                    jb = 3 * b
                    for c in range(3):
                        F = DBf[b, :, c]
                        Hh = DBh[b, :, c]
                        K[ia, jb + c] += bx * F[0] + by * F[1] + bn * F[4] - nbn * Hh[0]
                        K[ia + 1, jb + c] += bx * F[2] + by * F[3] - nbn * Hh[3]
                        K[ia + 2, jb + c] += nbn * F[4] - bn * Hh[0] + bx * Hh[1] + by * Hh[2]
            # dilatation constraint: G_k = sum_q W Np_qk dJ/df B_f
            dJ = dJq[q]
            for a in range(nen):
                ga = dJ[0] * bf[a, 0] + dJ[1] * bf[a, 1] + dJ[4] * bf[a, 2]
                gb = dJ[2] * bf[a, 0] + dJ[3] * bf[a, 1]
                gc = dJ[4] * bf[a, 3]
                for k in range(npr):
                    wk = W * Np[q, k]
                    G[k, 3 * a] += wk * ga
                    G[k, 3 * a + 1] += wk * gb
                    G[k, 3 * a + 2] += wk * gc
        # wc kappa G^T M^-1 G
        for k in range(npr):
            for j in range(nd):
                s = 0.0
                for m in range(npr):
                    s += Minv[e, k, m] * G[m, j]
                H[k, j] = wc * ka * s
        for i in range(nd):
            for j in range(3 * (i // 3 + 1)):
                s = 0.0
                for k in range(npr):
                    s += G[k, i] * H[k, j]
                K[i, j] += s
        # mirror the lower node blocks (the diagonal blocks are full: symmetric already)
        for i in range(nd):
            for j in range(3 * (i // 3 + 1)):
                Ke[e, i, j] = K[i, j]
                Ke[e, j, i] = K[i, j]
    return Ke, True


@njit(cache=True)
def harmonic_cavity_matrices(x: np.ndarray, edges: np.ndarray, n: float, wc: float, ws: float) -> np.ndarray:
    """Hessians ``H_V`` of the cavity volume for harmonic ``n``, one per cavity edge.

    The volume of the perturbed surface of revolution ``x(s, phi)`` is the flux
    ``V = -1/2 int int (x, y, 0) . (x_s x x_phi) ds dphi`` (it reduces to ``pi int r^2 dz`` of
    :mod:`snapjump_kernels.cavity` for an axisymmetric surface, with the same edge orientation).
    Its first variation is ``proportional to cos n phi`` and integrates to zero for ``n >= 1``; its
    second variation is (``a, b, c`` the amplitudes along the edge, ``r, z`` the current surface)::

        d2V/de2 = 2 pi int [ wc (a^2 z' + 2 r a b' + n a c z' + n r c b')
                           + ws (c^2 z' + n a c z' + n r b c' - n b c r') ] ds

    Parameters
    ----------
    x : (nn, 2) current node positions (scaled); edges : (m, 2|3) oriented cavity edges
    n, wc, ws : harmonic and phi-averages, as in :func:`harmonic_element_matrices`

    Returns
    -------
    He : (m, 3 nen, 3 nen) symmetric, in the edge's dof order ``[a_0, b_0, c_0, a_1, ...]``
    """
    m, nen = edges.shape
    nd = 3 * nen
    He = np.zeros((m, nd, nd))
    N = np.empty(nen)
    dN = np.empty(nen)
    for e in range(m):
        for q in range(3):
            edge_shape(_GP[q], nen, N, dN)
            r = 0.0
            rs = 0.0
            zs = 0.0
            for a in range(nen):
                r += N[a] * x[edges[e, a], 0]
                rs += dN[a] * x[edges[e, a], 0]
                zs += dN[a] * x[edges[e, a], 1]
            w = 2.0 * np.pi * _GW[q]
            for i in range(nen):
                ia = 3 * i
                for j in range(nen):
                    ja = 3 * j
                    NN = N[i] * N[j]
                    # a a and c c
                    He[e, ia, ja] += w * wc * zs * NN
                    He[e, ia + 2, ja + 2] += w * ws * zs * NN
                    # a b: 2 r a b'
                    t = w * wc * r * N[i] * dN[j]
                    He[e, ia, ja + 1] += t
                    He[e, ja + 1, ia] += t
                    # a c: (wc + ws) n z' a c
                    t = 0.5 * w * (wc + ws) * n * zs * NN
                    He[e, ia, ja + 2] += t
                    He[e, ja + 2, ia] += t
                    # c_i b_j: wc n r c b'
                    t = 0.5 * w * wc * n * r * N[i] * dN[j]
                    He[e, ia + 2, ja + 1] += t
                    He[e, ja + 1, ia + 2] += t
                    # b_i c_j: ws n (r b c' - r' b c)
                    t = 0.5 * w * ws * n * (r * N[i] * dN[j] - rs * NN)
                    He[e, ia + 1, ja + 2] += t
                    He[e, ja + 2, ia + 1] += t
    return He


@njit(cache=True)
def scatter_band(Me: np.ndarray, dofs: np.ndarray, coef: np.ndarray, factor: float, ab: np.ndarray) -> np.ndarray:
    """``ab += factor * sum_e P_e^T Me_e P_e`` into the lower band storage of
    :mod:`snapjump_kernels.banded` (``A[i, j] = ab[j, i - j]``).

    ``dofs[e, i]`` is the global dof of element dof ``i`` (-1: constrained to zero) and
    ``coef[e, i]`` its coefficient (an axis node of harmonic 1 carries ``c = -a``: its ``c`` dof
    maps to the ``a`` dof with coefficient -1). Entries that land above the diagonal are dropped
    (their transposes are stored); two element dofs sharing a global dof add both cross terms to
    the diagonal, as they must. The caller sizes ``ab`` to hold every ``i - j`` that occurs.
    """
    ne, nd = dofs.shape
    for e in range(ne):
        for i in range(nd):
            di = dofs[e, i]
            if di < 0:
                continue
            ci = coef[e, i] * factor
            for j in range(nd):
                dj = dofs[e, j]
                if dj < 0 or dj > di:
                    continue
                ab[dj, di - dj] += ci * coef[e, j] * Me[e, i, j]
    return ab
