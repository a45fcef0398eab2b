"""Incompressible Gent energy density in axisymmetric deformation-gradient components.

The deformation gradient of an axisymmetric motion ``(R, Z) -> (r, z)`` has five non-zero
components, stored as ``f = [F_rR, F_rZ, F_zR, F_zZ, F_theta]`` with ``F_theta = r / R``.
Energy density (per unit reference volume), isochoric/volumetric split::

    psi_iso(f) = -(mu J_m / 2) ln(1 - (Ibar_1 - 3) / J_m),   Ibar_1 = J^(-2/3) I_1,
    J = (F_rR F_zZ - F_rZ F_zR) F_theta.

The volumetric part (the incompressibility constraint) is handled by the mixed element in
:mod:`snapjump_kernels.assembly`. Outside the Gent domain (``Ibar_1 - 3 >= J_m`` or ``J <= 0``)
the functions return ``False``: the caller treats that iterate as failed (docs/physics.md,
pitfall c).
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def jacobian_derivs(f: np.ndarray, dJ: np.ndarray, d2J: np.ndarray) -> float:
    """``J`` of ``f``; fills its gradient ``dJ`` (5,) and Hessian ``d2J`` (5, 5)."""
    a = f[0] * f[3] - f[1] * f[2]
    J = a * f[4]
    dJ[0] = f[3] * f[4]
    dJ[1] = -f[2] * f[4]
    dJ[2] = -f[1] * f[4]
    dJ[3] = f[0] * f[4]
    dJ[4] = a
    d2J[:, :] = 0.0
    d2J[0, 3] = d2J[3, 0] = f[4]
    d2J[1, 2] = d2J[2, 1] = -f[4]
    d2J[0, 4] = d2J[4, 0] = f[3]
    d2J[3, 4] = d2J[4, 3] = f[0]
    d2J[1, 4] = d2J[4, 1] = -f[2]
    d2J[2, 4] = d2J[4, 2] = -f[1]
    return J


@njit(cache=True, inline="always")
def gent_iso(f, mu, jm, want, dpsi, d2psi, dJ, d2J):
    """Isochoric Gent energy density and (for ``want >= 1``/``2``) its first/second derivatives.

    Returns
    -------
    (ok, psi, J) : (bool, float, float)
        ``ok`` is False outside the Gent domain; ``dJ`` and ``d2J`` are always filled.
    """
    J = jacobian_derivs(f, dJ, d2J)
    if J <= 0.0:
        return False, 0.0, J
    I1 = 0.0
    for k in range(5):
        I1 += f[k] * f[k]
    c = J ** (-2.0 / 3.0)
    Ib = c * I1
    arg = 1.0 - (Ib - 3.0) / jm
    if arg <= 0.0:
        return False, 0.0, J
    psi = -0.5 * mu * jm * np.log(arg)
    if want >= 1:
        a = 0.5 * mu / arg  # dpsi/dIb
        cJ = (2.0 / 3.0) * c / J  # -d c / dJ
        # dIb = c dI1 - (2/3) c/J I1 dJ
        for k in range(5):
            dpsi[k] = a * (c * 2.0 * f[k] - cJ * I1 * dJ[k])
        if want >= 2:
            b = 0.5 * mu / (jm * arg * arg)  # d2psi/dIb2
            inv_a = 1.0 / a
            for k in range(5):  # symmetric: the upper triangle, mirrored
                for m in range(k, 5):
                    d2 = (
                        -cJ * (2.0 * f[k] * dJ[m] + 2.0 * f[m] * dJ[k])
                        + (10.0 / 9.0) * c / (J * J) * I1 * dJ[k] * dJ[m]
                        - cJ * I1 * d2J[k, m]
                    )
                    if k == m:
                        d2 += 2.0 * c
                    # dpsi[k] / a = dIb_k
                    v = a * d2 + b * (dpsi[k] * inv_a) * (dpsi[m] * inv_a)
                    d2psi[k, m] = v
                    d2psi[m, k] = v
    return True, psi, J
