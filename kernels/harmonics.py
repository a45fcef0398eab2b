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


@njit(cache=True, inline="always")
def _put(Kp, k, e, i, j, v):
    """``Kp[k, e, i, j] = Kp[k, e, j, i] = v``."""
    Kp[k, e, i, j] = v
    Kp[k, e, j, i] = v


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
    bx = np.empty(nen)
    by = np.empty(nen)
    bn = np.empty(nen)
    DfU = np.empty((5, nen))  # D_f times the a column of B_f0, per node
    DfV = np.empty((5, nen))  # D_f times the b column of B_f0
    DhS = np.empty((4, nen))  # D_h times the c column of B_h0
    Gc = np.empty((3, npr, nen))  # G's a, b and c columns (the c column: G_1)
    Hc = np.empty((3, npr, nen))  # wc kappa M^-1 G
    g = np.empty(npr)
    pb = np.empty(npr)
    Df = np.empty((5, 5))
    Dh = np.empty((4, 4))
    # the blocks (node x node) of the three coefficient matrices: n^0: aa, ab, bb, cc; n^1: ac, bc;
    # n^2: aa, ab, bb, cc (the blocks ba, ca, cb are transposes: D_f, D_h and M^-1 are symmetric)
    acc = np.empty((10, nen, nen))
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
        Gc[:, :, :] = 0.0
        acc[:, :, :] = 0.0
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
            for b in range(nen):
                bx[b] = dNdX[e, q, b, 0]
                by[b] = dNdX[e, q, b, 1]
                bn[b] = N_ref[q, b] / R
            for k in range(5):
                for b in range(nen):
                    DfU[k, b] = Df[k, 0] * bx[b] + Df[k, 1] * by[b] + Df[k, 4] * bn[b]
                    DfV[k, b] = Df[k, 2] * bx[b] + Df[k, 3] * by[b]
            for k in range(4):
                for b in range(nen):
                    DhS[k, b] = -Dh[k, 0] * bn[b] + Dh[k, 1] * bx[b] + Dh[k, 2] * by[b]
            f44 = Df[4, 4]
            h00 = Dh[0, 0]
            h03 = Dh[0, 3]
            h33 = Dh[3, 3]
            for a in range(nen):
                bxa = bx[a]
                bya = by[a]
                bna = bn[a]
                ua4 = DfU[4, a]
                va4 = DfV[4, a]
                for b in range(nen):  # contiguous: vectorised
                    acc[0, a, b] += bxa * DfU[0, b] + bya * DfU[1, b] + bna * DfU[4, b]
                    acc[1, a, b] += bxa * DfV[0, b] + bya * DfV[1, b] + bna * DfV[4, b]
                    acc[2, a, b] += bxa * DfV[2, b] + bya * DfV[3, b]
                    acc[3, a, b] += -bna * DhS[0, b] + bxa * DhS[1, b] + bya * DhS[2, b]
                    acc[4, a, b] += bn[b] * ua4 - bna * DhS[0, b]
                    acc[5, a, b] += bn[b] * va4 - bna * DhS[3, b]
                    t = bna * bn[b]
                    acc[6, a, b] += t * h00
                    acc[7, a, b] += t * h03
                    acc[8, a, b] += t * h33
                    acc[9, a, b] += t * f44
            # dilatation constraint: G_k = sum_q W Np_qk dJ/df B_f
            dJ = dJq[q]
            for k in range(npr):
                wk = W * Np[q, k]
                for a in range(nen):
                    Gc[0, k, a] += wk * (dJ[0] * bx[a] + dJ[1] * by[a] + dJ[4] * bn[a])
                    Gc[1, k, a] += wk * (dJ[2] * bx[a] + dJ[3] * by[a])
                    Gc[2, k, a] += wk * (dJ[4] * bn[a])
        # wc kappa G^T M^-1 G: (a, b) x (a, b) -> n^0, (a, b) x c -> n^1, c x c -> n^2
        for c in range(3):
            for k in range(npr):
                for a in range(nen):
                    s = 0.0
                    for m in range(npr):
                        s += Minv[e, k, m] * Gc[c, m, a]
                    Hc[c, k, a] = wc * ka * s
        for k in range(npr):
            for a in range(nen):
                ga = Gc[0, k, a]
                gb = Gc[1, k, a]
                gc = Gc[2, k, a]
                for b in range(nen):
                    acc[0, a, b] += ga * Hc[0, k, b]
                    acc[1, a, b] += ga * Hc[1, k, b]
                    acc[2, a, b] += gb * Hc[1, k, b]
                    acc[4, a, b] += ga * Hc[2, k, b]
                    acc[5, a, b] += gb * Hc[2, k, b]
                    acc[9, a, b] += gc * Hc[2, k, b]
        # the lower node blocks (b <= a) in the element's dof order, mirrored
        for a in range(nen):
            i = 3 * a
            for b in range(a + 1):
                j = 3 * b
                _put(Kp, 0, e, i, j, acc[0, a, b])
                _put(Kp, 0, e, i, j + 1, acc[1, a, b])
                _put(Kp, 0, e, i + 1, j, acc[1, b, a])
                _put(Kp, 0, e, i + 1, j + 1, acc[2, a, b])
                _put(Kp, 0, e, i + 2, j + 2, acc[3, a, b])
                _put(Kp, 1, e, i, j + 2, acc[4, a, b])
                _put(Kp, 1, e, i + 1, j + 2, acc[5, a, b])
                _put(Kp, 1, e, i + 2, j, acc[4, b, a])
                _put(Kp, 1, e, i + 2, j + 1, acc[5, b, a])
                _put(Kp, 2, e, i, j, acc[6, a, b])
                _put(Kp, 2, e, i, j + 1, acc[7, a, b])
                _put(Kp, 2, e, i + 1, j, acc[7, a, b])
                _put(Kp, 2, e, i + 1, j + 1, acc[8, a, b])
                _put(Kp, 2, e, i + 2, j + 2, acc[9, a, b])
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


