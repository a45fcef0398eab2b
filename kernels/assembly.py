"""Element loops for the axisymmetric mixed Gent solid: energy, residual, tangent into CSR.

Formulation (documented here once): a three-field Hu-Washizu element with discontinuous
pressure and dilatation fields in the span of the element's pressure basis ``Np`` (Q4: P0,
i.e. mean dilatation; Q9: P1 = [1, xi, eta]). Eliminating both fields at element level with the
volumetric energy ``kappa/2 (theta - 1)^2`` gives the reduced element energy::

    Pi_e(u) = sum_q W_q psi_iso(f_q)  +  kappa/2 g^T M^-1 g,
    g_k = sum_q W_q Np_qk (J_q - 1),   M_kl = sum_q W_q Np_qk Np_ql,

whose gradient and Hessian are exact (the element pressure is ``p = kappa M^-1 g`` evaluated at
the quadrature points).

Mixed linearisation (optional, ``p_geo``): the tangent may take the element pressure from an
outside estimate instead of ``kappa M^-1 g(u)`` in its geometric term ``p d2J``. This is the
Newton matrix of the three-field problem with the pressure as an unknown (its right-hand side,
with the dilatation and pressure eliminated, is the same residual). At a predicted state the
pressure ``kappa M^-1 g(u)`` carries ``kappa`` times the predictor's volume error (hundreds of
times the true pressure), and a tangent built on it costs a Newton iteration; the pressure carried
along the path does not (docs/numerics.md, "Newton on the mixed element"). ``kappa = bulk_ratio * mu`` makes the rubber incompressible to
``|J - 1| ~ p / kappa``; the constraint is imposed on the projected dilatation only, so the
element does not lock. ``W_q = w_q det(J0) 2 pi R_q`` carries the axisymmetric weighting: it is
formed in :func:`reference_geometry` and nowhere else.

All arrays in, all arrays out; free-dof indices of -1 denote constrained (zero) dofs.
"""
from __future__ import annotations

import numpy as np
from numba import literally, njit

from snapjump_kernels.cavity import cavity_assemble
from snapjump_kernels.banded import dot_any_order
from snapjump_kernels.gent import gent_iso, gent_scalars, gent_tangent, ibar_gradient


@njit(cache=True)
def reference_geometry(X, conn, dN_ref, N_ref, wq):
    """Reference-configuration quadrature data of every element.

    Returns
    -------
    dNdX : (ne, nq, nen, 2) shape-function gradients w.r.t. (R, Z)
    Rq : (ne, nq) reference radius at the quadrature points
    Wq : (ne, nq) integration weights ``w_q det(J0) 2 pi R_q`` (volume of revolution)
    min_det : smallest Jacobian determinant found (<= 0 means an inverted element)
    """
    ne, nen = conn.shape
    nq = wq.shape[0]
    dNdX = np.empty((ne, nq, nen, 2))
    Rq = np.empty((ne, nq))
    Wq = np.empty((ne, nq))
    min_det = np.inf
    for e in range(ne):
        for q in range(nq):
            j00 = 0.0
            j01 = 0.0
            j10 = 0.0
            j11 = 0.0
            R = 0.0
            for a in range(nen):
                xa = X[conn[e, a], 0]
                ya = X[conn[e, a], 1]
                j00 += dN_ref[q, a, 0] * xa
                j01 += dN_ref[q, a, 1] * xa
                j10 += dN_ref[q, a, 0] * ya
                j11 += dN_ref[q, a, 1] * ya
                R += N_ref[q, a] * xa
            det = j00 * j11 - j01 * j10
            if det < min_det:
                min_det = det
            # inverse of [[dR/dxi, dR/deta], [dZ/dxi, dZ/deta]]
            i00 = j11 / det
            i01 = -j01 / det
            i10 = -j10 / det
            i11 = j00 / det
            for a in range(nen):
                dNdX[e, q, a, 0] = dN_ref[q, a, 0] * i00 + dN_ref[q, a, 1] * i10
                dNdX[e, q, a, 1] = dN_ref[q, a, 0] * i01 + dN_ref[q, a, 1] * i11
            Rq[e, q] = R
            Wq[e, q] = wq[q] * det * 2.0 * np.pi * R
    return dNdX, Rq, Wq, min_det


