"""Structured quadrilateral meshes of the axisymmetric scenes (gmsh, in-process).

Every cap is one transfinite, recombined surface bounded by the symmetry axis, two circular arcs
(its lower and upper surfaces) and its base segment; the ring under an inner cap is a row of
transfinite rectangles whose top face is split wherever a cap base starts or ends, so that all
glued interfaces share their nodes (the geometric points and curves are shared, hence the mesh is
conforming by construction). Order 2 gives 9-node quads (``Mesh.SecondOrderIncomplete = 0``) whose
mid-edge nodes lie on the exact arcs.

Density (``MeshSettings``): ``nt`` elements through each cap's thickness; along each arc the
element length is at most ``aspect * t / nt``; the ring gets ``ceil(t_ring / h)`` elements through
its thickness (``h = t_i / nt``) and free ring faces at most ``aspect`` times the ring's element
thickness along them.

Cross-section points of a design (paper S1, Fig. S1/S2): 1, 2 inner poles (lower, upper), 3, 4
outer poles, 5 outer cap's outer base corner, 6 the shared corner of both caps, 7 inner cap's inner
base corner, 8-9-10 ring corners. When ``x5 > x10`` (a thick, shallow outer cap overhangs the ring)
the outer cap's base is split at ``x10`` and its part beyond ``x10`` is a free surface. When x5 and
x10 nearly coincide (closer than ``SNAP_FRAC`` of the local element size), the ring's outer face is
moved onto x5 instead of meshing a sliver (the ring width changes by that much; see
:func:`meshed_design`).

Edge sets other than ``cavity`` run from the pole towards the base (surfaces) or towards +r
(``ground``, ``base``). Single caps: ``inner_upper`` / ``inner_lower`` are the only cap's surfaces
(as ``pole_lower`` / ``pole_upper`` are its poles); an outer cap alone also has them under
``outer_upper`` / ``outer_lower``.

Nodes are numbered along the structure, in the model's dof order (Cuthill-McKee from the lower
pole, :func:`snapjump_cli.mesh.data.node_order`). Mesh files are written by
:mod:`snapjump_cli.mesh.io`; volumes and Jacobians of a mesh are in :mod:`snapjump_cli.mesh.data`.
"""
from __future__ import annotations

import dataclasses
import logging
import math
import time

import numpy as np

from snapjump_cli.geometry.caps import CapScene, Design, cap_points, cap_volumes, design_points
from snapjump_cli.mesh.gmsh_session import LINE_TYPES, QUAD_TYPES, gmsh_session
from snapjump_cli.mesh.data import (
    REGION_INNER_CAP,
    REGION_NAMES,
    REGION_OUTER_CAP,
    REGION_RING,
    Mesh,
    boundary_volume,
    solid_volumes,
)
from snapjump_cli.mesh.io import MESH_SUFFIXES, write_mesh
from snapjump_cli.mesh.tidy import chain_edges, compact, half_bandwidth, orient, renumber
from snapjump_cli.settings import MeshSettings

__all__ = [
    "mesh_scene",
    "MeshTooLarge",
    "cap_node_count",
    "meshed_design",
    "SNAP_TOL",
    "SNAP_FRAC",
    # re-exported for the ``mesh`` command (their homes: snapjump_cli.mesh.io, snapjump_cli.mesh.data)
    "write_mesh",
    "MESH_SUFFIXES",
    "solid_volumes",
]

log = logging.getLogger(__name__)

#: Relative (to R_i) distance under which x5 and x10 are always taken as the same point.
SNAP_TOL = 1e-9
#: ... and the fraction of the local element size (ring element thickness when x10 > x5, outer cap
#: element thickness when x5 > x10) under which the ring's outer face is moved onto x5.
SNAP_FRAC = 0.15


def meshed_design(design: Design, mesh: Mesh) -> Design:
    """The design whose exact geometry ``mesh`` discretises: ``design`` itself, or with the ring
    width that snapping onto x5 produced (``mesh.info["w_ring_frac_used"]``)."""
    w = mesh.info.get("w_ring_frac_used")
    if not mesh.info.get("ring_snapped") or w is None:
        return design
    return dataclasses.replace(design, w_ring_frac=w)