@njit(cache=True)
def harmonic_band(Kp: np.ndarray, n: float, edofs: np.ndarray, ecoef: np.ndarray, x: np.ndarray, edges: np.ndarray,
                  gdofs: np.ndarray, gcoef: np.ndarray, wc: float, ws: float, p: float, base: np.ndarray,
                  gauge: np.ndarray) -> np.ndarray:
    """The lower band of ``base + K_n`` at a state: the element matrices of harmonic ``n``
    (:func:`scatter_harmonic` of the parts ``Kp``) and the cavity's load stiffness ``-p H_V``
    (:func:`harmonic_cavity_matrices` at the current positions ``x``) scattered into a copy of
    ``base`` (the band's zeros, or the zero-tolerance shift). Then the rows and columns of the
    ``gauge`` dofs are replaced by a pivot equal to the largest diagonal entry (the rigid modes of
    ``n = 1`` removed exactly: docs/harmonics.md section 5).

    Parameters
    ----------
    Kp : (3, ne, nd, nd) from :func:`harmonic_element_parts`; n : the harmonic
    edofs, ecoef, gdofs, gcoef : dof maps and coefficients of the elements and cavity edges
        (:func:`scatter_band`)
    x : (nn, 2) current positions; edges : cavity edges; wc, ws : the phi-averages; p : pressure
    base : (ndof, kl + 1) band added to (not modified); gauge : (k,) dofs to fix (int64)

    Returns
    -------
    ab : (ndof, kl + 1) a new band
    """
    ab = base.copy()
    scatter_harmonic(Kp, n, edofs, ecoef, ab)
    He = harmonic_cavity_matrices(x, edges, n, wc, ws)
    scatter_band(He, gdofs, gcoef, -p, ab)
    if gauge.size:
        kl = ab.shape[1] - 1
        scale = 0.0
        for i in range(ab.shape[0]):
            scale = max(scale, abs(ab[i, 0]))
        for d in gauge:
            ab[d, :] = 0.0
            for j in range(max(0, d - kl), d):
                ab[j, d - j] = 0.0
            ab[d, 0] = scale
    return ab
