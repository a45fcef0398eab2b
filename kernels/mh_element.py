"""Energy, residual and tangent of the multi-harmonic mixed Gent solid, element by element.

The energy is the phi-average (times the ``2 pi R`` weight that ``Wq`` carries) of the mixed
element's reduced energy evaluated with the 3D ``F`` (:mod:`snapjump_kernels.mh_basis`) at every
phi point of a trapezoidal rule on ``[0, pi / n_1]`` (:func:`~snapjump_kernels.mh_basis.phi_rule`;
the fields are even in phi and, with harmonics that are multiples of ``n_1``, ``2 pi / n_1``-periodic)::

    Pi = sum_j w_j [ sum_q W_q psi_iso(F_q(phi_j)) + kappa/2 g_j^T M^-1 g_j ],
    g_j = sum_q W_q Np_q (J_q(phi_j) - 1)

so the pressure and the dilatation are eliminated at every phi point, as the axisymmetric element
does (:mod:`snapjump_kernels.assembly`); the pointwise law is
:mod:`snapjump_kernels.mh_material`'s. Gradient and Hessian are exact for that quadrature; they
are formed through the phi-moments of the pointwise stress and tangent, ``sum_j w_j t_k(phi_j)
s(phi_j)`` and ``sum_j w_j t_k t_l D(phi_j)`` (``t = cos`` or ``sin`` by component), contracted with
the phi-independent nodal B matrices of each harmonic.

:func:`mh_elements` returns the element residuals and tangents; :func:`mh_assemble_band` scatters
each element's tangent into the band as it is formed; :func:`scatter_vector` assembles element
vectors. JIT-compiled (not in the ahead-of-time build). Arrays in, arrays out.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.mh_basis import dof_offset, harmonic_gradients, harmonic_ndof, node_b
from snapjump_kernels.mh_material import gent3, imperfect_point


@njit(cache=True)
def _fourier_tables(phis: np.ndarray, wphi: np.ndarray, hn: np.ndarray, sel: np.ndarray):
    """The tables and work arrays of :func:`_pair_moments`, made once per element pass:
    ``TC[m, j] = w_j cos(m phi_j)`` and ``TS[m, j] = w_j sin(m phi_j)`` for ``m = 0 .. 2 max(hn)``;
    the flat components ``9 c + d`` of ``D`` in the order ``perm``: first the ``ncos`` whose two
    factors are alike (``cos cos``: ``c, d < 5``; ``sin sin``: ``c, d >= 5``), whose pair moments
    are cosine moments, then the mixed ones (sine moments); ``need[m]``: whether a pair of the
    harmonics ``sel`` uses the multiple ``m``; then the work arrays ``P`` (one point's components in
    that order, every phi point), ``MC`` and ``MS`` (the moments)."""
    nphi = phis.shape[0]
    K = hn.shape[0]
    mm = 2 * hn[-1] + 1
    TC = np.empty((mm, nphi))
    TS = np.empty((mm, nphi))
    for m in range(mm):
        for j in range(nphi):
            TC[m, j] = wphi[j] * np.cos(m * phis[j])
            TS[m, j] = wphi[j] * np.sin(m * phis[j])
    perm = np.empty(81, np.int64)
    n = 0
    for c in range(9):
        for d in range(9):
            if (c < 5) == (d < 5):
                perm[n] = 9 * c + d
                n += 1
    ncos = n
    for c in range(9):
        for d in range(9):
            if (c < 5) != (d < 5):
                perm[n] = 9 * c + d
                n += 1
    need = np.zeros(mm, np.bool_)
    for k in range(K):
        if not sel[k]:
            continue
        for l in range(k, K):
            if sel[l]:
                need[hn[l] - hn[k]] = True
                need[hn[l] + hn[k]] = True
    return TC, TS, perm, ncos, need, np.empty((nphi, 81)), np.empty((mm, ncos)), np.empty((mm, 81 - ncos))


@njit(cache=True, error_model="numpy")
def _pair_moments(Df: np.ndarray, tabs, hn: np.ndarray, sel: np.ndarray, Dtp: np.ndarray) -> None:
    """The phi-moments of the pointwise tangent for every harmonic pair ``p = (k, l)``, ``k <= l``
    of the harmonics ``sel`` (``k`` outer): ``Dtp[p, q, 9 c + d] = sum_j w_j t_k(phi_j, c)
    t_l(phi_j, d) D[q, j, c, d]`` (``t`` is ``cos n phi`` for the components ``c < 5``, ``sin n phi``
    after), from the Fourier moments of ``D`` by the product formulas (``a = n_k <= b = n_l``)::

        cos a cos b = (cos(b - a) + cos(a + b)) / 2     sin a sin b = (cos(b - a) - cos(a + b)) / 2
        cos a sin b = (sin(a + b) + sin(b - a)) / 2     sin a cos b = (sin(a + b) - sin(b - a)) / 2

    so that each component needs the moments of the ``2 max(hn) + 1`` multiples of phi (those the
    pairs use), not one per pair (45 pairs for the harmonics ``0..8``, 17 moments). Equal to the
    pair-by-pair sums to round-off (``tests/unit/test_multiharmonic_kernel.py``). ``Df (nq, nphi,
    81)``; ``tabs`` from :func:`_fourier_tables`."""
    TC, TS, perm, ncos, need, P, MC, MS = tabs
    nq, nphi = Df.shape[0], Df.shape[1]
    K = hn.shape[0]
    mm = TC.shape[0]
    nsin = 81 - ncos
    for q in range(nq):
        for j in range(nphi):
            dq = Df[q, j]
            pj = P[j]
            for x in range(81):
                pj[x] = dq[perm[x]]
        for m in range(mm):
            if not need[m]:
                continue
            mc = MC[m]
            ms = MS[m]
            for x in range(ncos):
                mc[x] = 0.0
            for x in range(nsin):
                ms[x] = 0.0
            for j in range(nphi):
                wc = TC[m, j]
                ws = TS[m, j]
                pj = P[j]
                for x in range(ncos):
                    mc[x] += wc * pj[x]
                ps = P[j, ncos:]
                for x in range(nsin):
                    ms[x] += ws * ps[x]
        p = -1
        for k in range(K):
            for l in range(k, K):
                p += 1
                if not (sel[k] and sel[l]):
                    continue
                a = hn[k]
                b = hn[l]
                dlt = b - a  # >= 0
                sm = a + b
                acc = Dtp[p, q]
                for x in range(ncos):
                    f = perm[x]
                    if f < 45:  # c < 5 (and d < 5): cos a cos b
                        acc[f] = 0.5 * (MC[dlt, x] + MC[sm, x])
                    else:  # sin a sin b
                        acc[f] = 0.5 * (MC[dlt, x] - MC[sm, x])
                for x in range(nsin):
                    f = perm[ncos + x]
                    if f < 45:  # cos a sin b = (sin(a + b) - sin(a - b)) / 2 = (S[sm] + S[dlt]) / 2
                        acc[f] = 0.5 * (MS[sm, x] + MS[dlt, x])
                    else:  # sin a cos b = (sin(a + b) + sin(a - b)) / 2 = (S[sm] - S[dlt]) / 2
                        acc[f] = 0.5 * (MS[sm, x] - MS[dlt, x])


@njit(cache=True, error_model="numpy")
def _elastic_tangent(Dq: np.ndarray, tabs, bxq: np.ndarray, byq: np.ndarray, bnq: np.ndarray,
                     hn: np.ndarray, Dtp: np.ndarray, DB: np.ndarray, Kh: np.ndarray, sel: np.ndarray) -> None:
    """The elastic tangent ``sum_q B_k^T Dt_kl B_l`` of one element, harmonic pair by pair
    (``k <= l``), into ``Kh`` in the *harmonic-major* element order: dof ``(k, i, a)`` (harmonic,
    component a/b/c, node) at ``nen offset(k) + i nen + a``, so that the columns of every harmonic
    ``l >= k`` are contiguous and the rows below run over all of them (126 - 18 k columns for
    ``K = 5`` on Q9; LLVM vectorises them).

    First the phi-moments ``Dtp[p, q]`` of every pair (flat 81, :func:`_pair_moments`); then, per
    harmonic ``k`` and point, ``DB = Dt_kl B_l`` of every node and
    every ``l >= k`` side by side (``DB[c, nen offset(l) - nen offset(k) + i nen + b]``), then the
    rows ``B_k^T DB`` of every node of harmonic ``k`` over all of them (a node's B is sparse: its
    columns a, b, c have 4, 3 and 4 non-zeros). Every entry receives the terms of the points in
    the order of ``q``. The element pass that forms each node pair's block alone is the test
    oracle (``tests/unit/mh_reference.py``; equal to round-off).

    ``Dq (nq, nphi, 9, 9)`` the pointwise ``W (d2psi + p d2J)``; ``bxq, byq, bnq (nq, nen)`` the
    node values ``dN/dR, dN/dZ, N / R`` at each point; ``Dtp (npair, nq, 81)``, ``DB (9, nen nc)``
    work arrays. ``sel (K,)``: the harmonics whose rows and columns are wanted; the pairs with an
    unselected harmonic are not formed (their rows stay zero, their columns hold anything finite).
    """
    nq, nphi = Dq.shape[0], Dq.shape[1]
    nen = bxq.shape[1]
    K = hn.shape[0]
    nd = Kh.shape[0]
    Df = Dq.reshape(nq, nphi, 81)
    _pair_moments(Df, tabs, hn, sel, Dtp)
    Kh[:, :] = 0.0
    for k in range(K):
        if not sel[k]:
            continue
        nk = harmonic_ndof(k)
        fk = float(hn[k])
        r0 = nen * dof_offset(k)
        m = nd - r0  # the columns of every harmonic l >= k: contiguous in the harmonic-major order
        for q in range(nq):
            bx = bxq[q]
            by = byq[q]
            bn = bnq[q]
            for l in range(k, K):
                if not sel[l]:
                    continue
                p = _pair_index(k, l, K)
                nl = harmonic_ndof(l)
                fl = float(hn[l])
                c0 = nen * dof_offset(l) - r0
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
                        tmp: np.ndarray, Ke: np.ndarray, sel: np.ndarray, dsel: np.ndarray) -> None:
    """Add the volumetric-constraint stiffness ``sum_j w_j kappa G_j^T M^-1 G_j`` of element ``e``
    to the upper triangle of its node-major tangent ``Ke`` (the caller mirrors it). ``G_j`` is
    formed from the sparse B (``B^T (dJ t)`` per node) and ``H_j = w_j kappa M^-1 G_j`` for every
    phi point first; then each row ``i`` of the upper triangle receives the terms ``G_j[:, i]^T
    H_j`` of every point in turn (``j`` in order, each summed over the pressure dofs from 0), the
    row staying in the L1 cache. ``Gv, Hv (nphi, npr, nd)``, ``tmp (nd,)`` are work arrays. ``sel (K,)``
    the harmonics wanted and ``dsel (nd,)`` the element dofs of them: the rows of the others are
    not formed (rows and columns of unselected dofs hold anything finite)."""
    nd = Ke.shape[0]
    nq, nphi = dJq.shape[0], dJq.shape[1]
    npr = Np.shape[1]
    K = hn.shape[0]
    nen = bxq.shape[1]
    nc = 2 + 3 * (K - 1)
    for j in range(nphi):
        Gj = Gv[j]
        Gj[:, :] = 0.0
        for q in range(nq):
            W = Wq[e, q]
            for k in range(K):
                if not sel[k]:
                    continue
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
                    o = a * nc + dof_offset(k)
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
        if not dsel[i]:
            continue
        ru = Ke[i, i:]
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


@njit(cache=True)
def mh_elements(A: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
                kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
                Np: np.ndarray, Minv: np.ndarray, hn: np.ndarray, phis: np.ndarray, wphi: np.ndarray,
                want: int, Fi: np.ndarray, Jimp: np.ndarray, Minvp: np.ndarray):
    """Energy, element residuals and element tangents of the multi-harmonic solid.

    Parameters
    ----------
    A : (nn, nc) nodal amplitudes (scaled displacements), layout of :mod:`snapjump_kernels.mh_basis`
    conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv : as in
        :func:`snapjump_kernels.assembly.assemble`
    hn : (K,) harmonic numbers, ``hn[0] = 0``
    phis, wphi : the phi rule (:func:`snapjump_kernels.mh_basis.phi_rule`)
    want : 0 energy, 1 and residuals, 2 and tangents
    Fi, Jimp : an initial geometric imperfection (empty arrays: none). ``Fi (ne, nq, nphi, 3, 3)``
        is the inverse of the imperfection's deformation gradient ``F0`` (perfect reference ->
        stress-free imperfect body) at every point and ``Jimp = det F0``. ``A`` is then the total
        displacement from the perfect reference (imperfection included); the elastic gradient is
        ``F F0^-1`` and every volume integral carries ``Jimp``
        (:func:`snapjump_kernels.mh_material.imperfect_point`)
    Minvp : ``(ne, nphi, np, np)`` with an imperfection: the inverse pressure mass matrices of the
        imperfect body at every phi point (``sum_q W_q Jimp Np Np^T``), used instead of ``Minv``

    Returns
    -------
    (E, ok, re, Ke) : the energy, False if some point left the Gent domain, the element residuals
        (ne, nen nc) and tangents (ne, nen nc, nen nc; empty unless ``want >= 2``; symmetric: the
        lower triangle is the upper's mirror image)
    """
    npr = Np.shape[1]
    nphi = phis.shape[0]
    return _mh_pass(A, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, hn, phis, wphi, want, Fi, Jimp,
                    Minvp, False, np.zeros((0, 0), np.int64), np.zeros((0, 0)), np.zeros((0, 0)),
                    np.zeros((0, nphi, npr)), np.zeros((0, nphi, npr)), np.zeros((0, nphi, npr, 0)),
                    np.ones(hn.shape[0], np.bool_))


@njit(cache=True)
def _mh_pass(A: np.ndarray, conn: np.ndarray, mat: np.ndarray, mu: np.ndarray, jm: np.ndarray,
             kappa: np.ndarray, dNdX: np.ndarray, N_ref: np.ndarray, Rq: np.ndarray, Wq: np.ndarray,
             Np: np.ndarray, Minv: np.ndarray, hn: np.ndarray, phis: np.ndarray, wphi: np.ndarray,
             want: int, Fi: np.ndarray, Jimp: np.ndarray, Minvp: np.ndarray, fused: bool,
             edofs: np.ndarray, ecoef: np.ndarray, ab: np.ndarray, p_geo: np.ndarray, pb_out: np.ndarray,
             H_out: np.ndarray, sel: np.ndarray):
    """The element pass of :func:`mh_elements`; with ``fused`` (and ``want >= 2``) each
    element's tangent is scattered into the band ``ab`` as soon as it is formed (as
    :func:`snapjump_kernels.harmonics.scatter_band` with factor 1 would, element by element) and
    not kept: the returned ``Ke`` is then one element's work array. ``p_geo``, ``pb_out``,
    ``H_out``: the mixed linearisation of :func:`mh_assemble_band` (arrays of length 0: none).
    ``sel (K,)``: the harmonics whose tangent rows and columns are formed (the others' entries of
    ``Ke`` hold anything finite; all selected: the whole tangent)."""
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
    # (the tangent's tables; a pass without the tangent makes them for harmonic 0 alone)
    tabs = _fourier_tables(phis, wphi, hn, sel) if want >= 2 else _fourier_tables(phis, wphi, hn[:1], sel[:1])
    Dtp = np.empty((npair, nq, 81))
    DB = np.zeros((9, nd))  # (zero: the columns of unselected harmonics are read, not written)
    Kh = np.zeros((nd, nd))
    tmp = np.empty(nd)
    bxq = np.empty((nq, nen))
    byq = np.empty((nq, nen))
    bnq = np.empty((nq, nen))
    hinv = np.empty(nd, np.int64)  # harmonic-major element dof of each node-major one
    for k in range(K):
        for dof in range(harmonic_ndof(k)):
            for a in range(nen):
                hinv[a * nc + dof_offset(k) + dof] = nen * dof_offset(k) + dof * nen + a
    imperfect = Fi.shape[0] > 0
    use_geo = p_geo.shape[0] == ne
    keep_pb = pb_out.shape[0] == ne
    keep_H = H_out.shape[0] == ne and want >= 2
    ve = np.empty(9)
    dpe = np.zeros(9)
    d2pe = np.zeros((9, 9))
    dJe = np.zeros(9)
    d2Je = np.zeros((9, 9))
    for a in range(nen):
        for k in range(K):
            for dof in range(harmonic_ndof(k)):
                hk[a * nc + dof_offset(k) + dof] = k
    dsel = np.empty(nd, np.bool_)  # the element dofs of the selected harmonics
    for i in range(nd):
        dsel[i] = sel[hk[i]]
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
                if keep_pb:
                    pb_out[e, j, k2] = pel[j, k2]
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
                    node_b(bx, by, bn, float(hn[k]), Bn[a, k])
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
                    o = a * nc + dof_offset(k)
                    for dof in range(harmonic_ndof(k)):
                        s = 0.0
                        for c in range(9):
                            s += Bn[a, k, c, dof] * S[k, c]
                        re[e, o + dof] += s
            # the node values of B at this point, by node (contiguous over the nodes)
            for a in range(nen):
                bxq[q, a] = bq[a, 0]
                byq[q, a] = bq[a, 1]
                bnq[q, a] = bq[a, 2]
            if want < 2:
                continue
            # the tangent's pointwise D with the pressure part, W (d2psi + p d2J) (p from p_geo
            # in the mixed linearisation)
            pj = p_geo[e] if use_geo else pel
            for j in range(nphi):
                pq = 0.0
                for k2 in range(npr):
                    pq += Np[q, k2] * pj[j, k2]
                pw = W * pq
                for c in range(9):
                    for d in range(9):
                        Dq[q, j, c, d] += pw * d2Jq[q, j, c, d]
        if want < 2:
            continue
        _elastic_tangent(Dq, tabs, bxq, byq, bnq, hn, Dtp, DB, Kh, sel)
        # harmonic-major blocks -> the upper triangle of the node-major Ke; the blocks of harmonics
        # k < l were formed once: their transposes are the (l, k) blocks (as the dofs' harmonics say)
        Ke_e = Ke[0] if fuse else Ke[e]
        for pr in range(nd):
            r = hinv[pr]
            kr = hk[pr]
            for pc in range(pr, nd):
                c = hinv[pc]
                if kr <= hk[pc]:
                    Ke_e[pr, pc] = Kh[r, c]
                else:
                    Ke_e[pr, pc] = Kh[c, r]
        _volumetric_tangent(e, dJq, t, Wq, Np, Minv, Minvp, imperfect, wphi, ka, bxq, byq, bnq, hn, Gv, Hv,
                            tmp, Ke_e, sel, dsel)
        if keep_H:  # kappa M^-1 G_j: the element pressures' derivative at every phi point
            for j in range(nphi):
                Mi = Minvp[e, j] if imperfect else Minv[e]
                for k2 in range(npr):
                    for i in range(nd):
                        s = 0.0
                        for l2 in range(npr):
                            s += Mi[k2, l2] * Gv[j, l2, i]
                        H_out[e, j, k2, i] = ka * s
        for i in range(nd):  # the lower triangle: the upper's mirror image
            for jj in range(i + 1, nd):
                Ke_e[jj, i] = Ke_e[i, jj]
        if fuse:
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
                     ext: np.ndarray, ab: np.ndarray, p_geo: np.ndarray, pb_out: np.ndarray, H_out: np.ndarray,
                     sel: np.ndarray):
    """Energy, element residuals and the tangent scattered into the lower band ``ab`` in one pass.

    ``ab``'s envelope (``ab[j, :ext[j] + 1]``) is zeroed first (entries outside it are neither
    read nor written: a band that was zero there stays so); then every element's tangent is
    added as it is formed: the same band, bit for bit, as :func:`mh_elements` (``want = 2``)
    followed by :func:`snapjump_kernels.harmonics.scatter_band` (factor 1), without the
    ``(ne, nd, nd)`` element matrices in memory.

    Mixed linearisation (as :func:`snapjump_kernels.assembly.assemble`'s): the element pressure at
    every phi point, condensed in the energy and the residual (``kappa M^-1 g_j(u)``), may be taken
    in the tangent's geometric term ``p d2J`` from ``p_geo (ne, nphi, np)`` instead (the pressure of
    the three-field Newton iteration: extrapolated along the path, then updated linearly). The
    residual is the same; only the Newton matrix changes (``p_geo`` equal to the condensed
    pressures gives the reduced tangent bit for bit). ``pb_out (ne, nphi, np)`` receives the
    condensed pressures and ``H_out (ne, nphi, np, nd)`` their derivative ``kappa M^-1 G_j`` with
    respect to the element dofs (node-major, as ``edofs``); arrays of length 0: not used / not wanted.

    A block of the tangent (``sel (K,)`` bool: the harmonics kept; all True: the whole tangent):
    the rows and columns of the other harmonics are not formed, and ``edofs`` must map their dofs
    to -1 (a band of the block alone, numbered as ``edofs`` says). At a state whose harmonics the
    block's do not couple with the others' (the multiples of ``n_c`` against the rest), this is
    that diagonal block of the whole tangent, entry for entry the same sums.

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
                            Jimp, Minvp, True, edofs, ecoef, ab, p_geo, pb_out, H_out, sel)
    return E, ok, re


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