# ------------------------------------------------------------------------------------------------
# Geometry construction (built-in kernel; shared points and curves => conforming)
# ------------------------------------------------------------------------------------------------
class MeshTooLarge(ValueError):
    """A mesh with more nodes than the limit (``SolverSettings.max_nodes``): ``n_nodes`` (the
    exact count, or with ``estimated`` the count of its caps' nodes alone, known before meshing)
    and ``limit``."""

    def __init__(self, n_nodes: int, limit: int, estimated: bool = False) -> None:
        self.n_nodes, self.limit, self.estimated = int(n_nodes), int(limit), estimated
        size = f"at least {n_nodes} nodes (counted before meshing)" if estimated else f"{n_nodes} nodes"
        super().__init__(f"the mesh has {size}, more than the limit of {limit} nodes (setting max_nodes)")


def cap_node_count(info: dict, order: int) -> int:
    """The nodes of the caps of a scene about to be meshed (``info`` of :func:`_build`): each cap is
    one structured patch of ``n_arc`` by ``nt`` elements, and the caps share no node, so this is a
    lower bound of the mesh's node count."""
    return sum((order * int(na) + 1) * (order * int(info["nt"][region]) + 1) for region, na in info["n_arc"].items())


def _count(length: float, size: float) -> int:
    """Number of elements so that each is at most ``size`` long (at least 1)."""
    return max(1, int(math.ceil(length / size - 1e-9)))


class _Builder:
    def __init__(self, gmsh):
        self.gmsh = gmsh
        self.geo = gmsh.model.geo
        self.surfaces: list[tuple[int, int, int]] = []  # (tag, region, material)
        self.coords: dict[int, tuple[float, float]] = {}

    def point(self, x: float, y: float) -> int:
        tag = self.geo.addPoint(float(x), float(y), 0.0)
        self.coords[tag] = (float(x), float(y))
        return tag

    def line(self, p: int, q: int, n: int) -> int:
        c = self.geo.addLine(p, q)
        self.geo.mesh.setTransfiniteCurve(c, int(n) + 1)
        return c

    def arc(self, p: int, centre: int, q: int, n: int) -> int:
        c = self.geo.addCircleArc(p, centre, q)
        self.geo.mesh.setTransfiniteCurve(c, int(n) + 1)
        return c

    def surface(self, loop: list[int], corners: list[int], region: int, material: int) -> int:
        cl = self.geo.addCurveLoop(loop)
        s = self.geo.addPlaneSurface([cl])
        self.geo.mesh.setTransfiniteSurface(s, "Left", corners)
        self.geo.mesh.setRecombine(2, s)
        self.surfaces.append((s, region, material))
        return s

    def cap(self, p_lo, p_up, p_bin, p_bout, base_curves, lower_arc, upper_arc, axis, region, material):
        """Cap surface bounded by lower arc (p_lo -> p_bin), base curves (p_bin -> p_bout, in
        order), upper arc (p_up -> p_bout) and axis (p_lo -> p_up); counter-clockwise loop."""
        loop = [lower_arc, *base_curves, -upper_arc, -axis]
        return self.surface(loop, [p_lo, p_bin, p_bout, p_up], region, material)

    def rect(self, bottom, right, top, left, corners, region, material):
        """Rectangle; ``bottom`` runs left->right, ``right``/``left`` run upwards, ``top`` runs
        left->right. ``corners`` = (bottom-left, bottom-right, top-right, top-left)."""
        return self.surface([bottom, right, -top, -left], list(corners), region, material)


class _CapGeom:
    """Analytic data of one cap: sphere centre height, radii of its faces, base height."""

    def __init__(self, cy: float, R: float, eta: float, yb: float):
        self.cy, self.a, self.b, self.yb = cy, R * (1 - 0.5 / eta), R * (1 + 0.5 / eta), yb
        self.t = R / eta
        self.x_in = math.sqrt(max(self.a**2 - (yb - cy) ** 2, 0.0))
        self.x_out = math.sqrt(max(self.b**2 - (yb - cy) ** 2, 0.0))

    def arc_count(self, nt: int, aspect: float) -> int:
        phi_a = math.atan2(self.x_in, self.yb - self.cy)
        phi_b = math.atan2(self.x_out, self.yb - self.cy)
        return _count(max(self.a * phi_a, self.b * phi_b), aspect * self.t / nt)


def _build(b: _Builder, scene: Design | CapScene, s: MeshSettings, snap: float = 0.0) -> dict:
    """Create the geometry and its transfinite constraints; return the bookkeeping needed to
    extract node and edge sets (point tags, curve tags with their start points)."""
    nt, aspect = int(s.nt), float(s.aspect)
    bk: dict = {"points": {}, "edge_sets": {}, "node_curves": {}, "info": {}}
    if isinstance(scene, Design):
        return _build_design(b, scene, nt, aspect, snap, bk)
    return _build_cap(b, scene, nt, aspect, bk)


