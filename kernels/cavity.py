"""Exact cavity volume of an axisymmetric boundary and its first and second derivatives.

The cavity volume is ``V(x) = pi * sum_e integral_e r^2 dy + offset`` over oriented boundary
edges (see :mod:`snapjump_cli.mesh.data`). Along an edge with Lagrange shape functions ``N_a(s)``
(2 nodes: linear, 3 nodes ordered start, end, mid: quadratic) the integrand ``r(s)^2 y'(s)`` is a
polynomial of degree <= 5, so 3-point Gauss quadrature is exact for both edge orders. Because V is
a scalar function of the nodal positions, the load ``p dV/dx`` has the symmetric load stiffness
``p d2V/dx2``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

_GP = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GW = np.array([5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0])


@njit(cache=True)
def edge_shape(s: float, nen: int, N: np.ndarray, dN: np.ndarray) -> None:
    if nen == 2:
        N[0] = 0.5 * (1.0 - s)
        N[1] = 0.5 * (1.0 + s)
        dN[0] = -0.5
        dN[1] = 0.5
    else:  # start, end, mid
        N[0] = 0.5 * s * (s - 1.0)
        N[1] = 0.5 * s * (s + 1.0)
        N[2] = 1.0 - s * s
        dN[0] = s - 0.5
        dN[1] = s + 0.5
        dN[2] = -2.0 * s


@njit(cache=True)
def cavity_volume(x: np.ndarray, edges: np.ndarray) -> float:
    """``pi * sum integral r^2 dy`` over the oriented ``edges`` of the node positions ``x`` (n, 2)."""
    nen = edges.shape[1]
    N = np.empty(nen)
    dN = np.empty(nen)
    v = 0.0
    for e in range(edges.shape[0]):
        for q in range(3):
            edge_shape(_GP[q], nen, N, dN)
            r = 0.0
            dy = 0.0
            for a in range(nen):
                r += N[a] * x[edges[e, a], 0]
                dy += dN[a] * x[edges[e, a], 1]
            v += _GW[q] * r * r * dy
    return np.pi * v


@njit(cache=True)
def _edge_terms(x, nodes, N, dN, ge, he):
    """Volume of one edge; fills its gradient ``ge`` (2 nen) and Hessian ``he`` (2 nen, 2 nen)."""
    nen = nodes.shape[0]
    ge[:] = 0.0
    he[:, :] = 0.0
    v = 0.0
    for q in range(3):
        edge_shape(_GP[q], nen, N, dN)
        r = 0.0
        dy = 0.0
        for a in range(nen):
            r += N[a] * x[nodes[a], 0]
            dy += dN[a] * x[nodes[a], 1]
        w = np.pi * _GW[q]
        v += w * r * r * dy
        for a in range(nen):
            ge[2 * a] += w * 2.0 * r * N[a] * dy
            ge[2 * a + 1] += w * r * r * dN[a]
            for b in range(nen):
                he[2 * a, 2 * b] += w * 2.0 * N[a] * N[b] * dy
                t = w * 2.0 * r * N[a] * dN[b]
                he[2 * a, 2 * b + 1] += t
                he[2 * b + 1, 2 * a] += t
    return v


@njit(cache=True)
def cavity_assemble(x, edges, edge_dofs, edge_pos, coef, want, g_out, data_out):
    """Cavity volume; adds ``dV/du`` into ``g_out`` (free dofs) and, for ``want >= 2``,
    ``coef * d2V/du2`` into the CSR values ``data_out``.

    Parameters
    ----------
    x : (n, 2) current node positions
    edges : (m, nen) oriented cavity edges
    edge_dofs : (m, 2 nen) free-dof index of each edge dof (-1 if constrained)
    edge_pos : (m, 2 nen, 2 nen) position of each Hessian entry in the CSR data (-1 if dropped)
    coef : factor applied to the Hessian (``-p`` for the load stiffness)
    """
    m, nen = edges.shape
    N = np.empty(nen)
    dN = np.empty(nen)
    ge = np.empty(2 * nen)
    he = np.empty((2 * nen, 2 * nen))
    v = 0.0
    for e in range(m):
        v += _edge_terms(x, edges[e], N, dN, ge, he)
        for i in range(2 * nen):
            di = edge_dofs[e, i]
            if di < 0:
                continue
            g_out[di] += ge[i]
            if want >= 2:
                for j in range(2 * nen):
                    pj = edge_pos[e, i, j]
                    if pj >= 0:
                        data_out[pj] += coef * he[i, j]
    return v
