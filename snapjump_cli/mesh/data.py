"""The mesh handed from :mod:`snapjump_cli.mesh.build` to the solver: plain arrays, no gmsh state; its
measures (element and solid volumes, Jacobians, boundary volume) and its node ordering.

Conventions
-----------
* ``nodes[:, 0]`` is the radius ``r = x`` (>= 0), ``nodes[:, 1]`` the height ``y``; metres.
* ``elements`` are quadrilaterals listed counter-clockwise in the (r, y) plane, in gmsh's node
  order: order 1 -> 4 corners; order 2 -> 9 nodes (4 corners, 4 mid-edge nodes with node 4
  between corners 0 and 1, node 5 between 1 and 2, ..., node 8 at the centre). Curved arcs are
  represented by the mid-edge nodes lying on the exact arc.
* ``edge_sets["cavity"]`` are the boundary edges that bound the fluid cavity, as an (m, 2) array
  (order 1: start, end) or (m, 3) array (order 2: start, end, mid), ORIENTED so that the cavity
  volume in any configuration x is

      V(x) = pi * sum over edges of  integral_edge r^2 dy  +  cavity_volume_offset.

  Full actuator: from point 2 along the inner cap's upper surface to point 6, then along the
  outer cap's inner surface from 6 to point 3 (the axis closes the loop and adds nothing);
  offset 0, so V is the true cavity volume.
  Single inner cap (loaded from above): pole -> base corner along the upper surface; outer cap
  alone (loaded from below): base corner -> pole along the lower surface. For single caps the
  offset makes V(X) = 0, i.e. V is the supplied volume dV of docs/physics.md section 3
  (inner: V_under(X) - V_under(x); outer: V_under(x) - V_under(X)).

Measures use the element tables of :mod:`snapjump_kernels.elements` and the cavity kernel of
:mod:`snapjump_kernels.cavity`, the ones the model integrates with.

Node ordering: Cuthill-McKee from the inner (or only) cap's lower pole (:func:`cuthill_mckee`)
numbers the nodes along the structure, so that the band of the tangent stiffness is narrow and its
envelope small. :func:`snapjump_cli.mesh.build.mesh_scene` numbers its nodes so (:func:`node_order`:
the ties between neighbours of equal degree broken the way that gives the smaller envelope), and
the model numbers its dofs so; on a mesh from ``mesh_scene`` the model's order is the mesh's own.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from snapjump_kernels.calls import cavity_volume, envelope_extents, quadrature_geometry

__all__ = [
    "Mesh",
    "REGION_INNER_CAP",
    "REGION_RING",
    "REGION_OUTER_CAP",
    "REGION_NAMES",
    "cuthill_mckee",
    "node_order",
    "fixed_dofs",
    "number_dofs",
    "envelope_cost",
    "jacobian_dets",
    "element_volumes",
    "solid_volumes",
    "boundary_volume",
]

REGION_INNER_CAP = 0
REGION_RING = 1
REGION_OUTER_CAP = 2
#: Names of the regions (``.msh`` physical groups, mesh info).
REGION_NAMES = {REGION_INNER_CAP: "inner_cap", REGION_RING: "ring", REGION_OUTER_CAP: "outer_cap"}


@dataclass(frozen=True)
class Mesh:
    """A meshed axisymmetric scene.

    Attributes
    ----------
    nodes : (n, 2) float64
        Reference coordinates ``(r, y)`` [m].
    elements : (ne, 4) or (ne, 9) int64
        Connectivity, counter-clockwise, gmsh ordering (see module docstring).
    order : int
        1 (bilinear Q4) or 2 (biquadratic Q9).
    region : (ne,) int8
        ``REGION_INNER_CAP``, ``REGION_RING`` or ``REGION_OUTER_CAP`` per element.
    material : (ne,) int8
        0 = inner-cap rubber (``mu_i``; the ring is glued inner-cap rubber), 1 = outer-cap rubber.
    node_sets : dict[str, ndarray of int64]
        ``axis`` (all nodes on r = 0), ``dirichlet_y`` (nodes with u_y = 0),
        ``dirichlet_x`` (nodes with u_r = 0 besides the axis; clamped bases),
        ``pole_lower`` (1 node: inner/only cap's pole on its lower surface, point 1),
        ``pole_upper`` (1 node: point 2), ``outer_pole_lower`` / ``outer_pole_upper`` (points 3, 4
        for actuators), ``point6`` (1 node, actuators), ``ground`` (ring bottom nodes, actuators
        and ring-roller caps), ``base`` (base face nodes of a single cap).
    edge_sets : dict[str, ndarray of int64]
        Named boundary edges in the same (m, 2|3) layout as ``cavity_edges``: at least
        ``cavity``, ``inner_upper``, ``inner_lower`` and for actuators ``outer_lower``,
        ``outer_upper``, ``ground``.
    cavity_volume_offset : float
        Constant making ``pi * sum integral r^2 dy`` equal to the cavity volume (0 for actuators).
    scene : str
        ``"design"``, ``"cap-inner"`` or ``"cap-outer"``.
    info : dict
        Free-form provenance (nt, aspect, counts, gmsh version, timings).
    """

    nodes: np.ndarray
    elements: np.ndarray
    order: int
    region: np.ndarray
    material: np.ndarray
    node_sets: dict[str, np.ndarray]
    edge_sets: dict[str, np.ndarray]
    cavity_volume_offset: float = 0.0
    scene: str = "design"
    info: dict = field(default_factory=dict)

    @property
    def cavity_edges(self) -> np.ndarray:
        return self.edge_sets["cavity"]

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])

    @property
    def n_elements(self) -> int:
        return int(self.elements.shape[0])


def cuthill_mckee(n_nodes: int, conn: np.ndarray, start: int, ties: np.ndarray | None = None) -> np.ndarray:
    """Breadth-first (Cuthill-McKee) node order from ``start``; neighbours by increasing degree.

    Parameters
    ----------
    n_nodes : number of nodes
    conn : (ne, nen) element connectivity
    start : the first node (the inner or only cap's lower pole: the order then runs along the
        structure)
    ties : rank of each node that orders neighbours of equal degree (default: the node number)

    Returns
    -------
    ndarray of int64
        ``order[k]`` is the node numbered ``k`` (new -> old). On a mesh already numbered in an
        order of this function from ``start`` (whatever its ``ties``), the default order is the
        identity.
    """
    if ties is not None:
        return _breadth_first(_node_graph(n_nodes, conn), start, ties)
    conn = np.ascontiguousarray(conn, dtype=np.int64)
    return _cached(("cuthill_mckee", n_nodes, int(start), conn.shape, conn.tobytes()),
                   lambda: _breadth_first(_node_graph(n_nodes, conn), start, None))


def _node_graph(n_nodes: int, conn: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The node graph of ``conn`` (with self-loops): ``rows``, ``cols`` (sorted by row, then
    column) and the degree of each node."""
    nen = conn.shape[1]
    r = np.repeat(conn, nen, axis=1).ravel().astype(np.int64)
    c = np.tile(conn, (1, nen)).ravel().astype(np.int64)
    pairs = np.unique(r * n_nodes + c)
    rows, cols = pairs // n_nodes, pairs % n_nodes
    return rows, cols, np.bincount(rows, minlength=n_nodes)


def _breadth_first(graph: tuple[np.ndarray, np.ndarray, np.ndarray], start: int, ties: np.ndarray | None) -> np.ndarray:
    """Cuthill-McKee order of ``graph`` (:func:`_node_graph`) from ``start``; other components
    (none in a mesh of a scene) from their node of least degree."""
    rows, cols, deg = graph
    n_nodes = deg.size
    # every node's neighbours by increasing degree, ties by ``ties`` (default: the node number)
    key = cols if ties is None else np.asarray(ties)[cols]
    nbrs = cols[np.lexsort((key, deg[cols], rows))].tolist()
    indptr = np.concatenate([[0], np.cumsum(deg)]).tolist()
    seen = bytearray(n_nodes)
    order: list[int] = []
    for s in [start] + np.argsort(deg).tolist():
        if seen[s]:
            continue
        seen[s] = 1
        order.append(s)
        k = len(order) - 1
        while k < len(order):  # the queue is the tail of ``order``
            v = order[k]
            k += 1
            for w in nbrs[indptr[v] : indptr[v + 1]]:
                if not seen[w]:
                    seen[w] = 1
                    order.append(w)
    return np.array(order, dtype=np.int64)


def fixed_dofs(n_nodes: int, node_sets: dict[str, np.ndarray]) -> np.ndarray:
    """The constrained dofs, (n_nodes, 2) bool: ``u_r`` on the axis and on ``dirichlet_x``, ``u_y``
    on ``dirichlet_y``."""
    fixed = np.zeros((n_nodes, 2), bool)
    fixed[node_sets["axis"], 0] = True
    fixed[node_sets.get("dirichlet_x", np.zeros(0, int)), 0] = True
    fixed[node_sets.get("dirichlet_y", np.zeros(0, int)), 1] = True
    return fixed


def number_dofs(order: np.ndarray, fixed: np.ndarray) -> tuple[np.ndarray, int]:
    """Number the free dofs node by node in ``order`` (components in their order at each node).

    Parameters
    ----------
    order : node order (a permutation of the nodes)
    fixed : (n_nodes, n_components) bool, the constrained dofs

    Returns
    -------
    (dofmap, n)
        dofmap (n_nodes, n_components): the dof number, -1 where fixed; n the number of free dofs.
    """
    free = ~np.asarray(fixed, bool)[order]
    dofmap = np.full(free.shape, -1, np.int64)
    dofmap[order] = np.where(free, np.cumsum(free.ravel()).reshape(free.shape) - 1, -1)
    return dofmap, int(free.sum())


def envelope_cost(order: np.ndarray, conn: np.ndarray, fixed: np.ndarray) -> float:
    """``sum(ext^2)`` of the envelope of the stiffness (the work of its band LDL^T,
    :mod:`snapjump_kernels.banded`) when the free dofs are numbered node by node in ``order``."""
    free = ~fixed[order]
    dof = np.full(fixed.shape, -1, np.int64)
    dof[order] = np.where(free, np.cumsum(free.ravel()).reshape(free.shape) - 1, -1)
    edofs = dof[conn].reshape(conn.shape[0], -1)
    nd = edofs.shape[1]
    ri, ci = np.repeat(edofs, nd, axis=1).ravel(), np.tile(edofs, (1, nd)).ravel()
    ok = (ri >= 0) & (ci >= 0)
    n = int(free.sum())
    ext = envelope_extents(ri[ok], ci[ok], n, n - 1).astype(float)
    return float(ext @ ext)


def node_order(n_nodes: int, conn: np.ndarray, start: int, fixed: np.ndarray) -> np.ndarray:
    """Cuthill-McKee order from ``start`` (new -> old) whose envelope is the smaller of two ways of
    breaking ties between neighbours of equal degree.

    The ties are taken in reverse Cuthill-McKee order from ``start`` or from the far end of the
    structure (the last node reached from ``start``): consecutive levels then run the same way
    through the thickness. The first is the better one on single caps, the second on actuators.

    Parameters
    ----------
    n_nodes : number of nodes
    conn : (ne, nen) element connectivity
    start : the first node (the inner or only cap's lower pole)
    fixed : (n_nodes, 2) constrained dofs (:func:`fixed_dofs`), for the envelope
    """
    conn = np.ascontiguousarray(conn, dtype=np.int64)
    fixed = np.ascontiguousarray(fixed, dtype=bool)
    return _cached(("node_order", n_nodes, int(start), conn.shape, conn.tobytes(), fixed.tobytes()),
                   lambda: _node_order(n_nodes, conn, start, fixed))


#: Node orders (:func:`node_order`, :func:`cuthill_mckee`) of the meshes seen last, by the mesh's
#: connectivity, start node (and constrained dofs). An order depends on the topology alone, and a
#: sweep meshes the same topology again and again (the structured meshes of 347 paper-grid
#: designs have 75 distinct ones, ``bench/profile_designs.py@51d9ff8 --topologies 400``): five
#: breadth-first searches (~6-8 ms a design) become dictionary look-ups.
_ORDER_CACHE: dict = {}
_ORDER_CACHE_SIZE = 1024


def _cached(key: tuple, compute) -> np.ndarray:
    """``compute()`` through :data:`_ORDER_CACHE` (oldest entry dropped when full); a copy."""
    hit = _ORDER_CACHE.get(key)
    if hit is None:
        if len(_ORDER_CACHE) >= _ORDER_CACHE_SIZE:
            _ORDER_CACHE.pop(next(iter(_ORDER_CACHE)))
        hit = _ORDER_CACHE[key] = compute()
    return hit.copy()


def _node_order(n_nodes: int, conn: np.ndarray, start: int, fixed: np.ndarray) -> np.ndarray:
    """:func:`node_order`, computed."""
    graph = _node_graph(n_nodes, conn)
    first = _breadth_first(graph, start, None)
    best, best_cost = first, math.inf
    for back in (first[::-1], _breadth_first(graph, int(first[-1]), None)[::-1]):
        rank = np.empty_like(back)
        rank[back] = np.arange(back.size)
        order = _breadth_first(graph, start, rank)
        cost = envelope_cost(order, conn, fixed)
        if cost < best_cost:
            best, best_cost = order, cost
    return best


def jacobian_dets(nodes: np.ndarray, elements: np.ndarray, order: int) -> np.ndarray:
    """Jacobian determinants ``det(d(r, y)/d(xi, eta))`` at the Gauss points, shape (ne, nq)
    (2x2 points for Q4, 3x3 for Q9). Positive everywhere for a valid counter-clockwise mesh."""
    return quadrature_geometry(nodes, elements, order)[1]


def element_volumes(mesh: Mesh) -> np.ndarray:
    """Solid volume of revolution of each element, ``sum_q w_q 2 pi r detJ`` [m^3].

    Exact for the isoparametric geometry: the integrand is a polynomial of degree <= 3 (Q4) or
    <= 5 (Q9) in each reference coordinate, integrated by 2x2 / 3x3 Gauss points.
    """
    r, det, w = quadrature_geometry(mesh.nodes, mesh.elements, mesh.order)
    return 2.0 * np.pi * (r * det) @ w


def solid_volumes(mesh: Mesh) -> dict[str, float]:
    """Meshed solid volumes: ``inner_solid`` (inner cap + ring) and ``outer_solid`` [m^3]."""
    v = element_volumes(mesh)
    outer = mesh.region == REGION_OUTER_CAP
    return {"inner_solid": float(v[~outer].sum()), "outer_solid": float(v[outer].sum())}


def boundary_volume(nodes: np.ndarray, edges: np.ndarray) -> float:
    """``pi * sum over edges of integral r^2 dy`` (:func:`snapjump_kernels.cavity.cavity_volume`):
    the volume bounded by oriented edges, as in the cavity volume ``V(x)`` above."""
    return float(cavity_volume(np.ascontiguousarray(nodes, dtype=np.float64),
                               np.ascontiguousarray(edges, dtype=np.int64)))