def _build_design(b: _Builder, d: Design, nt: int, aspect: float, snap: float, bk: dict) -> dict:
    """:func:`_build` for a design: inner cap, ring and outer cap (see the module docstring)."""
    P, E = bk["points"], bk["edge_sets"]
    pts = design_points(d)
    yb = pts["7"][1]
    ci = _CapGeom(0.0, d.R_i, d.eta_i, yb)
    co = _CapGeom(d.Delta, d.R_o, d.eta_o, yb)
    x6 = pts["6i"][0]
    x5, x10 = pts["5"][0], pts["10"][0]
    nt_i = nt
    h = ci.t / nt_i
    n_ring = _count(d.t_ring, h)
    h_ring = d.t_ring / n_ring
    # x5 and x10 closer than a fraction of the local element size would leave a sliver
    # (a narrow ring column, or a thin row through the outer cap): move the ring's free
    # outer face (points 9, 10) onto x5 instead.
    gap = x5 - x10
    tol = max(SNAP_TOL * d.R_i, snap * (co.t / nt if gap > 0 else h_ring))
    coincide = abs(gap) <= tol
    overhang = gap > 0 and not coincide
    nt_o = max(nt, 2) if overhang else nt
    na_i, na_o = ci.arc_count(nt_i, aspect), co.arc_count(nt_o, aspect)
    y_g = pts["8"][1]

    for k in ("1", "2", "3", "4", "5", "7", "8", "9", "10"):
        if k in ("9", "10") and coincide:
            continue
        P[k] = b.point(*pts[k])
    P["6"] = b.point(*pts["6i"])
    if coincide:
        P["10"] = P["5"]
        P["9"] = b.point(x5, y_g)
    c_i, c_o = b.point(0.0, 0.0), b.point(0.0, d.Delta)
    P["11"] = b.point(x6, y_g)  # ring bottom below point 6

    # inner cap
    ax_i = b.line(P["1"], P["2"], nt_i)
    lo_i = b.arc(P["1"], c_i, P["7"], na_i)
    up_i = b.arc(P["2"], c_i, P["6"], na_i)
    base_i = b.line(P["7"], P["6"], nt_i)
    b.cap(P["1"], P["2"], P["7"], P["6"], [base_i], lo_i, up_i, ax_i, REGION_INNER_CAP, 0)
    # outer cap
    ax_o = b.line(P["3"], P["4"], nt_o)
    lo_o = b.arc(P["3"], c_o, P["6"], na_o)
    up_o = b.arc(P["4"], c_o, P["5"], na_o)
    if overhang:
        n1 = min(max(int(round(nt_o * (x10 - x6) / (x5 - x6))), 1), nt_o - 1)
        base_o = [b.line(P["6"], P["10"], n1), b.line(P["10"], P["5"], nt_o - n1)]
        top_ring = [(base_o[0], P["6"], P["10"], n1)]
    else:
        base_o = [b.line(P["6"], P["5"], nt_o)]
        top_ring = [(base_o[0], P["6"], P["5"], nt_o)]
        if not coincide:
            n_free = _count(x10 - x5, aspect * h_ring)
            top_ring.append((b.line(P["5"], P["10"], n_free), P["5"], P["10"], n_free))
    b.cap(P["3"], P["4"], P["6"], P["5"], base_o, lo_o, up_o, ax_o, REGION_OUTER_CAP, 1)
    # ring: [x7, x6] under the inner cap base, then the pieces of the top face beyond x6
    ground = _ring(b, P, (base_i, P["7"], P["6"], nt_i), top_ring, P["8"], P["11"], P["9"], n_ring)

    E["cavity"] = [(up_i, P["2"]), (lo_o, P["6"])]
    E["inner_upper"] = [(up_i, P["2"])]
    E["inner_lower"] = [(lo_i, P["1"])]
    E["outer_lower"] = [(lo_o, P["3"])]
    E["outer_upper"] = [(up_o, P["4"])]
    E["ground"] = ground
    bk["node_curves"] = {"axis": [ax_i, ax_o], "ground": [c for c, _ in ground]}
    bk["node_points"] = {"pole_lower": "1", "pole_upper": "2", "outer_pole_lower": "3",
                         "outer_pole_upper": "4", "point6": "6"}
    bk["dirichlet"] = {"dirichlet_y": ("points", ["6"]), "dirichlet_x": None}
    bk["info"] = {"nt": {"inner_cap": nt_i, "ring": n_ring, "outer_cap": nt_o},
                  "n_arc": {"inner_cap": na_i, "outer_cap": na_o},
                  "overhang": bool(overhang), "x5_minus_x10": gap,
                  "ring_snapped": bool(coincide and gap != 0.0),
                  "w_ring_frac_used": ((x5 if coincide else x10) - x6) / d.R_i}
    bk["scene"] = "design"
    return bk


