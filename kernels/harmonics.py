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
Only ``B_f``'s ``c`` column and ``B_h``'s ``a`` and ``b`` columns carry ``n``, so the strain-energy
part is a quadratic polynomial in ``n`` (for fixed ``wc, ws``): :func:`harmonic_element_parts`
returns its three coefficients from one element pass, which serves every harmonic ``n >= 1``, and
:func:`scatter_harmonic` combines them for one ``n`` while scattering.

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
def harmonic_element_parts(U: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
                           kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
                           Np: np.ndarray, Minv: np.ndarray, wc: float, ws: float):
    """Element matrices of the strain-energy part of ``K_n`` (without the cavity load stiffness)
    as a polynomial in the harmonic number: ``Ke_n = Kp[0] + n Kp[1] + n^2 Kp[2]`` for every ``n``
    with these phi-averages (``wc = ws = 1/2`` for all ``n >= 1``), so one pass serves every
    harmonic (:func:`scatter_harmonic` combines and scatters them).

    ``B_f = B_f0 + n B_f1`` and ``B_h = B_h0 + n B_h1`` with, for node ``a`` (``bx, by = dN/dR,
    dN/dZ``, ``bn = N / R``; columns ``a, b, c``)::

        B_f0: a -> (bx, by, 0, 0, bn),  b -> (0, 0, bx, by, 0),   B_f1: c -> (0, 0, 0, 0, bn)
        B_h0: c -> (-bn, bx, by, 0),                              B_h1: a -> (-bn, 0, 0, 0),  b -> (0, 0, 0, -bn)

    so that (``D_f``, ``D_h`` symmetric) the ``(a, b) x (a, b)`` and ``c x c`` entries of ``K_n``
    are ``n^0 + n^2`` terms and the ``(a, b) x c`` entries ``n^1`` terms; the dilatation row
    ``G = G_0 + n G_1`` (``G_1`` on the ``c`` columns) splits the same way.

    Parameters
    ----------
    U : (nn, 2) nodal displacements of the axisymmetric state (scaled)
    conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv : as in
        :func:`snapjump_kernels.assembly.assemble`
    wc, ws : phi-averages of ``cos^2 n phi`` and ``sin^2 n phi`` (1/2, 1/2 for ``n >= 1``; 1, 1 for
        ``n = 0``)

    Returns
    -------
    (Kp, ok) : (3, ne, 3 nen, 3 nen) symmetric coefficient matrices of ``n^0, n^1, n^2``; ``ok``
        False if a quadrature point lies outside the Gent domain
    """
    ne, nen = conn.shape
    nq = Wq.shape[1]
    npr = Np.shape[1]
    nd = 3 * nen
    Kp = np.zeros((3, ne, nd, nd))
    f = np.empty(5)
    dpsi = np.zeros((nq, 5))
    d2psi = np.zeros((nq, 5, 5))
    dJq = np.zeros((nq, 5))
    d2Jq = np.zeros((nq, 5, 5))
    fq = np.zeros((nq, 5))
    psi_hh = np.empty((4, 4))
    J_hh = np.empty((4, 4))
    DfU = np.empty((nen, 5))
    DfV = np.empty((nen, 5))
    DhS = np.empty((nen, 4))
    G = np.empty((npr, nd))
    H = np.empty((npr, nd))
    g = np.empty(npr)
    pb = np.empty(npr)
    Df = np.empty((5, 5))
    Dh = np.empty((4, 4))
    K0 = np.empty((nd, nd))
    K1 = np.empty((nd, nd))
    K2 = np.empty((nd, nd))
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
                return Kp, False
            for k in range(npr):
                g[k] += Wq[e, q] * Np[q, k] * (J - 1.0)
        for k in range(npr):
            s = 0.0
            for m in range(npr):
                s += Minv[e, k, m] * g[m]
            pb[k] = ka * s
        G[:, :] = 0.0
        K0[:, :] = 0.0
        K1[:, :] = 0.0
        K2[:, :] = 0.0
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
                return Kp, False
            for k in range(4):
                for m in range(4):
                    Dh[k, m] = ws * W * (psi_hh[k, m] + pq * J_hh[k, m])
            R = Rq[e, q]
            dN = dNdX[e, q]
            # D B_0 of every node: D_f times the a and b columns of B_f0, D_h times the c column of B_h0
            for b in range(nen):
                bx = dN[b, 0]
                by = dN[b, 1]
                bn = N_ref[q, b] / R
                for k in range(5):
                    DfU[b, k] = Df[k, 0] * bx + Df[k, 1] * by + Df[k, 4] * bn
                    DfV[b, k] = Df[k, 2] * bx + Df[k, 3] * by
                for k in range(4):
                    DhS[b, k] = -Dh[k, 0] * bn + Dh[k, 1] * bx + Dh[k, 2] * by
            f44 = Df[4, 4]
            h00 = Dh[0, 0]
            h03 = Dh[0, 3]
            h33 = Dh[3, 3]
            # lower node blocks (b <= a) of the three coefficient matrices
            for a in range(nen):
                bxa = dN[a, 0]
                bya = dN[a, 1]
                bna = N_ref[q, a] / R
                ia = 3 * a
                for b in range(a + 1):
                    jb = 3 * b
                    bnb = N_ref[q, b] / R
                    K0[ia, jb] += bxa * DfU[b, 0] + bya * DfU[b, 1] + bna * DfU[b, 4]
                    K0[ia, jb + 1] += bxa * DfV[b, 0] + bya * DfV[b, 1] + bna * DfV[b, 4]
                    K0[ia + 1, jb] += bxa * DfU[b, 2] + bya * DfU[b, 3]
                    K0[ia + 1, jb + 1] += bxa * DfV[b, 2] + bya * DfV[b, 3]
                    K0[ia + 2, jb + 2] += -bna * DhS[b, 0] + bxa * DhS[b, 1] + bya * DhS[b, 2]
                    K1[ia, jb + 2] += bnb * DfU[a, 4] - bna * DhS[b, 0]
                    K1[ia + 1, jb + 2] += bnb * DfV[a, 4] - bna * DhS[b, 3]
                    K1[ia + 2, jb] += bna * DfU[b, 4] - bnb * DhS[a, 0]
                    K1[ia + 2, jb + 1] += bna * DfV[b, 4] - bnb * DhS[a, 3]
                    nn_ = bna * bnb
                    K2[ia, jb] += nn_ * h00
                    K2[ia, jb + 1] += nn_ * h03
                    K2[ia + 1, jb] += nn_ * h03
                    K2[ia + 1, jb + 1] += nn_ * h33
                    K2[ia + 2, jb + 2] += nn_ * f44
            # dilatation constraint: G_k = sum_q W Np_qk dJ/df B_f (the c columns: G_1)
            dJ = dJq[q]
            for a in range(nen):
                bx = dN[a, 0]
                by = dN[a, 1]
                bn = N_ref[q, a] / R
                ga = dJ[0] * bx + dJ[1] * by + dJ[4] * bn
                gb = dJ[2] * bx + dJ[3] * by
                gc = dJ[4] * bn
                for k in range(npr):
                    wk = W * Np[q, k]
                    G[k, 3 * a] += wk * ga
                    G[k, 3 * a + 1] += wk * gb
                    G[k, 3 * a + 2] += wk * gc
        # wc kappa G^T M^-1 G: (a, b) x (a, b) -> n^0, (a, b) x c -> n^1, c x c -> n^2
        for k in range(npr):
            for j in range(nd):
                s = 0.0
                for m in range(npr):
                    s += Minv[e, k, m] * G[m, j]
                H[k, j] = wc * ka * s
        for i in range(nd):
            ci = i % 3 == 2
            for j in range(3 * (i // 3 + 1)):
                s = 0.0
                for k in range(npr):
                    s += G[k, i] * H[k, j]
                cj = j % 3 == 2
                if ci and cj:
                    K2[i, j] += s
                elif ci or cj:
                    K1[i, j] += s
                else:
                    K0[i, j] += s
        # mirror the lower node blocks (the diagonal blocks are full: symmetric already)
        for i in range(nd):
            for j in range(3 * (i // 3 + 1)):
                Kp[0, e, i, j] = K0[i, j]
                Kp[0, e, j, i] = K0[i, j]
                Kp[1, e, i, j] = K1[i, j]
                Kp[1, e, j, i] = K1[i, j]
                Kp[2, e, i, j] = K2[i, j]
                Kp[2, e, j, i] = K2[i, j]
    return Kp, True


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
    n, wc, ws : harmonic and phi-averages, as in :func:`harmonic_element_parts`

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


@njit(cache=True)
def scatter_harmonic(Kp: np.ndarray, n: float, dofs: np.ndarray, coef: np.ndarray, ab: np.ndarray) -> np.ndarray:
    """``ab += sum_e P_e^T (Kp[0, e] + n Kp[1, e] + n^2 Kp[2, e]) P_e``: the element matrices of
    harmonic ``n`` (:func:`harmonic_element_parts`), combined and scattered as :func:`scatter_band`
    scatters (the same dof maps, coefficients and band storage)."""
    ne, nd = dofs.shape
    n2 = n * n
    for e in range(ne):
        for i in range(nd):
            di = dofs[e, i]
            if di < 0:
                continue
            ci = coef[e, i]
            for j in range(nd):
                dj = dofs[e, j]
                if dj < 0 or dj > di:
                    continue
                ab[dj, di - dj] += ci * coef[e, j] * (Kp[0, e, i, j] + n * Kp[1, e, i, j] + n2 * Kp[2, e, i, j])
    return ab
