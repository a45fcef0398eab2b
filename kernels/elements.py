"""Quadrilateral elements and quadrature tables (plain numpy; evaluated once per mesh).

Node order is gmsh's: corners (-1,-1), (1,-1), (1,1), (-1,1); for the 9-node quad then the
mid-edge nodes (0,-1), (1,0), (0,1), (-1,0) and the centre (0,0).

Mixed formulation: the pressure/dilatation field is discontinuous per element with basis
``[1]`` for the bilinear Q4 (Q1/P0, mean dilatation) and ``[1, xi, eta]`` for the biquadratic Q9
(Q2/P1-discontinuous), both inf-sup stable choices for incompressible solids.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ElementTables", "element_tables", "quadrature_geometry", "shape_q4", "shape_q9"]

_Q9_NODES = np.array(
    [[-1, -1], [1, -1], [1, 1], [-1, 1], [0, -1], [1, 0], [0, 1], [-1, 0], [0, 0]], dtype=float
)


def _lagrange1d_q2(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic 1D Lagrange basis on nodes (-1, 0, 1) and its derivative; shape (len(s), 3)."""
    s = np.asarray(s, dtype=float)
    L = np.stack([0.5 * s * (s - 1.0), 1.0 - s * s, 0.5 * s * (s + 1.0)], axis=-1)
    dL = np.stack([s - 0.5, -2.0 * s, s + 0.5], axis=-1)
    return L, dL


def shape_q4(xi: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear shape functions ``N`` (m, 4) and derivatives ``dN`` (m, 4, 2) at points (xi, eta)."""
    xi = np.atleast_1d(np.asarray(xi, float))
    eta = np.atleast_1d(np.asarray(eta, float))
    cx = np.array([-1.0, 1.0, 1.0, -1.0])
    cy = np.array([-1.0, -1.0, 1.0, 1.0])
    N = 0.25 * (1 + xi[:, None] * cx) * (1 + eta[:, None] * cy)
    dN = np.empty(N.shape + (2,))
    dN[..., 0] = 0.25 * cx * (1 + eta[:, None] * cy)
    dN[..., 1] = 0.25 * cy * (1 + xi[:, None] * cx)
    return N, dN


def shape_q9(xi: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Biquadratic (Lagrange) shape functions ``N`` (m, 9) and derivatives ``dN`` (m, 9, 2)."""
    xi = np.atleast_1d(np.asarray(xi, float))
    eta = np.atleast_1d(np.asarray(eta, float))
    Lx, dLx = _lagrange1d_q2(xi)
    Ly, dLy = _lagrange1d_q2(eta)
    ix = (_Q9_NODES[:, 0] + 1).astype(int)  # index of the 1D node (-1, 0, 1) -> (0, 1, 2)
    iy = (_Q9_NODES[:, 1] + 1).astype(int)
    N = Lx[:, ix] * Ly[:, iy]
    dN = np.empty(N.shape + (2,))
    dN[..., 0] = dLx[:, ix] * Ly[:, iy]
    dN[..., 1] = Lx[:, ix] * dLy[:, iy]
    return N, dN


def _gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    p, w = np.polynomial.legendre.leggauss(n)
    xi, eta = np.meshgrid(p, p, indexing="ij")
    W = np.outer(w, w)
    return np.stack([xi.ravel(), eta.ravel()], axis=1), W.ravel()


@dataclass(frozen=True)
class ElementTables:
    """Reference-element tables of one element type.

    Attributes
    ----------
    nen : nodes per element
    N : (nq, nen) shape functions at the quadrature points
    dN : (nq, nen, 2) derivatives w.r.t. (xi, eta)
    w : (nq,) quadrature weights
    Np : (nq, npres) pressure/dilatation basis at the quadrature points
    """

    nen: int
    N: np.ndarray
    dN: np.ndarray
    w: np.ndarray
    Np: np.ndarray


def element_tables(order: int) -> ElementTables:
    """Tables for ``order`` 1 (Q4, 2x2 Gauss, P0) or 2 (Q9, 3x3 Gauss, P1 discontinuous)."""
    if order == 1:
        pts, w = _gauss(2)
        N, dN = shape_q4(pts[:, 0], pts[:, 1])
        Np = np.ones((len(w), 1))
        return ElementTables(4, N, dN, w, Np)
    if order == 2:
        pts, w = _gauss(3)
        N, dN = shape_q9(pts[:, 0], pts[:, 1])
        Np = np.stack([np.ones(len(w)), pts[:, 0], pts[:, 1]], axis=1)
        return ElementTables(9, N, dN, w, Np)
    raise ValueError(f"element order must be 1 or 2, got {order!r}")


def quadrature_geometry(nodes: np.ndarray, elements: np.ndarray, order: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The isoparametric map of every element at the quadrature points of :func:`element_tables`.

    Parameters
    ----------
    nodes : (n, 2) node coordinates ``(r, y)``
    elements : (ne, nen) connectivity in gmsh's node order
    order : 1 (Q4) or 2 (Q9)

    Returns
    -------
    r : (ne, nq) radius at the quadrature points
    det : (ne, nq) Jacobian determinant ``det(d(r, y)/d(xi, eta))``
    w : (nq,) quadrature weights
    """
    tab = element_tables(order)
    X = np.asarray(nodes, dtype=float)[np.asarray(elements)]  # (ne, nen, 2)
    r = np.einsum("qa,ea->eq", tab.N, X[:, :, 0])
    J = np.einsum("qak,eai->eqik", tab.dN, X)
    det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    return r, det, tab.w
