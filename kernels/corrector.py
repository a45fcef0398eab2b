"""The continuation's Newton corrector as one compiled call (no Python between its iterations).

It is :meth:`snapjump_cli.fe.continuation.tracer.Tracer.correct` for the pressurised solid of
:mod:`snapjump_kernels.assembly` with the path measures ``zeta = (V / s_V, p / s_p, w / s_w)``
(cavity volume, pressure, pole displacement): each iteration evaluates the residual and the
stiffness (:func:`snapjump_kernels.assembly.evaluate`), factorises the bordered matrix and solves
it (:mod:`snapjump_kernels.banded`; the tangent with one step of iterative refinement, the Newton
corrections without: the next iteration corrects them).

Two convergence tests:

* residual (snap states, limit points, targets): the constraint below ``tol max(1, |ds|)`` and
  the residual below ``tol`` times the pressure load ``|dV/du| max(|p|, 1e-3 s_p)``, or below
  ``100 tol`` after a negligible correction;
* error (ordinary path points, ``tol_inc > 0``): the Newton correction computed at the iterate,
  measured in the arc-length metric (the scaled measures and the weighted displacement), below
  ``tol_inc`` and smaller than the one before. That correction estimates the iterate's error; the
  residual of the reduced (displacement-only) equations is not a good one for a nearly
  incompressible solid, as ``kappa`` times a tiny volume error dominates it. The accepted state is
  the iterate plus that correction (its error is of the order of the correction squared), with
  its cavity volume and ``dV/du`` evaluated there and the element pressures of the mixed update;
  its residual, stiffness and energy are not evaluated (``R`` and ``data`` returned are those of
  the iterate, ``E`` is NaN).

Mixed linearisation (``p_geo0`` given): the tangent's geometric term takes the element pressure
from the Newton iteration of the three-field problem (start: ``p_geo0``, the pressure carried
along the path; then the linearised update ``kappa M^-1 (g(u) + G du)``) instead of
``kappa M^-1 g(u)`` (:func:`snapjump_kernels.assembly.assemble`). The residual, and hence the
converged state, is the same.

With the Riks constraint the call also returns the path tangent at the accepted state, solved with
the bordered matrix of the last iteration (whose border row is the previous tangent's, as
:meth:`snapjump_cli.fe.continuation.tracer.Tracer.tangent` uses): ``[[K, -g], [c^T, c_p]] [v; q] = [0; 1]``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.assembly import cavity_state, evaluate
from snapjump_kernels.banded import bordered_factor, bordered_solve


@njit(cache=True)
def _element_update(edofs, H, x, base, out):
    """``out[e] = base[e] + H[e] @ x[edofs[e]]`` (constrained dofs, ``-1``, count as zero)."""
    ne, npr, nd = H.shape
    for e in range(ne):
        for k in range(npr):
            s = base[e, k]
            for j in range(nd):
                d = edofs[e, j]
                if d >= 0:
                    s += H[e, k, j] * x[d]
            out[e, k] = s


@njit(cache=True)
def newton_correct(u0, p0, target_k, target_val, z0, t_z, t_u, u_ref, ds, alpha2, sc, tol, max_newton,
                   pole_dof, V_offset, kl, ext, dofmap, X, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv,
                   edofs, epos, edges, edge_dofs, edge_pos, p_geo0, tol_inc, theta_max):
    """Newton on ``R(u, p) = 0`` and one constraint: ``target_k >= 0`` fixes the scaled measure
    ``zeta_k = target_val``; ``target_k < 0`` is the Riks hyperplane
    ``t_z . (zeta - z0) + alpha2 t_u . (u - u_ref) = ds``.

    ``p_geo0`` (ne, np): the element pressures to start the mixed linearisation from, or shape
    (0, np) for the reduced one; ``tol_inc > 0`` accepts an iterate by the error test (Riks only),
    and then Newton gives up as soon as a correction above ``tol_inc`` is more than ``theta_max``
    times the one before (no contraction: the caller halves the step instead of iterating on).

    Returns
    -------
    (ok, iterations, factorisations, u, p, R, g, data, V, E, p_el, xt, n_neg, schur, dp_el)
        the accepted state with its residual, ``dV/du``, stiffness (band storage, flat), cavity
        volume (with ``V_offset``) and strain energy; ``ok`` False if Newton failed (material
        domain left, singular matrix, no convergence in ``max_newton`` iterations). ``p_el``: the
        element pressures at the state (the linearised update after an error-test acceptance).
        Riks only (else empty / 0): ``xt`` the unnormalised tangent ``[v; q]``, ``n_neg`` the
        negative pivots of ``K`` and ``schur`` the bordered matrix's Schur complement of that
        factorisation, ``dp_el = H v`` the element pressures' derivative along ``v``.
    """
    n = u0.shape[0]
    ne = conn.shape[0]
    npr = Np.shape[1]
    nd = edofs.shape[1]
    riks = target_k < 0
    mixed = p_geo0.shape[0] == ne
    u = u0.copy()
    p = p0
    R = np.zeros(n)
    g = np.zeros(n)
    data = np.zeros(n * (kl + 1))
    c_u = np.empty(n)
    rhs = np.empty(n + 1)
    pg = p_geo0.copy() if mixed else np.zeros((0, npr))
    pb = np.zeros((ne, npr))
    H = np.zeros((ne, npr, nd)) if (riks or mixed) else np.zeros((0, npr, nd))
    p_el = np.zeros((ne, npr))
    dp_el = np.zeros((ne, npr))
    empty = np.zeros(0)
    step_small = False
    n_fac = 0
    E = 0.0
    Vt = 0.0
    inc_prev = np.inf
    # a typed int, not the constant 2: numba would compile evaluate and the element pass a second
    # time for the argument type Literal[int](2)
    want = np.int64(2)
    for it in range(max_newton + 1):
        R[:] = 0.0
        g[:] = 0.0
        data[:] = 0.0
        E, ok, V = evaluate(u, dofmap, X, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos,
                            edges, edge_dofs, edge_pos, p, want, R, g, data, pg, pb, H)
        if not ok:
            return False, it, n_fac, u, p, R, g, data, 0.0, 0.0, pb, empty, 0, 0.0, dp_el
        Vt = V + V_offset
        z0_ = Vt / sc[0]
        z1_ = p / sc[1]
        z2_ = u[pole_dof] / sc[2]
        if riks:
            hu = 0.0
            for i in range(n):
                hu += t_u[i] * (u[i] - u_ref[i])
            h = t_z[0] * (z0_ - z0[0]) + t_z[1] * (z1_ - z0[1]) + t_z[2] * (z2_ - z0[2]) + alpha2 * hu - ds
            for i in range(n):
                c_u[i] = t_z[0] * (g[i] / sc[0]) + alpha2 * t_u[i]
            c_u[pole_dof] += t_z[2] / sc[2]
            c_p = t_z[1] / sc[1]
        else:
            if target_k == 0:
                h = z0_ - target_val
                for i in range(n):
                    c_u[i] = g[i] / sc[0]
                c_p = 0.0
            elif target_k == 1:
                h = z1_ - target_val
                c_u[:] = 0.0
                c_p = 1.0 / sc[1]
            else:
                h = z2_ - target_val
                c_u[:] = 0.0
                c_u[pole_dof] = 1.0 / sc[2]
                c_p = 0.0
        gn = 0.0
        rr = 0.0
        for i in range(n):
            gn += g[i] * g[i]
            rr += R[i] * R[i]
        ref = np.sqrt(gn) * max(abs(p), 1e-3 * sc[1])
        rn = np.sqrt(rr) / ref
        converged = it > 0 and abs(h) < tol * max(1.0, abs(ds)) and (
            rn < tol or (step_small and rn < 100.0 * tol))
        if converged and not riks:
            return True, it, n_fac, u, p, R, g, data, Vt, E, pb, empty, 0, 0.0, dp_el
        if not converged and (it == max_newton or not np.isfinite(rn)):
            return False, it, n_fac, u, p, R, g, data, Vt, E, pb, empty, 0, 0.0, dp_el
        K = data.reshape(n, kl + 1)
        b = -g
        okf, nneg, fac, Kib, schur = bordered_factor(K, ext, b, c_u, c_p)
        n_fac += 1
        if not okf or not np.isfinite(schur) or schur == 0.0:
            return False, it, n_fac, u, p, R, g, data, Vt, E, pb, empty, 0, 0.0, dp_el
        if converged:  # Riks, by the residual test: the tangent from this factorisation
            rhs[:] = 0.0
            rhs[n] = 1.0
            xt = bordered_solve(fac, K, ext, b, c_u, c_p, Kib, schur, rhs, True)
            _element_update(edofs, H, xt, np.zeros((ne, npr)), dp_el)
            return True, it, n_fac, u, p, R, g, data, Vt, E, pb, xt, nneg, schur, dp_el
        for i in range(n):
            rhs[i] = -R[i]
        rhs[n] = -h
        # the correction without the refinement step (the tangent solves keep it): Newton's next
        # iteration corrects its error, and on the regression sample the iteration counts and
        # answers are the same (to 1e-8) with and without it
        x = bordered_solve(fac, K, ext, b, c_u, c_p, Kib, schur, rhs, False)
        dV = 0.0
        uu = 0.0
        for i in range(n):
            if not np.isfinite(x[i]):
                return False, it, n_fac, u, p, R, g, data, Vt, E, pb, empty, 0, 0.0, dp_el
            dV += g[i] * x[i]
            uu += x[i] * x[i]
        if not np.isfinite(x[n]):
            return False, it, n_fac, u, p, R, g, data, Vt, E, pb, empty, 0, 0.0, dp_el
        dz0 = dV / sc[0]
        dz1 = x[n] / sc[1]
        dz2 = x[pole_dof] / sc[2]
        inc = np.sqrt(dz0 * dz0 + dz1 * dz1 + dz2 * dz2 + alpha2 * uu)
        if riks and tol_inc > 0.0 and it > 0 and inc < tol_inc and inc < inc_prev:
            # accepted by the error test: the corrected iterate; the tangent from this factorisation
            _element_update(edofs, H, x, pb, p_el)
            rhs[:] = 0.0
            rhs[n] = 1.0
            xt = bordered_solve(fac, K, ext, b, c_u, c_p, Kib, schur, rhs, True)
            _element_update(edofs, H, xt, np.zeros((ne, npr)), dp_el)
            for i in range(n):
                u[i] += x[i]
            p += x[n]
            Vt = cavity_state(u, dofmap, X, edges, edge_dofs, edge_pos, g) + V_offset
            return True, it, n_fac, u, p, R, g, data, Vt, np.nan, p_el, xt, nneg, schur, dp_el
        if riks and tol_inc > 0.0 and it > 0 and inc >= tol_inc and inc > theta_max * inc_prev:
            return False, it, n_fac, u, p, R, g, data, Vt, E, pb, empty, 0, 0.0, dp_el
        inc_prev = inc
        if mixed:  # the three-field Newton's pressure update
            _element_update(edofs, H, x, pb, pg)
        for i in range(n):
            u[i] += x[i]
        p += x[n]
        step_small = np.sqrt(dz0 * dz0 + dz1 * dz1 + dz2 * dz2) < 1e-12
    return False, max_newton, n_fac, u, p, R, g, data, Vt, E, pb, empty, 0, 0.0, dp_el
