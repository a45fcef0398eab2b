"""Fields a designer reads off a deformed axisymmetric section (plain numpy, no solving).

* :func:`principal_stretch`: the largest principal stretch at points of every element, from the
  deformation gradient of the axisymmetric map ``(R, Z) -> (r, y)``::

      F = [[dr/dR, dr/dZ, 0], [dy/dR, dy/dZ, 0], [0, 0, r/R]],

  i.e. the larger of the in-plane 2x2 block's singular values and the hoop stretch ``r / R``
  (on the axis, where ``R = 0``, its limit ``dr/dR``).
* :func:`nodal_stretch`: the same at the mesh nodes (each node's value averaged over the elements
  that share it), for point data.
* :func:`element_points`: positions inside every element (curved Q9 edges drawn as curves).

The shape functions are those of the FE model (:mod:`snapjump_kernels.elements`, numba-free).
"""
from __future__ import annotations

import numpy as np

from snapjump_kernels.elements import shape_q4, shape_q9

__all__ = ["shape", "principal_stretch", "nodal_stretch", "element_points", "NODE_XI"]

#: Natural coordinates of the element nodes, gmsh's order (Q4: 4 corners; Q9: corners, mid-edges, centre).
NODE_XI = {
    1: np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float),
    2: np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [0, -1], [1, 0], [0, 1], [-1, 0], [0, 0]], dtype=float),
}


def shape(order: int, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions ``N`` (m, nen) and their derivatives ``dN`` (m, nen, 2) at the natural
    coordinates ``xi`` (m, 2) of an element of ``order`` 1 (Q4) or 2 (Q9)."""
    xi = np.asarray(xi, dtype=float).reshape(-1, 2)
    if order == 1:
        return shape_q4(xi[:, 0], xi[:, 1])
    if order == 2:
        return shape_q9(xi[:, 0], xi[:, 1])
    raise ValueError(f"element order must be 1 or 2, got {order!r}")


def element_points(x: np.ndarray, elements: np.ndarray, order: int, xi: np.ndarray) -> np.ndarray:
    """Positions (ne, m, 2) of the natural points ``xi`` (m, 2) in every element, the nodes at ``x``."""
    N, _ = shape(order, xi)
    return np.einsum("ma,eak->emk", N, np.asarray(x, float)[np.asarray(elements)])


def principal_stretch(X: np.ndarray, x: np.ndarray, elements: np.ndarray, order: int,
                      xi: np.ndarray) -> np.ndarray:
    """The largest principal stretch at the natural points ``xi`` (m, 2) of every element.

    Parameters
    ----------
    X : (n, 2) reference node coordinates ``(R, Z)``
    x : (n, 2) deformed node coordinates ``(r, y)`` (same units as ``X``)
    elements : (ne, nen) connectivity (gmsh order)
    order : 1 (Q4) or 2 (Q9)
    xi : (m, 2) natural coordinates in [-1, 1]^2

    Returns
    -------
    ndarray (ne, m)
        ``max(sigma_max(F_2x2), r / R)``; 1 where ``x == X``.
    """
    _, dN = shape(order, xi)
    Xe = np.asarray(X, float)[np.asarray(elements)]  # (ne, nen, 2)
    xe = np.asarray(x, float)[np.asarray(elements)]
    J0 = np.einsum("mak,eai->emik", dN, Xe)  # d(R, Z) / d(xi, eta): [i = R|Z, k = xi|eta]
    J = np.einsum("mak,eai->emik", dN, xe)  # d(r, y) / d(xi, eta)
    F = J @ np.linalg.inv(J0)  # d(r, y) / d(R, Z)
    s = np.linalg.svd(F, compute_uv=False)[..., 0]
    N, _ = shape(order, xi)
    R = np.einsum("ma,ea->em", N, Xe[:, :, 0])
    r = np.einsum("ma,ea->em", N, xe[:, :, 0])
    on_axis = np.abs(R) <= 1e-12 * max(float(np.abs(Xe).max()), 1e-300)
    hoop = np.where(on_axis, F[..., 0, 0], r / np.where(on_axis, 1.0, R))
    return np.maximum(s, hoop)


def nodal_stretch(X: np.ndarray, x: np.ndarray, elements: np.ndarray, order: int) -> np.ndarray:
    """The largest principal stretch at every node (n,), the average of its elements' values at it."""
    elements = np.asarray(elements)
    vals = principal_stretch(X, x, elements, order, NODE_XI[order])  # (ne, nen)
    total = np.bincount(elements.ravel(), weights=vals.ravel(), minlength=len(X))
    count = np.bincount(elements.ravel(), minlength=len(X))
    return total / np.maximum(count, 1)
