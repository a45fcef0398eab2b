"""The mesh handed from :mod:`snapjump_cli.mesh` to the solver: plain arrays, no gmsh state.

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
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Mesh", "REGION_INNER_CAP", "REGION_RING", "REGION_OUTER_CAP"]

REGION_INNER_CAP = 0
REGION_RING = 1
REGION_OUTER_CAP = 2


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