def _build_cap(b: _Builder, c: CapScene, nt: int, aspect: float, bk: dict) -> dict:
    """:func:`_build` for a single cap (with the ring under it for ``bc="ring-roller"``)."""
    P, E = bk["points"], bk["edge_sets"]
    cp = cap_points(c)
    g = _CapGeom(0.0, c.R, c.eta, cp["base_inner"][1])
    na = g.arc_count(nt, aspect)
    region, material = (REGION_INNER_CAP, 0) if c.kind == "inner" else (REGION_OUTER_CAP, 1)
    P["1"] = b.point(*cp["pole_lower"])
    P["2"] = b.point(*cp["pole_upper"])
    P["7"] = b.point(*cp["base_inner"])
    P["6"] = b.point(*cp["base_outer"])
    centre = b.point(0.0, 0.0)
    ax = b.line(P["1"], P["2"], nt)
    lo = b.arc(P["1"], centre, P["7"], na)
    up = b.arc(P["2"], centre, P["6"], na)
    base = b.line(P["7"], P["6"], nt)
    b.cap(P["1"], P["2"], P["7"], P["6"], [base], lo, up, ax, region, material)
    info = {"nt": {REGION_NAMES[region]: nt}, "n_arc": {REGION_NAMES[region]: na}}
    E["inner_upper"] = [(up, P["2"])]
    E["inner_lower"] = [(lo, P["1"])]
    E["base"] = [(base, P["7"])]
    bk["node_curves"] = {"axis": [ax], "base": [base]}
    bk["node_points"] = {"pole_lower": "1", "pole_upper": "2"}
    if c.kind == "outer":
        E["outer_upper"] = E["inner_upper"]
        E["outer_lower"] = E["inner_lower"]
        E["cavity"] = [(lo, P["7"])]  # base corner -> pole along the lower surface
        bk["dirichlet"] = {"dirichlet_y": ("curves", [base]), "dirichlet_x": ("curves", [base])}
        bk["scene"] = "cap-outer"
    else:
        E["cavity"] = [(up, P["2"])]  # pole -> base corner along the upper surface
        bk["scene"] = "cap-inner"
        if c.bc == "clamped":
            bk["dirichlet"] = {"dirichlet_y": ("curves", [base]), "dirichlet_x": ("curves", [base])}
        elif c.bc == "roller":
            bk["dirichlet"] = {"dirichlet_y": ("curves", [base]), "dirichlet_x": None}
        elif c.bc == "roller-point":
            bk["dirichlet"] = {"dirichlet_y": ("points", ["6"]), "dirichlet_x": None}
        else:  # ring-roller
            bk["dirichlet"] = {"dirichlet_y": ("curves", [base]), "dirichlet_x": None}
            h = g.t / nt
            n_ring = _count(c.t_ring, h)
            h_ring = c.t_ring / n_ring
            P["8"] = b.point(*cp["ring_8"])
            P["9"] = b.point(*cp["ring_9"])
            P["10"] = b.point(*cp["ring_10"])
            P["11"] = b.point(cp["base_outer"][0], cp["ring_8"][1])
            n_free = _count(cp["ring_10"][0] - cp["base_outer"][0], aspect * h_ring)
            free = b.line(P["6"], P["10"], n_free)
            ground = _ring(b, P, (base, P["7"], P["6"], nt), [(free, P["6"], P["10"], n_free)],
                           P["8"], P["11"], P["9"], n_ring)
            E["ground"] = ground
            bk["node_curves"]["ground"] = [cc for cc, _ in ground]
            info["nt"]["ring"] = n_ring
    bk["info"] = info
    return bk


