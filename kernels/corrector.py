"""The continuation's Newton corrector as one compiled call (no Python between its iterations).

It is :meth:`snapjump_cli.continuation.Tracer.correct` for the pressurised solid of
:mod:`snapjump_kernels.assembly` with the path measures ``zeta = (V / s_V, p / s_p, w / s_w)``
(cavity volume, pressure, pole displacement): each iteration evaluates the residual and the
stiffness (:func:`snapjump_kernels.assembly.evaluate`), factorises the bordered matrix and solves
it with one step of refinement (:mod:`snapjump_kernels.banded`). The same convergence test: the
constraint below ``tol max(1, |ds|)`` and the residual below ``tol`` times the pressure load
``|dV/du| max(|p|, 1e-3 s_p)``, or below ``100 tol`` after a negligible correction.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from snapjump_kernels.assembly import evaluate
from snapjump_kernels.banded import bordered_factor, bordered_solve


@njit(cache=True)
def newton_correct(u0, p0, target_k, target_val, z0, t_z, t_u, u_ref, ds, alpha2, sc, tol, max_newton,
                   pole_dof, V_offset, kl, ext, dofmap, X, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv,
                   edofs, epos, edges, edge_dofs, edge_pos):
    """Newton on ``R(u, p) = 0`` and one constraint: ``target_k >= 0`` fixes the scaled measure
    ``zeta_k = target_val``; ``target_k < 0`` is the Riks hyperplane
    ``t_z . (zeta - z0) + alpha2 t_u . (u - u_ref) = ds``.

    Returns
    -------
    (ok, iterations, factorisations, u, p, R, g, data, V, E)
        the converged state with its residual, ``dV/du``, stiffness (band storage, flat), cavity
        volume (with ``V_offset``) and strain energy; ``ok`` False if Newton failed (material
        domain left, singular matrix, no convergence in ``max_newton`` iterations).
    """
    n = u0.shape[0]
    u = u0.copy()
    p = p0
    R = np.zeros(n)
    g = np.zeros(n)
    data = np.zeros(n * (kl + 1))
    c_u = np.empty(n)
    rhs = np.empty(n + 1)
    step_small = False
    n_fac = 0
    E = 0.0
    Vt = 0.0
    for it in range(max_newton + 1):
        R[:] = 0.0
        g[:] = 0.0
        data[:] = 0.0
        E, ok, V = evaluate(u, dofmap, X, conn, mat, mu, jm, kappa, dNdX, N_ref, Rq, Wq, Np, Minv, edofs, epos,
                            edges, edge_dofs, edge_pos, p, 2, R, g, data)
        if not ok:
            return False, it, n_fac, u, p, R, g, data, 0.0, 0.0
        Vt = V + V_offset
        z0_ = Vt / sc[0]
        z1_ = p / sc[1]
        z2_ = u[pole_dof] / sc[2]
        if target_k < 0:
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
        if it > 0 and abs(h) < tol * max(1.0, abs(ds)):
            if rn < tol or (step_small and rn < 100.0 * tol):
                return True, it, n_fac, u, p, R, g, data, Vt, E
        if it == max_newton or not np.isfinite(rn):
            return False, it, n_fac, u, p, R, g, data, Vt, E
        K = data.reshape(n, kl + 1)
        b = -g
        okf, nneg, fac, Kib, schur = bordered_factor(K, ext, b, c_u, c_p)
        n_fac += 1
        if not okf or not np.isfinite(schur) or schur == 0.0:
            return False, it, n_fac, u, p, R, g, data, Vt, E
        for i in range(n):
            rhs[i] = -R[i]
        rhs[n] = -h
        x = bordered_solve(fac, K, ext, b, c_u, c_p, Kib, schur, rhs, True)
        dV = 0.0
        for i in range(n):
            if not np.isfinite(x[i]):
                return False, it, n_fac, u, p, R, g, data, Vt, E
            dV += g[i] * x[i]
        if not np.isfinite(x[n]):
            return False, it, n_fac, u, p, R, g, data, Vt, E
        dz0 = dV / sc[0]
        dz1 = x[n] / sc[1]
        dz2 = x[pole_dof] / sc[2]
        for i in range(n):
            u[i] += x[i]
        p += x[n]
        step_small = np.sqrt(dz0 * dz0 + dz1 * dz1 + dz2 * dz2) < 1e-12
    return False, max_newton, n_fac, u, p, R, g, data, Vt, E