@njit(cache=True)
def pressure_mass_inverse(Wq, Np):
    """``M^-1`` per element, ``M_kl = sum_q W_q Np_qk Np_ql``; shape (ne, np, np)."""
    ne, nq = Wq.shape
    npr = Np.shape[1]
    Minv = np.empty((ne, npr, npr))
    for e in range(ne):
        M = np.zeros((npr, npr))
        for q in range(nq):
            for k in range(npr):
                for m in range(npr):
                    M[k, m] += Wq[e, q] * Np[q, k] * Np[q, m]
        Minv[e] = np.linalg.inv(M)
    return Minv


@njit(cache=True, inline="always")
def _deformation(u, conn_e, dNdX_eq, N_q, R_q, f):
    f[0] = 1.0
    f[1] = 0.0
    f[2] = 0.0
    f[3] = 1.0
    ur = 0.0
    for a in range(conn_e.shape[0]):
        n = conn_e[a]
        f[0] += u[n, 0] * dNdX_eq[a, 0]
        f[1] += u[n, 0] * dNdX_eq[a, 1]
        f[2] += u[n, 1] * dNdX_eq[a, 0]
        f[3] += u[n, 1] * dNdX_eq[a, 1]
        ur += u[n, 0] * N_q[a]
    f[4] = 1.0 + ur / R_q


#: Elements per batch (lanes) of :func:`assemble`: 8 elements are two AVX2 registers of the
#: vectorised lane loops; 4 (one register) and 16 (arrays spill out of the L1 cache) were slower.
_LANES = 8


@njit(cache=True)
def assemble(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, f_out, data_out,
             p_geo, pb_out, H_out):
    """Strain energy, and for ``want >= 1`` the internal force, for ``want >= 2`` the tangent.

    Parameters
    ----------
    u : (n, 2) nodal displacements
    conn : (ne, nen) connectivity; mat : (ne,) material index into ``mu``, ``jm``, ``kappa``
    dNdX, Rq, Wq : from :func:`reference_geometry`; N_ref (nq, nen); Np (nq, np); Minv (ne, np, np)
    edofs : (ne, 2 nen) free-dof index of each element dof, -1 if constrained
    epos : (ne, 2 nen, 2 nen) position of each element matrix entry in ``data_out``, -1 if not
        stored (constrained, or the upper triangle of a symmetric band storage)
    want : 0 energy, 1 + residual, 2 + tangent
    f_out, data_out : accumulated into (zero them before the call)
    p_geo : (ne, np) element pressures for the tangent's geometric term, or shape (0, np): the
        element's own ``kappa M^-1 g(u)`` (the exact Hessian of the reduced energy)
    pb_out : (ne, np) filled with ``kappa M^-1 g(u)`` per element, or shape (0, np): not wanted
    H_out : (ne, np, 2 nen) filled (``want >= 2``) with ``kappa M^-1 G``, the derivative of the
        element pressure with respect to the element dofs, or shape (0, np, 2 nen): not wanted

    Returns
    -------
    (energy, ok, max_dilatation)
        ``ok`` is False if any quadrature point left the Gent domain (a failed iterate; the other
        outputs are then incomplete); ``max_dilatation`` is the largest ``|theta - 1|`` of the
        projected (constrained) dilatation.

    Notes
    -----
    The Q9 element with 3x3 points and the P1 pressure (the grid's) goes through
    :func:`_assemble_lanes`, compiled for these sizes as constants; every other element table
    (Q4/P0) through the plain element-by-element loop :func:`_assemble_plain`, which compiles in a
    fraction of the time (a lanes version for Q4 added ~20 s to the cold compile for a mesh the
    sweeps do not use). Both compute the energy, force, ``pb_out`` and ``H_out`` in the same order
    (the same floating-point result, bit for bit); the stiffness's sums are ordered differently
    (it differs by round-off).
    """
    nen = conn.shape[1]
    nq = Wq.shape[1]
    npr = Np.shape[1]
    if nen == 9 and nq == 9 and npr == 3:
        return _assemble_lanes(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want,
                               f_out, data_out, p_geo, pb_out, H_out, 9, 9, 3)
    return _assemble_plain(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, f_out,
                           data_out, p_geo, pb_out, H_out)