def _ring(b: _Builder, P: dict, first_top, more_top, p8: int, p11: int, p9: int, n_ring: int):
    """Row of transfinite rectangles under the ring's top-face pieces, left to right:
    ``first_top`` over [x7, x6] and ``more_top``, each ``(curve, left point, right point, n)``
    (curves run left to right; the last piece ends at point 10). ``p8``, ``p11``, ``p9`` are the
    bottom points under x7, x6 and x10. Returns the ground edge set ``[(curve, start point)]``."""
    tops = [first_top, *more_top]
    y_g = b.coords[p8][1]
    bottom = [p8, p11]
    for top in tops[1:-1]:
        bottom.append(b.point(b.coords[top[2]][0], y_g))
    bottom.append(p9)
    left_v = b.line(bottom[0], tops[0][1], n_ring)
    ground = []
    for k, (top, left, right, n) in enumerate(tops):
        right_v = b.line(bottom[k + 1], right, n_ring)
        bot = b.line(bottom[k], bottom[k + 1], n)
        b.rect(bot, right_v, top, left_v, (bottom[k], bottom[k + 1], right, left), REGION_RING, 0)
        ground.append((bot, bottom[k]))
        left_v = right_v
    return ground


def mesh_scene(scene: Design | CapScene, settings: MeshSettings = MeshSettings(), *, snap: float | None = None,
               max_nodes: int | None = None) -> Mesh:
    """Mesh a design (inner cap + ring + outer cap) or a single cap; see the module docstring.

    ``snap`` (default :data:`SNAP_FRAC`): when ``|x5 - x10|`` is below ``snap`` times the local
    element size, the ring's outer face is moved onto ``x5`` (``info["ring_snapped"]``,
    ``info["w_ring_frac_used"]``) rather than meshing a sliver; 0 keeps the exact geometry.

    Returns a :class:`~snapjump_cli.mesh.data.Mesh` with compact, bandwidth-reduced node numbering
    (Cuthill-McKee from the lower pole, :func:`~snapjump_cli.mesh.data.node_order`),
    counter-clockwise elements and the node/edge sets of the scene.
    Raises ``ValueError`` for bad mesh settings and :class:`MeshTooLarge` for a mesh of more than
    ``max_nodes`` nodes (before gmsh meshes it when its caps' element counts already tell).
    """
    if not isinstance(scene, (Design, CapScene)):
        raise TypeError(f"scene must be a Design or CapScene, got {type(scene).__name__}")
    order, nt, aspect = settings.order, settings.nt, settings.aspect
    snap = SNAP_FRAC if snap is None else float(snap)
    if not (math.isfinite(snap) and 0.0 <= snap < 1.0):
        raise ValueError(f"snap must lie in [0, 1), got {snap!r}")
    if order not in (1, 2):
        raise ValueError(f"mesh order must be 1 or 2, got {order!r}")
    if isinstance(nt, bool) or not isinstance(nt, (int, np.integer)) or nt < 1:
        raise ValueError(f"nt must be an integer >= 1, got {nt!r}")
    if not (isinstance(aspect, (int, float)) and math.isfinite(aspect) and aspect > 0):
        raise ValueError(f"aspect must be a finite number > 0, got {aspect!r}")

    # the one-time import (slow on first use) stays out of the timing
    import gmsh as _gmsh  # noqa: F401

    t0 = time.perf_counter()
    xy, elements, region, material, node_sets, edge_sets, bk, gmsh_version = _generate(scene, settings, snap,
                                                                                         max_nodes)
    t_gmsh = time.perf_counter() - t0
    nodes, elements, node_sets, edge_sets = compact(xy, elements, node_sets, edge_sets)
    if max_nodes is not None and nodes.shape[0] > max_nodes:
        raise MeshTooLarge(nodes.shape[0], max_nodes)
    nodes[node_sets["axis"], 0] = 0.0
    orient(nodes, elements, order)
    nodes, elements, region, material, node_sets, edge_sets = renumber(nodes, elements, region, material,
                                                                         node_sets, edge_sets)

    offset = 0.0
    if bk["scene"] != "design":
        offset = -boundary_volume(nodes, edge_sets["cavity"])  # V(X) = 0 exactly (meshed)
    info = dict(bk["info"])
    info.update(
        order=order, nt_setting=nt, aspect=float(aspect), n_nodes=int(nodes.shape[0]),
        n_elements=int(elements.shape[0]), half_bandwidth=half_bandwidth(elements),
        gmsh_version=gmsh_version, gmsh_s=t_gmsh, mesh_s=time.perf_counter() - t0,
    )
    if bk["scene"] != "design":
        info["V_under_exact"] = cap_volumes(scene)["under"]
    mesh = Mesh(
        nodes=nodes, elements=elements, order=order, region=region, material=material,
        node_sets=node_sets, edge_sets=edge_sets, cavity_volume_offset=offset,
        scene=bk["scene"], info=info,
    )
    log.debug("meshed %s: %d nodes, %d elements in %.1f ms", mesh.scene, mesh.n_nodes, mesh.n_elements,
              1e3 * info["mesh_s"])
    return mesh


