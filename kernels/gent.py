"""Incompressible Gent energy density in axisymmetric deformation-gradient components.

The deformation gradient of an axisymmetric motion ``(R, Z) -> (r, z)`` has five non-zero
components, stored as ``f = [F_rR, F_rZ, F_zR, F_zZ, F_theta]`` with ``F_theta = r / R``.
Energy density (per unit reference volume), isochoric/volumetric split::

    psi_iso(f) = -(mu J_m / 2) ln(1 - (Ibar_1 - 3) / J_m),   Ibar_1 = J^(-2/3) I_1,
    J = (F_rR F_zZ - F_rZ F_zR) F_theta.

Its derivatives go through ``Ibar_1``: with ``c = J^(-2/3)``, ``a = dpsi/dIbar_1 = (mu/2) / arg``
and ``b = d2psi/dIbar_1^2 = (mu/2) / (J_m arg^2)`` (``arg = 1 - (Ibar_1 - 3) / J_m``)::

    dpsi = a dIbar,                     dIbar = 2 c f - (2/3) (c/J) I_1 dJ,
    d2psi = a d2Ibar + b dIbar dIbar^T,
    d2Ibar = 2 c 1 - (2/3) (c/J) (2 f dJ^T + 2 dJ f^T + I_1 d2J) + (10/9) (c/J^2) I_1 dJ dJ^T.

:func:`gent_iso` evaluates them as arrays at one point; :func:`gent_scalars`,
:func:`ibar_gradient` and :func:`gent_tangent` are the same formulas on scalars, for the
element loops of :mod:`snapjump_kernels.assembly` (which run over a batch of elements at once and
keep each point's values in registers). The volumetric part (the incompressibility constraint) is
handled by the mixed element in :mod:`snapjump_kernels.assembly`. Outside the Gent domain
(``Ibar_1 - 3 >= J_m`` or ``J <= 0``) the functions return ``False``: the caller treats that
iterate as failed (docs/physics.md, pitfall c).
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
def gent_scalars(J, I1, mu, jm):
    """Energy density and the scalar factors of its derivatives, from ``J > 0`` and ``I_1``.

    Returns
    -------
    (ok, psi, c, a, b) : (bool, float, float, float, float)
        ``c = J^(-2/3)``, ``a = dpsi/dIbar_1``, ``b = d2psi/dIbar_1^2``; ``ok`` is False outside
        the Gent domain (``Ibar_1 - 3 >= J_m``; ``psi``, ``a``, ``b`` are then finite but
        meaningless). Without branches: the element loops evaluate it for several elements at once.
    """
    c = J ** (-2.0 / 3.0)
    Ib = c * I1
    arg = 1.0 - (Ib - 3.0) / jm
    ok = arg > 0.0
    s = arg if ok else 1.0  # outside the domain: no log of a negative number, no division by 0
    psi = -0.5 * mu * jm * np.log(s)
    a = 0.5 * mu / s
    b = 0.5 * mu / (jm * s * s)
    return ok, psi, c, a, b


@njit(cache=True, inline="always")
def ibar_gradient(f0, f1, f2, f3, f4, dJ0, dJ1, dJ2, dJ3, dJ4, J, I1, c):
    """``dIbar_1/df = 2 c f - (2/3) (c/J) I_1 dJ`` (five floats), ``c = J^(-2/3)``."""
    t = (2.0 / 3.0) * c / J * I1
    c2 = c * 2.0
    return c2 * f0 - t * dJ0, c2 * f1 - t * dJ1, c2 * f2 - t * dJ2, c2 * f3 - t * dJ3, c2 * f4 - t * dJ4


@njit(cache=True, inline="always")
def gent_tangent(w, p, f0, f1, f2, f3, f4, dJ0, dJ1, dJ2, dJ3, dJ4, i0, i1, i2, i3, i4, J, I1, c, a, b):
    """``w (d2psi + p d2J)``: the material tangent of one quadrature point in the five components.

    ``dJ*`` is ``dJ/df``, ``i*`` is ``dIbar_1/df`` (:func:`ibar_gradient`), ``c``, ``a``, ``b`` as
    returned by :func:`gent_scalars`; ``w`` is the point's integration weight and ``p`` the
    pressure of the geometric term. Returns the upper triangle row by row (15 floats:
    ``D00, D01, D02, D03, D04, D11, D12, D13, D14, D22, D23, D24, D33, D34, D44``).
    """
    cJ = (2.0 / 3.0) * c / J
    wa = w * a
    A = -2.0 * wa * cJ  # w a (-(2/3)(c/J)) 2 (f dJ^T + dJ f^T)
    B = wa * (10.0 / 9.0) * c / (J * J) * I1  # w a (10/9)(c/J^2) I_1 dJ dJ^T
    wb = w * b  # w b dIbar dIbar^T
    g = w * (p - a * cJ * I1)  # w (p - a (2/3)(c/J) I_1) d2J
    d = 2.0 * wa * c  # w a 2 c 1
    # d2J has the non-zeros (0,3) = f4, (1,2) = -f4, (0,4) = f3, (3,4) = f0, (1,4) = -f2, (2,4) = -f1
    return (A * (f0 * dJ0 + f0 * dJ0) + B * dJ0 * dJ0 + wb * i0 * i0 + d,
            A * (f0 * dJ1 + f1 * dJ0) + B * dJ0 * dJ1 + wb * i0 * i1,
            A * (f0 * dJ2 + f2 * dJ0) + B * dJ0 * dJ2 + wb * i0 * i2,
            A * (f0 * dJ3 + f3 * dJ0) + B * dJ0 * dJ3 + wb * i0 * i3 + g * f4,
            A * (f0 * dJ4 + f4 * dJ0) + B * dJ0 * dJ4 + wb * i0 * i4 + g * f3,
            A * (f1 * dJ1 + f1 * dJ1) + B * dJ1 * dJ1 + wb * i1 * i1 + d,
            A * (f1 * dJ2 + f2 * dJ1) + B * dJ1 * dJ2 + wb * i1 * i2 - g * f4,
            A * (f1 * dJ3 + f3 * dJ1) + B * dJ1 * dJ3 + wb * i1 * i3,
            A * (f1 * dJ4 + f4 * dJ1) + B * dJ1 * dJ4 + wb * i1 * i4 - g * f2,
            A * (f2 * dJ2 + f2 * dJ2) + B * dJ2 * dJ2 + wb * i2 * i2 + d,
            A * (f2 * dJ3 + f3 * dJ2) + B * dJ2 * dJ3 + wb * i2 * i3,
            A * (f2 * dJ4 + f4 * dJ2) + B * dJ2 * dJ4 + wb * i2 * i4 - g * f1,
            A * (f3 * dJ3 + f3 * dJ3) + B * dJ3 * dJ3 + wb * i3 * i3 + d,
            A * (f3 * dJ4 + f4 * dJ3) + B * dJ3 * dJ4 + wb * i3 * i4 + g * f0,
            A * (f4 * dJ4 + f4 * dJ4) + B * dJ4 * dJ4 + wb * i4 * i4 + d)


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
    ok, psi, c, a, b = gent_scalars(J, I1, mu, jm)
    if not ok:
        return False, 0.0, J
    if want >= 1:
        cJ = (2.0 / 3.0) * c / J  # -d c / dJ
        # dIb = c dI1 - (2/3) c/J I1 dJ
        for k in range(5):
            dpsi[k] = a * (c * 2.0 * f[k] - cJ * I1 * dJ[k])
        if want >= 2:
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
