"""Analytic benchmark: inflation of a thick-walled incompressible Gent hollow sphere.

A fixture of the tests (``from tests.sphere import sphere_mesh``). The sphere (inner radius ``A``, outer ``B``)
is modelled as a quarter annulus in the (r, y) plane with ``u_y = 0`` on the equatorial plane.

Closed form. With ``r^3 = R^3 + a^3 - A^3`` (incompressibility) and the hoop stretch
``lam = r / R``, radial equilibrium ``d sigma_rr / dr = 2 (sigma_tt - sigma_rr) / r`` integrated
from the loaded inner surface (``sigma_rr = -p``) to the free outer surface gives::

    p(a) = int_a^b  2 (sigma_tt - sigma_rr) / r  dr,
    sigma_tt - sigma_rr = 2 W_1 (lam^2 - lam^-4),   W_1 = (mu / 2) / (1 - (I_1 - 3) / J_m),
    I_1 = lam^-4 + 2 lam^2.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import quad

from snapjump_cli.mesh.data import Mesh, REGION_INNER_CAP

__all__ = ["sphere_pressure", "sphere_mesh"]


def sphere_pressure(a: float, A: float, B: float, mu: float, J_m: float) -> float:
    """Exact internal pressure of the Gent hollow sphere whose inner radius is inflated to ``a``."""
    c = a**3 - A**3
    b = (B**3 + c) ** (1.0 / 3.0)

    def integrand(r: float) -> float:
        R = (r**3 - c) ** (1.0 / 3.0)
        lam = r / R
        I1 = lam**-4 + 2 * lam**2
        W1 = 0.5 * mu / (1.0 - (I1 - 3.0) / J_m)
        return 2.0 * 2.0 * W1 * (lam**2 - lam**-4) / r

    val, _ = quad(integrand, a, b, epsabs=0.0, epsrel=1e-10, limit=400)
    return val


def sphere_mesh(A: float, B: float, nt: int, n_arc: int, order: int = 2, full: bool = False) -> Mesh:
    """Structured quarter-annulus mesh of the hollow sphere (exact arcs; Q4 or Q9).

    ``edge_sets["cavity"]`` runs along the inner surface from the equator to the pole, so the
    cavity volume is that of the upper half sphere, ``2/3 pi a^3``. With ``full`` the mesh is the
    half annulus from the south to the north pole (the complete sphere, ``n_arc`` elements over
    180 deg), free: both poles are on the axis and one node on the outer equator carries
    ``u_y = 0`` only to remove the vertical translation of the axisymmetric problem.
    """
    nr, na = order * nt + 1, order * n_arc + 1
    rho = np.linspace(A, B, nr)
    phi = np.linspace(math.pi if full else 0.5 * math.pi, 0.0, na)  # (south pole or) equator -> pole
    P, F = np.meshgrid(rho, phi, indexing="ij")
    nodes = np.stack([P * np.sin(F), P * np.cos(F)], axis=-1).reshape(-1, 2)
    nodes[np.abs(nodes[:, 0]) < 1e-14 * B, 0] = 0.0
    nodes[np.abs(nodes[:, 1]) < 1e-14 * B, 1] = 0.0
    idx = np.arange(nr * na).reshape(nr, na)
    els = []
    for i in range(0, nr - 1, order):
        for j in range(0, na - 1, order):
            if order == 1:
                els.append([idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]])
            else:
                els.append(
                    [idx[i, j], idx[i + 2, j], idx[i + 2, j + 2], idx[i, j + 2],
                     idx[i + 1, j], idx[i + 2, j + 1], idx[i + 1, j + 2], idx[i, j + 1], idx[i + 1, j + 1]]
                )
    els = np.array(els, dtype=np.int64)
    # orientation check (counter-clockwise in (r, y))
    c = nodes[els[:, :4]]
    area = 0.5 * np.sum(c[:, :, 0] * np.roll(c[:, :, 1], -1, 1) - np.roll(c[:, :, 0], -1, 1) * c[:, :, 1], axis=1)
    if np.any(area < 0):
        flip = [0, 3, 2, 1] if order == 1 else [0, 3, 2, 1, 7, 6, 5, 4, 8]
        els = els[:, flip]
    edges = []
    for j in range(0, na - 1, order):
        edges.append([idx[0, j], idx[0, j + order]] + ([idx[0, j + 1]] if order == 2 else []))
    node_sets = {
        "axis": np.concatenate([idx[:, 0], idx[:, -1]]) if full else idx[:, -1].copy(),
        "dirichlet_y": np.array([idx[-1, (na - 1) // 2]]) if full else idx[:, 0].copy(),
        "dirichlet_x": np.zeros(0, np.int64),
        "pole_upper": np.array([idx[0, -1]]),
        "pole_lower": np.array([idx[-1, -1]]),
    }
    ne = len(els)
    return Mesh(
        nodes=nodes,
        elements=els,
        order=order,
        region=np.full(ne, REGION_INNER_CAP, np.int8),
        material=np.zeros(ne, np.int8),
        node_sets=node_sets,
        edge_sets={"cavity": np.array(edges, dtype=np.int64)},
        cavity_volume_offset=0.0,
        scene="sphere-full" if full else "sphere",
        info={"A": A, "B": B, "nt": nt, "n_arc": n_arc},
    )