def _generate(scene: Design | CapScene, settings: MeshSettings, snap: float, max_nodes: int | None = None) -> tuple:
    """Build and mesh the scene with gmsh; returns its node coordinates, connectivity, region and
    material per element, node and edge sets (in gmsh's node order), the builder's bookkeeping and
    gmsh's version. Raises :class:`MeshTooLarge` before meshing if the caps alone exceed ``max_nodes``."""
    order = settings.order
    with gmsh_session() as gmsh:
        b = _Builder(gmsh)
        bk = _build(b, scene, settings, snap)
        if max_nodes is not None and (n := cap_node_count(bk["info"], order)) > max_nodes:
            raise MeshTooLarge(n, max_nodes, estimated=True)
        gmsh.model.geo.synchronize()
        gmsh.option.setNumber("Mesh.RecombineAll", 1)
        gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 0)
        gmsh.model.mesh.generate(2)
        if order == 2:
            gmsh.model.mesh.setOrder(2)
        gmsh_version = gmsh.__version__

        tags, coords, _ = gmsh.model.mesh.getNodes(returnParametricCoord=False)
        tags = np.asarray(tags, dtype=np.int64)
        xy = np.asarray(coords, dtype=float).reshape(-1, 3)[:, :2]
        lookup = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
        lookup[tags] = np.arange(tags.size)

        qtype, ltype = QUAD_TYPES[order], LINE_TYPES[order]
        elems, region, material = [], [], []
        for s, reg, mat in b.surfaces:
            types, _, ntags = gmsh.model.mesh.getElements(2, s)
            if list(types) != [qtype]:
                raise RuntimeError(f"surface {s}: expected only quadrangles of type {qtype}, got types {list(types)}")
            conn = lookup[np.asarray(ntags[0], dtype=np.int64)].reshape(-1, 9 if order == 2 else 4)
            elems.append(conn)
            region.append(np.full(conn.shape[0], reg, np.int8))
            material.append(np.full(conn.shape[0], mat, np.int8))

        def curve_edges(c: int) -> np.ndarray:
            types, _, ntags = gmsh.model.mesh.getElements(1, abs(c))
            if list(types) != [ltype]:
                raise RuntimeError(f"curve {c}: expected line elements of type {ltype}, got {list(types)}")
            return lookup[np.asarray(ntags[0], dtype=np.int64)].reshape(-1, order + 1)

        def point_node(p: int) -> int:
            nt_, _, _ = gmsh.model.mesh.getNodes(0, p, returnParametricCoord=False)
            return int(lookup[int(nt_[0])])

        def curve_nodes(c: int) -> np.ndarray:
            nt_, _, _ = gmsh.model.mesh.getNodes(1, abs(c), includeBoundary=True, returnParametricCoord=False)
            return lookup[np.asarray(nt_, dtype=np.int64)]

        P = bk["points"]
        edge_sets = {
            name: np.concatenate([chain_edges(curve_edges(c), point_node(p0)) for c, p0 in parts])
            for name, parts in bk["edge_sets"].items()
        }
        node_sets = {name: np.unique(np.concatenate([curve_nodes(c) for c in cs]))
                     for name, cs in bk["node_curves"].items()}
        for name, key in bk["node_points"].items():
            node_sets[name] = np.array([point_node(P[key])], dtype=np.int64)
        for name in ("dirichlet_x", "dirichlet_y"):
            spec = bk["dirichlet"][name]
            if spec is None:
                node_sets[name] = np.zeros(0, np.int64)
            elif spec[0] == "points":
                node_sets[name] = np.array([point_node(P[k]) for k in spec[1]], dtype=np.int64)
            else:
                node_sets[name] = np.unique(np.concatenate([curve_nodes(c) for c in spec[1]]))
    elements = np.concatenate(elems).astype(np.int64)
    return (xy, elements, np.concatenate(region), np.concatenate(material), node_sets, edge_sets, bk,
            gmsh_version)
