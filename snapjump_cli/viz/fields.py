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

__all__ = ["shape", "principal_stretch", "nodal_stretch", "element_points", "NODE_XI", "deformation_gradient_3d",
           "principal_stretch_3d", "nodal_stretch_3d"]

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


#: (row, column) of the nine components of the multi-harmonic deformation gradient, in the order
#: of :mod:`snapjump_kernels.multiharmonic` (rows r, phi, z; columns R, Phi, Z).
_ROW3 = np.array([0, 0, 2, 2, 1, 0, 1, 1, 2])
_COL3 = np.array([0, 2, 0, 2, 1, 1, 0, 2, 1])


def deformation_gradient_3d(X: np.ndarray, A: np.ndarray, hn, elements: np.ndarray, order: int,
                            xi: np.ndarray, phi: float) -> np.ndarray:
    """The full 3D deformation gradient ``F`` (ne, m, 3, 3) of a Fourier-series displacement at the
    natural points ``xi`` (m, 2) of every element, in the meridian section at angle ``phi``.

    The displacement is that of :mod:`snapjump_kernels.multiharmonic`::

        u_r = sum_k a_k cos n_k phi,  u_z = sum_k b_k cos n_k phi,  u_phi = sum_{k>=1} c_k sin n_k phi

    with the nodal amplitudes ``A`` (n, 2 + 3 (K - 1)) stored ``[a_0, b_0, a_1, b_1, c_1, ...]``
    (same length unit as ``X``). Rows ``r, phi, z``, columns ``R, Phi, Z``; the components that
    divide by ``R`` need points off the axis (interior points of the elements are).

    Parameters
    ----------
    X : (n, 2) reference ``(R, Z)`` of the nodes
    A : (n, nc) nodal amplitudes (harmonic 0 alone: an axisymmetric state)
    hn : the harmonics ``n_k`` (``hn[0] = 0``)
    elements, order : connectivity (gmsh order) and element order (1: Q4, 2: Q9)
    xi : (m, 2) natural coordinates, inside the elements
    phi : the section's angle [rad]
    """
    hn = np.asarray(hn, dtype=float)
    N, dN = shape(order, xi)
    elements = np.asarray(elements)
    Xe = np.asarray(X, float)[elements]  # (ne, nen, 2)
    J0 = np.einsum("mak,eai->emik", dN, Xe)
    dNdX = np.einsum("mak,emki->emai", dN, np.linalg.inv(J0))  # (ne, m, nen, 2): d/dR, d/dZ
    R = np.einsum("ma,ea->em", N, Xe[:, :, 0])
    bn = N[None, :, :] / R[:, :, None]  # (ne, m, nen)
    bx, by = dNdX[..., 0], dNdX[..., 1]
    Ae = np.asarray(A, float)[elements]  # (ne, nen, nc)
    F = np.zeros(R.shape + (3, 3))
    for k, n in enumerate(hn):
        o = 0 if k == 0 else 2 + 3 * (k - 1)
        a, b = Ae[:, None, :, o], Ae[:, None, :, o + 1]
        c = Ae[:, None, :, o + 2] if k > 0 else np.zeros_like(a)
        G = [(bx * a).sum(-1), (by * a).sum(-1), (bx * b).sum(-1), (by * b).sum(-1), (bn * (a + n * c)).sum(-1),
             (-bn * (n * a + c)).sum(-1), (bx * c).sum(-1), (by * c).sum(-1), (-n * bn * b).sum(-1)]
        cs, sn = np.cos(n * phi), np.sin(n * phi)
        for comp in range(9):
            F[..., _ROW3[comp], _COL3[comp]] += (cs if comp < 5 else sn) * G[comp]
    F[..., 0, 0] += 1.0
    F[..., 1, 1] += 1.0
    F[..., 2, 2] += 1.0
    return F


def principal_stretch_3d(X: np.ndarray, A: np.ndarray, hn, elements: np.ndarray, order: int, xi: np.ndarray,
                         phi: float) -> np.ndarray:
    """The largest principal stretch (ne, m), the largest singular value of the 3D deformation
    gradient of :func:`deformation_gradient_3d`, at the natural points ``xi`` of every element of
    the section at ``phi``. For harmonic 0 alone it equals :func:`principal_stretch`."""
    F = deformation_gradient_3d(X, A, hn, elements, order, xi, phi)
    return np.linalg.svd(F, compute_uv=False)[..., 0]


#: How far inside its element a node's value is taken for :func:`nodal_stretch_3d` (natural
#: coordinates scaled by this factor): the components that divide by ``R`` are not defined on the axis.
_NODE_INSET = 0.96


def nodal_stretch_3d(X: np.ndarray, A: np.ndarray, hn, elements: np.ndarray, order: int, phi: float) -> np.ndarray:
    """The largest principal stretch of the 3D deformation gradient at every node (n,) of the
    section at ``phi``, each node's value the average of its elements' values just inside them."""
    elements = np.asarray(elements)
    vals = principal_stretch_3d(X, A, hn, elements, order, NODE_XI[order] * _NODE_INSET, phi)
    total = np.bincount(elements.ravel(), weights=vals.ravel(), minlength=len(X))
    count = np.bincount(elements.ravel(), minlength=len(X))
    return total / np.maximum(count, 1)
