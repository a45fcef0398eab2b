"""The element pass of :func:`snapjump_kernels.assembly.assemble` for the Q9 element with 3x3
points and the P1 pressure (the grid's), vectorised over batches of elements (lanes); the
formulation is in :mod:`snapjump_kernels.assembly`."""
from __future__ import annotations

import numpy as np
from numba import literally, njit

from snapjump_kernels.gent import gent_scalars, gent_tangent, ibar_gradient


#: Elements per batch (lanes) of :func:`assemble`: 8 elements are two AVX2 registers of the
#: vectorised lane loops; 4 (one register) and 16 (arrays spill out of the L1 cache) were slower.
LANES = 8


@njit(cache=True, error_model="numpy")
def assemble_lanes(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, f_out,
                    data_out, p_geo, pb_out, H_out, NEN, NQ, NPR):
    """:func:`assemble` for ``NEN`` nodes, ``NQ`` points and ``NPR`` pressure modes, compiled for
    each element type with these sizes as constants (:func:`numba.literally`), so that the loops
    over them have constant lengths. (Not ``inline="always"``: numba's inliner deep-copies the
    inlined IR, which for this function cost ~20 s of compile time per copy.)

    The elements are processed ``LANES`` at a time (a batch; lane ``l`` is element ``e0 + l``).
    Every per-element quantity is kept with the lane as its last, contiguous index, and every loop
    that computes runs over the lanes innermost: LLVM's loop vectoriser (the only vectoriser numba
    enables: it does not run LLVM's SLP vectoriser) then computes four elements per AVX2
    instruction. This shapes the code:

    * loops over nodes, points and pressure modes sit *inside* a lane loop: with constant lengths
      LLVM unrolls them completely, which leaves the lane loop innermost (an element-by-element
      loop consists of such short loops only, and stays scalar);
    * inside a lane loop, arrays are indexed ``[..., l]`` with ``l`` the loop variable, and only
      this batch's arrays: the caller's arrays indexed by ``e0 + l`` are copied in first (numba's
      wrap-around of a negative computed index would hide the stride from the vectoriser);
    * a lane loop writes one array and reads a few others: numba passes no aliasing information,
      so each (written, read) pair of arrays costs a run-time overlap test, and LLVM gives up
      beyond a handful; an array read and written in one loop at rows that depend on an outer
      loop's index cannot be proved independent at all. Hence the arrays by role below;
    * ``error_model="numpy"``: numba's default tests every division for a zero divisor and
      raises, an exit from the loop that also stops the vectoriser (the divisors here are radii,
      ``J`` and ``1 - (Ibar_1 - 3) / J_m``, positive wherever the result is used).

    Arrays of the batch (all with constant shapes, hence constant strides):

    ``GEO[field, q, l]``   shape-function gradients ``bx, by`` and ``bn = N / R`` per node, ``W``, ``R``
    ``PT[field, q, l]``    ``f``, ``J``, ``I_1``, ``c = J^(-2/3)``, ``a``, ``b``, ``psi``
    ``DV[field, q, l]``    ``dJ/df``, the stress ``W (dpsi + p dJ)`` and the tangent ``W (d2psi + p_geo d2J)``
    ``NODE[field, q, l]``  per point and node: the force term ``B^T stress``, ``B^T dJ`` and ``D B``
    ``EL[field, l]``       nodal displacements, material, ``M^-1``, element pressures, element force
    ``GG``, ``HH``         ``G`` and ``H = kappa M^-1 G`` (``[k * 2 nen + j, l]``)
    ``K[i, j, l]``         the element stiffness (lower triangle)

    The stiffness ``Ke = sum_q B^T D B + kappa G^T M^-1 G`` is formed entry by entry as one sum
    over the points per lane (and, in the same sum, ``sum_k G[k, i] H[k, j]``), exploiting the
    sparsity of ``B``: a ``u_r`` dof's column of ``B`` is ``(bx, by, 0, 0, bn)``, a ``u_z`` dof's
    ``(0, 0, bx, by, 0)``, so ``D B`` is needed in components 0, 1, 4 for the ``u_r`` columns and in
    2, 3 for all columns (the ``u_r``-``u_z`` block is formed from the ``u_z`` rows alone: ``Ke`` is
    symmetric).
    """
    literally(NEN)  # compiled for each element type, its sizes constants
    literally(NQ)
    literally(NPR)
    ne = conn.shape[0]
    ND = 2 * NEN
    NB = LANES
    # rows ("fields") of the batch arrays
    G_BX = 0
    G_BY = G_BX + NEN
    G_BN = G_BY + NEN
    G_W = G_BN + NEN
    G_R = G_W + 1
    P_F = 0
    P_J = P_F + 5
    P_I1 = P_J + 1
    P_C = P_I1 + 1
    P_A = P_C + 1
    P_B = P_A + 1
    P_PSI = P_B + 1
    V_DJ = 0
    V_SV = V_DJ + 5
    V_D = V_SV + 5
    N_FEQ = 0
    N_BT = N_FEQ + ND
    N_DBR = N_BT + ND  # 3 per node: components 0, 1, 4 of D B for its u_r dof
    N_DBZR = N_DBR + 3 * NEN  # 2 per node: components 2, 3 of D B for its u_r dof
    N_DBZZ = N_DBZR + 2 * NEN  # 2 per node: components 2, 3 of D B for its u_z dof
    E_UX = 0
    E_UZ = E_UX + NEN
    E_MU = E_UZ + NEN
    E_JM = E_MU + 1
    E_KA = E_JM + 1
    E_MINV = E_KA + 1
    E_PB = E_MINV + NPR * NPR
    E_PG = E_PB + NPR
    E_FE = E_PG + NPR
    GEO = np.empty((G_R + 1, NQ, NB))
    PT = np.empty((P_PSI + 1, NQ, NB))
    DV = np.empty((V_D + 15, NQ, NB))
    NODE = np.empty((N_DBZZ + 2 * NEN, NQ, NB))
    EL = np.empty((E_FE + ND, NB))
    GG = np.empty((NPR * ND, NB))
    HH = np.empty((NPR * ND, NB))
    K = np.empty((ND, ND, NB))
    g = np.empty(NPR)
    energy = 0.0
    maxdev = 0.0
    use_geo = p_geo.shape[0] == ne
    keep_pb = pb_out.shape[0] == ne
    keep_H = H_out.shape[0] == ne
    for e0 in range(0, ne, NB):
        nb = min(NB, ne - e0)
        # ---- copy the batch's data in (lane-last)
        for a in range(NEN):
            for l in range(nb):
                n = conn[e0 + l, a]
                EL[E_UX + a, l] = u[n, 0]
                EL[E_UZ + a, l] = u[n, 1]
        for l in range(nb):
            m_ = mat[e0 + l]
            EL[E_MU, l] = mu[m_]
            EL[E_JM, l] = jm[m_]
            EL[E_KA, l] = kappa[m_]
            for k in range(NPR):
                for m in range(NPR):
                    EL[E_MINV + NPR * k + m, l] = Minv[e0 + l, k, m]
        for q in range(NQ):
            for l in range(nb):
                GEO[G_W, q, l] = Wq[e0 + l, q]
                GEO[G_R, q, l] = Rq[e0 + l, q]
            for a in range(NEN):
                for l in range(nb):
                    GEO[G_BX + a, q, l] = dNdX[e0 + l, q, a, 0]
                    GEO[G_BY + a, q, l] = dNdX[e0 + l, q, a, 1]
            for a in range(NEN):
                for l in range(nb):
                    GEO[G_BN + a, q, l] = N_ref[q, a] / GEO[G_R, q, l]
        # ---- deformation gradient, J, I_1
        for q in range(NQ):
            for l in range(nb):
                f0 = 1.0
                f1 = 0.0
                f2 = 0.0
                f3 = 1.0
                ur = 0.0
                for a in range(NEN):
                    ux = EL[E_UX + a, l]
                    uz = EL[E_UZ + a, l]
                    f0 += ux * GEO[G_BX + a, q, l]
                    f1 += ux * GEO[G_BY + a, q, l]
                    f2 += uz * GEO[G_BX + a, q, l]
                    f3 += uz * GEO[G_BY + a, q, l]
                    ur += ux * N_ref[q, a]
                f4 = 1.0 + ur / GEO[G_R, q, l]
                PT[P_F, q, l] = f0
                PT[P_F + 1, q, l] = f1
                PT[P_F + 2, q, l] = f2
                PT[P_F + 3, q, l] = f3
                PT[P_F + 4, q, l] = f4
                PT[P_J, q, l] = (f0 * f3 - f1 * f2) * f4
                I1 = 0.0
                I1 += f0 * f0
                I1 += f1 * f1
                I1 += f2 * f2
                I1 += f3 * f3
                I1 += f4 * f4
                PT[P_I1, q, l] = I1
        # ---- Gent energy density and its derivatives' factors (pow and log: called per lane)
        ok_all = True
        for q in range(NQ):
            for l in range(nb):
                J = PT[P_J, q, l]
                pos = J > 0.0
                ok, psi, c, a_, b_ = gent_scalars(J if pos else 1.0, PT[P_I1, q, l], EL[E_MU, l], EL[E_JM, l])
                ok_all = ok_all and ok and pos
                PT[P_C, q, l] = c
                PT[P_A, q, l] = a_
                PT[P_B, q, l] = b_
                PT[P_PSI, q, l] = psi
        if not ok_all:
            return energy, False, maxdev
        # ---- energy, element pressure pb = kappa M^-1 g and dilatation: element by element, in
        # the order of the plain loop (the energy is a sum over all elements)
        for l in range(nb):
            e = e0 + l
            ka = EL[E_KA, l]
            for q in range(NQ):
                energy += GEO[G_W, q, l] * PT[P_PSI, q, l]
            for k in range(NPR):
                s = 0.0
                for q in range(NQ):
                    s += GEO[G_W, q, l] * Np[q, k] * (PT[P_J, q, l] - 1.0)
                g[k] = s
            for k in range(NPR):
                s = 0.0
                for m in range(NPR):
                    s += EL[E_MINV + NPR * k + m, l] * g[m]
                pbk = ka * s
                energy += 0.5 * g[k] * pbk
                EL[E_PB + k, l] = pbk
                EL[E_PG + k, l] = p_geo[e, k] if use_geo else pbk
                if keep_pb:
                    pb_out[e, k] = pbk
            # projected dilatation theta - 1 = p / kappa at the quadrature points (what is constrained)
            for q in range(NQ):
                th = 0.0
                for k in range(NPR):
                    th += Np[q, k] * EL[E_PB + k, l]
                dev = abs(th) / ka
                if dev > maxdev:
                    maxdev = dev
        if want == 0:
            continue
        # ---- derivatives at the points: dJ, dIbar_1, stress W (dpsi + p dJ), tangent W (d2psi + p_geo d2J)
        for q in range(NQ):
            for l in range(nb):
                f0 = PT[P_F, q, l]
                f1 = PT[P_F + 1, q, l]
                f2 = PT[P_F + 2, q, l]
                f3 = PT[P_F + 3, q, l]
                f4 = PT[P_F + 4, q, l]
                J = PT[P_J, q, l]
                I1 = PT[P_I1, q, l]
                c = PT[P_C, q, l]
                dJ0 = f3 * f4
                dJ1 = -f2 * f4
                dJ2 = -f1 * f4
                dJ3 = f0 * f4
                dJ4 = f0 * f3 - f1 * f2
                i0, i1, i2, i3, i4 = ibar_gradient(f0, f1, f2, f3, f4, dJ0, dJ1, dJ2, dJ3, dJ4, J, I1, c)
                DV[V_DJ, q, l] = dJ0
                DV[V_DJ + 1, q, l] = dJ1
                DV[V_DJ + 2, q, l] = dJ2
                DV[V_DJ + 3, q, l] = dJ3
                DV[V_DJ + 4, q, l] = dJ4
                pq = 0.0
                pg = 0.0
                for k in range(NPR):
                    pq += Np[q, k] * EL[E_PB + k, l]
                    pg += Np[q, k] * EL[E_PG + k, l]
                W = GEO[G_W, q, l]
                a_ = PT[P_A, q, l]
                DV[V_SV, q, l] = W * (a_ * i0 + pq * dJ0)
                DV[V_SV + 1, q, l] = W * (a_ * i1 + pq * dJ1)
                DV[V_SV + 2, q, l] = W * (a_ * i2 + pq * dJ2)
                DV[V_SV + 3, q, l] = W * (a_ * i3 + pq * dJ3)
                DV[V_SV + 4, q, l] = W * (a_ * i4 + pq * dJ4)
                if want >= 2:
                    (d00, d01, d02, d03, d04, d11, d12, d13, d14, d22, d23, d24, d33, d34,
                     d44) = gent_tangent(W, pg, f0, f1, f2, f3, f4, dJ0, dJ1, dJ2, dJ3, dJ4, i0, i1, i2, i3, i4,
                                         J, I1, c, a_, PT[P_B, q, l])
                    DV[V_D, q, l] = d00
                    DV[V_D + 1, q, l] = d01
                    DV[V_D + 2, q, l] = d02
                    DV[V_D + 3, q, l] = d03
                    DV[V_D + 4, q, l] = d04
                    DV[V_D + 5, q, l] = d11
                    DV[V_D + 6, q, l] = d12
                    DV[V_D + 7, q, l] = d13
                    DV[V_D + 8, q, l] = d14
                    DV[V_D + 9, q, l] = d22
                    DV[V_D + 10, q, l] = d23
                    DV[V_D + 11, q, l] = d24
                    DV[V_D + 12, q, l] = d33
                    DV[V_D + 13, q, l] = d34
                    DV[V_D + 14, q, l] = d44
        # ---- per point and node: the force term B^T stress, and B^T dJ and D B for the tangent
        for q in range(NQ):
            for a in range(NEN):
                for l in range(nb):
                    bx = GEO[G_BX + a, q, l]
                    by = GEO[G_BY + a, q, l]
                    bn = GEO[G_BN + a, q, l]
                    NODE[N_FEQ + 2 * a, q, l] = bx * DV[V_SV, q, l] + by * DV[V_SV + 1, q, l] + bn * DV[V_SV + 4, q, l]
                    NODE[N_FEQ + 2 * a + 1, q, l] = bx * DV[V_SV + 2, q, l] + by * DV[V_SV + 3, q, l]
            if want >= 2:
                for a in range(NEN):
                    for l in range(nb):
                        bx = GEO[G_BX + a, q, l]
                        by = GEO[G_BY + a, q, l]
                        bn = GEO[G_BN + a, q, l]
                        NODE[N_BT + 2 * a, q, l] = bx * DV[V_DJ, q, l] + by * DV[V_DJ + 1, q, l] + bn * DV[V_DJ + 4, q, l]
                        NODE[N_BT + 2 * a + 1, q, l] = bx * DV[V_DJ + 2, q, l] + by * DV[V_DJ + 3, q, l]
                        d00 = DV[V_D, q, l]
                        d01 = DV[V_D + 1, q, l]
                        d02 = DV[V_D + 2, q, l]
                        d03 = DV[V_D + 3, q, l]
                        d04 = DV[V_D + 4, q, l]
                        d11 = DV[V_D + 5, q, l]
                        d12 = DV[V_D + 6, q, l]
                        d13 = DV[V_D + 7, q, l]
                        d14 = DV[V_D + 8, q, l]
                        d22 = DV[V_D + 9, q, l]
                        d23 = DV[V_D + 10, q, l]
                        d24 = DV[V_D + 11, q, l]
                        d33 = DV[V_D + 12, q, l]
                        d34 = DV[V_D + 13, q, l]
                        d44 = DV[V_D + 14, q, l]
                        NODE[N_DBR + 3 * a, q, l] = d00 * bx + d01 * by + d04 * bn
                        NODE[N_DBR + 3 * a + 1, q, l] = d01 * bx + d11 * by + d14 * bn
                        NODE[N_DBR + 3 * a + 2, q, l] = d04 * bx + d14 * by + d44 * bn
                        NODE[N_DBZR + 2 * a, q, l] = d02 * bx + d12 * by + d24 * bn
                        NODE[N_DBZR + 2 * a + 1, q, l] = d03 * bx + d13 * by + d34 * bn
                        NODE[N_DBZZ + 2 * a, q, l] = d22 * bx + d23 * by
                        NODE[N_DBZZ + 2 * a + 1, q, l] = d23 * bx + d33 * by
        # ---- element force, G and H = kappa M^-1 G: sums over the points in their order
        for j in range(ND):
            for l in range(nb):
                s = 0.0
                for q in range(NQ):
                    s += NODE[N_FEQ + j, q, l]
                EL[E_FE + j, l] = s
        if want >= 2:
            for k in range(NPR):
                for j in range(ND):
                    for l in range(nb):
                        s = 0.0
                        for q in range(NQ):
                            s += GEO[G_W, q, l] * Np[q, k] * NODE[N_BT + j, q, l]
                        GG[ND * k + j, l] = s
            for k in range(NPR):
                for j in range(ND):
                    for l in range(nb):
                        s = 0.0
                        for m in range(NPR):
                            s += EL[E_MINV + NPR * k + m, l] * GG[ND * m + j, l]
                        HH[ND * k + j, l] = EL[E_KA, l] * s
            # ---- Ke = sum_q B^T D B + G^T H, lower triangle. Column b outermost: its D B rows stay
            # in the L1 cache while the rows of B stream past.
            for b in range(NEN):
                for a in range(b, NEN):
                    for l in range(nb):  # Ke[2a, 2b]: u_r rows, u_r columns
                        sx = 0.0
                        sy = 0.0
                        sn = 0.0
                        for q in range(NQ):
                            sx += GEO[G_BX + a, q, l] * NODE[N_DBR + 3 * b, q, l]
                            sy += GEO[G_BY + a, q, l] * NODE[N_DBR + 3 * b + 1, q, l]
                            sn += GEO[G_BN + a, q, l] * NODE[N_DBR + 3 * b + 2, q, l]
                        sv = 0.0
                        for k in range(NPR):
                            sv += GG[ND * k + 2 * a, l] * HH[ND * k + 2 * b, l]
                        K[2 * a, 2 * b, l] = ((sx + sy) + sn) + sv
                    for l in range(nb):  # Ke[2a + 1, 2b + 1]: u_z rows, u_z columns
                        sx = 0.0
                        sy = 0.0
                        for q in range(NQ):
                            sx += GEO[G_BX + a, q, l] * NODE[N_DBZZ + 2 * b, q, l]
                            sy += GEO[G_BY + a, q, l] * NODE[N_DBZZ + 2 * b + 1, q, l]
                        sv = 0.0
                        for k in range(NPR):
                            sv += GG[ND * k + 2 * a + 1, l] * HH[ND * k + 2 * b + 1, l]
                        K[2 * a + 1, 2 * b + 1, l] = (sx + sy) + sv
                for a in range(NEN):
                    # Ke[2a + 1, 2b] (u_z row, u_r column): in the lower triangle if b <= a, else
                    # stored as its transpose Ke[2b, 2a + 1]
                    i = 2 * a + 1 if b <= a else 2 * b
                    j = 2 * b if b <= a else 2 * a + 1
                    for l in range(nb):
                        sx = 0.0
                        sy = 0.0
                        for q in range(NQ):
                            sx += GEO[G_BX + a, q, l] * NODE[N_DBZR + 2 * b, q, l]
                            sy += GEO[G_BY + a, q, l] * NODE[N_DBZR + 2 * b + 1, q, l]
                        sv = 0.0
                        for k in range(NPR):
                            sv += GG[ND * k + 2 * a + 1, l] * HH[ND * k + 2 * b, l]
                        K[i, j, l] = (sx + sy) + sv
        # ---- scatter, element by element
        for l in range(nb):
            e = e0 + l
            if keep_H and want >= 2:
                for k in range(NPR):
                    for j in range(ND):
                        H_out[e, k, j] = HH[ND * k + j, l]
            _scatter(edofs, epos, e, l, EL, E_FE, K, want, f_out, data_out)
    return energy, True, maxdev


@njit(cache=True, inline="always")
def _scatter(edofs, epos, e, l, EL, E_FE, K, want, f_out, data_out):
    """Add element ``e``'s force (``EL[E_FE + i, l]``) and, for ``want >= 2``, its stiffness
    (``K[:, :, l]``, lower triangle of a symmetric matrix) into ``f_out`` and ``data_out``."""
    for i in range(edofs.shape[1]):
        di = edofs[e, i]
        if di < 0:
            continue
        f_out[di] += EL[E_FE + i, l]
        if want >= 2:
            for j in range(i + 1):
                v = K[i, j, l]
                pij = epos[e, i, j]
                if pij >= 0:
                    data_out[pij] += v
                if j != i:
                    pji = epos[e, j, i]
                    if pji >= 0:
                        data_out[pji] += v
