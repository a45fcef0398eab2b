"""The deformation gradient of the axisymmetric solid at one quadrature point, shared by the
element passes (:mod:`snapjump_kernels.element_lanes`, :mod:`snapjump_kernels.element_plain`),
the diagnostics of :mod:`snapjump_kernels.assembly` and the harmonic tangents."""
from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def deformation(u, conn_e, dNdX_eq, N_q, R_q, f):
    """Fill ``f`` with the deformation gradient's components ``(F_rR, F_rZ, F_zR, F_zZ, F_tt)`` at a
    quadrature point of the element with nodes ``conn_e`` (``u``: (n, 2) nodal displacements;
    ``dNdX_eq``, ``N_q``, ``R_q``: the point's shape-function gradients, values and radius)."""
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