@njit(cache=True, error_model="numpy")
def _assemble_lanes(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, f_out,
                    data_out, p_geo, pb_out, H_out, NEN, NQ, NPR):
    """:func:`assemble` for ``NEN`` nodes, ``NQ`` points and ``NPR`` pressure modes, compiled for
    each element type with these sizes as constants (:func:`numba.literally`), so that the loops
    over them have constant lengths. (Not ``inline="always"``: numba's inliner deep-copies the
    inlined IR, which for this function cost ~20 s of compile time per copy.)

    The elements are processed ``_LANES`` at a time (a batch; lane ``l`` is element ``e0 + l``).
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
    NB = _LANES
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


@njit(cache=True, inline="always")
def _bt_vec(dNdX_eq, N_q, R_q, v, out):
    """out += B^T v for the 5-component vector ``v`` (B maps element dofs to f)."""
    for a in range(dNdX_eq.shape[0]):
        out[2 * a] += dNdX_eq[a, 0] * v[0] + dNdX_eq[a, 1] * v[1] + N_q[a] / R_q * v[4]
        out[2 * a + 1] += dNdX_eq[a, 0] * v[2] + dNdX_eq[a, 1] * v[3]


@njit(cache=True)
def _assemble_plain(u, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, f_out, data_out,
             p_geo, pb_out, H_out):
    """:func:`assemble` element by element, for any element table (the reference of
    :func:`_assemble_lanes`, and the pass of the elements it is not compiled for)."""
    ne, nen = conn.shape
    nq = Wq.shape[1]
    npr = Np.shape[1]
    nd = 2 * nen
    f, dpsi, d2psi, dJq, d2Jq, fe, Ke, G, H, g, pb, Bt, DBt, D, sv, bt = _work_arrays(nq, npr, nd)
    energy = 0.0
    maxdev = 0.0
    use_geo = p_geo.shape[0] == ne
    keep_pb = pb_out.shape[0] == ne
    keep_H = H_out.shape[0] == ne
    for e in range(ne):
        m_ = mat[e]
        mu_e = mu[m_]
        jm_e = jm[m_]
        ka = kappa[m_]
        g[:] = 0.0
        # pass 1: kinematics, isochoric energy and its derivatives, projected dilatation g
        for q in range(nq):
            _deformation(u, conn[e], dNdX[e, q], N_ref[q], Rq[e, q], f)
            ok, psi, J = gent_iso(f, mu_e, jm_e, want, dpsi[q], d2psi[q], dJq[q], d2Jq[q])
            if not ok:
                return energy, False, maxdev
            W = Wq[e, q]
            energy += W * psi
            for k in range(npr):
                g[k] += W * Np[q, k] * (J - 1.0)
        # volumetric part: pbar = kappa M^-1 g, energy kappa/2 g^T M^-1 g
        for k in range(npr):
            s = 0.0
            for m in range(npr):
                s += Minv[e, k, m] * g[m]
            pb[k] = ka * s
            energy += 0.5 * g[k] * pb[k]
            if keep_pb:
                pb_out[e, k] = pb[k]
        # projected dilatation theta - 1 = p / kappa at the quadrature points (what is constrained)
        for q in range(nq):
            th = 0.0
            for k in range(npr):
                th += Np[q, k] * pb[k]
            dev = abs(th) / ka
            if dev > maxdev:
                maxdev = dev
        if want == 0:
            continue
        # pass 2: stress and tangent with the element pressure at each point
        fe[:] = 0.0
        if want >= 2:
            G[:, :] = 0.0
        for q in range(nq):
            W = Wq[e, q]
            pq = 0.0
            pg = 0.0
            for k in range(npr):
                pq += Np[q, k] * pb[k]
                pg += Np[q, k] * (p_geo[e, k] if use_geo else pb[k])
            for k in range(5):
                sv[k] = W * (dpsi[q, k] + pq * dJq[q, k])
            _bt_vec(dNdX[e, q], N_ref[q], Rq[e, q], sv, fe)
            if want >= 2:
                bt[:] = 0.0
                _bt_vec(dNdX[e, q], N_ref[q], Rq[e, q], dJq[q], bt)
                for k in range(npr):
                    s = W * Np[q, k]
                    for j in range(nd):
                        G[k, j] += s * bt[j]
                for k in range(5):
                    for m in range(5):
                        D[k, m] = W * (d2psi[q, k, m] + pg * d2Jq[q, k, m])
                _stack_b_db(dNdX[e, q], N_ref[q], Rq[e, q], D, 5 * q, Bt, DBt)
        if want >= 2:
            _volumetric_columns(Minv[e], ka, G, H, 5 * nq, Bt, DBt)
            for i in range(nd):  # Ke = sum over the points of B^T D B, + kappa G^T M^-1 G (lower)
                bi = Bt[i]
                for j in range(i + 1):
                    Ke[i, j] = dot_any_order(bi, DBt[j])
            if keep_H:
                H_out[e] = H
        _scatter_element(edofs[e], epos[e], fe, Ke, want, f_out, data_out)
    return energy, True, maxdev


@njit(cache=True, inline="always")
def _work_arrays(nq, npr, nd):
    """Scratch arrays of :func:`assemble` for elements with ``nq`` quadrature points, ``npr``
    pressure modes and ``nd`` dofs: ``f, dpsi, d2psi, dJq, d2Jq, fe, Ke, G, H, g, pb, Bt, DBt, D, sv, bt``
    (``Bt``, ``DBt``: see :func:`_stack_b_db`)."""
    f = np.empty(5)
    dpsi = np.zeros((nq, 5))
    d2psi = np.zeros((nq, 5, 5))
    dJq = np.empty((nq, 5))
    d2Jq = np.empty((nq, 5, 5))
    fe = np.empty(nd)
    Ke = np.empty((nd, nd))
    G = np.empty((npr, nd))
    H = np.empty((npr, nd))
    g = np.empty(npr)
    pb = np.empty(npr)
    Bt = np.zeros((nd, 5 * nq + npr))  # its structural zeros are never overwritten (_stack_b_db)
    DBt = np.empty((nd, 5 * nq + npr))
    D = np.empty((5, 5))
    sv = np.empty(5)
    bt = np.empty(nd)
    return f, dpsi, d2psi, dJq, d2Jq, fe, Ke, G, H, g, pb, Bt, DBt, D, sv, bt


@njit(cache=True, inline="always")
def _volumetric_columns(Minv_e, ka, G, H, c0, Bt, DBt):
    """``H = kappa M^-1 G`` (the element pressures' derivative), and ``G``, ``H`` as the columns
    ``c0 ..`` of ``Bt`` and ``DBt``: their row products then add ``kappa G^T M^-1 G = G^T H``."""
    npr, nd = G.shape
    for k in range(npr):
        for j in range(nd):
            s = 0.0
            for m in range(npr):
                s += Minv_e[k, m] * G[m, j]
            H[k, j] = ka * s
    for k in range(npr):
        for i in range(nd):
            Bt[i, c0 + k] = G[k, i]
            DBt[i, c0 + k] = H[k, i]


@njit(cache=True, inline="always")
def _stack_b_db(dNdX_eq, N_q, R_q, D, c, Bt, DBt):
    """One quadrature point's columns ``c .. c + 4`` of ``Bt = B^T`` and ``DBt = (D B)^T``
    (B sparse: rows 0, 1, 4 for a u_r dof, rows 2, 3 for a u_z dof). With every point's columns
    side by side, the element stiffness is the row products ``Ke[i, j] = Bt[i] . DBt[j]``: dot
    products ~50 long, which vectorise, where accumulating ``B^T D B`` point by point ran
    triangular loops 1-18 long (the element pass 15-20 % faster; the sums are reordered, so the
    stiffness changes by round-off). Only ``B``'s non-zeros are written: its zeros in ``Bt`` are
    those :func:`_work_arrays` allocated."""
    nen = dNdX_eq.shape[0]
    for a in range(nen):
        bx = dNdX_eq[a, 0]
        by = dNdX_eq[a, 1]
        bn = N_q[a] / R_q
        r = Bt[2 * a]  # B's zeros in these columns stay as _work_arrays set them
        z = Bt[2 * a + 1]
        r[c] = bx
        r[c + 1] = by
        r[c + 4] = bn
        z[c + 2] = bx
        z[c + 3] = by
        dr = DBt[2 * a]
        dz = DBt[2 * a + 1]
        for k in range(5):
            dr[c + k] = D[k, 0] * bx + D[k, 1] * by + D[k, 4] * bn
            dz[c + k] = D[k, 2] * bx + D[k, 3] * by


@njit(cache=True, inline="always")
def _scatter_element(edofs_e, epos_e, fe, Ke, want, f_out, data_out):
    """Add an element's force ``fe`` (and for ``want >= 2`` its stiffness; ``Ke`` holds the lower
    triangle of a symmetric matrix) into ``f_out`` and ``data_out`` (``edofs_e``, ``epos_e``: the
    element's rows of ``edofs`` and ``epos``)."""
    for i in range(fe.shape[0]):
        di = edofs_e[i]
        if di < 0:
            continue
        f_out[di] += fe[i]
        if want >= 2:
            for j in range(i + 1):
                v = Ke[i, j]
                pij = epos_e[i, j]
                if pij >= 0:
                    data_out[pij] += v
                if j != i:
                    pji = epos_e[j, i]
                    if pji >= 0:
                        data_out[pji] += v


@njit(cache=True)
def quadrature_jacobians(u, conn, dNdX, N_ref, Rq):
    """``J`` at every quadrature point, shape (ne, nq) (a diagnostic: volume preservation)."""
    ne = conn.shape[0]
    nq = Rq.shape[1]
    out = np.empty((ne, nq))
    f = np.empty(5)
    for e in range(ne):
        for q in range(nq):
            _deformation(u, conn[e], dNdX[e, q], N_ref[q], Rq[e, q], f)
            out[e, q] = (f[0] * f[3] - f[1] * f[2]) * f[4]
    return out


@njit(cache=True, inline="always")
def nodal_displacements(u, dofmap):
    """The (n_nodes, 2) displacements of the free-dof vector ``u`` (``dofmap[node, component]``:
    free dof or -1 for a constrained, zero one)."""
    nn = dofmap.shape[0]
    U = np.zeros((nn, 2))
    for a in range(nn):
        for c in range(2):
            k = dofmap[a, c]
            if k >= 0:
                U[a, c] = u[k]
    return U


@njit(cache=True)
def evaluate(u, dofmap, X, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos,
             edges, edge_dofs, edge_pos, p, want, R_out, g_out, data_out, p_geo, pb_out, H_out):
    """One evaluation of the pressurised solid at the free-dof displacement ``u`` (one call).

    Scatters ``u`` to the nodes (``dofmap[node, component]``: free dof or -1), assembles the
    element energy, force and (``want >= 2``) stiffness (:func:`assemble`), then the cavity volume,
    its gradient ``g = dV/du`` and (``want >= 2``) the load stiffness ``-p d2V/du2``
    (:func:`snapjump_kernels.cavity.cavity_assemble`). Fills ``R_out = f_int - p g``, ``g_out``
    and ``data_out`` (zeroed by the caller); ``p_geo``, ``pb_out``, ``H_out`` as in :func:`assemble`.

    Returns
    -------
    (energy, ok, V) : the strain energy, False outside the material domain, the cavity volume
        (without any offset)
    """
    U = nodal_displacements(u, dofmap)
    E, ok, _ = assemble(U, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos, want, R_out,
                        data_out, p_geo, pb_out, H_out)
    V = cavity_assemble(X + U, edges, edge_dofs, edge_pos, -p, max(want, 1), g_out, data_out)
    for i in range(R_out.shape[0]):
        R_out[i] -= p * g_out[i]
    return E, ok, V


@njit(cache=True)
def cavity_state(u, dofmap, X, edges, edge_dofs, edge_pos, g_out):
    """Cavity volume (without any offset) at the free-dof displacement ``u``; fills ``g_out`` with
    ``dV/du`` (zeroed here). The cavity part of :func:`evaluate` alone (no element pass)."""
    U = nodal_displacements(u, dofmap)
    g_out[:] = 0.0
    return cavity_assemble(X + U, edges, edge_dofs, edge_pos, 0.0, np.int64(1), g_out, np.zeros(1))
