"""Structured meshes: validity, conformity, node/edge sets, volumes and their convergence."""
from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest
from scipy.spatial import cKDTree

from snapjump_cli.geometry.designs import get_design
from snapjump_cli.geometry.caps import CapScene, Design, cap_points, cap_volumes, design_points, design_volumes
from snapjump_cli.mesh.build import SNAP_FRAC, mesh_scene, meshed_design
from snapjump_cli.mesh.io import write_mesh
from snapjump_cli.mesh.data import (
    REGION_INNER_CAP,
    REGION_OUTER_CAP,
    REGION_RING,
    Mesh,
    boundary_volume,
    element_volumes,
    jacobian_dets,
    solid_volumes,
)
from snapjump_cli.settings import MeshSettings
from snapjump_kernels.cavity import cavity_volume

NAMES = ("A", "B", "C", "D", "S20b", "S20c")
#: A thick, shallow outer cap on the paper's grid whose base overhangs the ring (x5 > x10).
OVERHANG = dict(eta_i=5.0, theta_i_deg=70.0, eta_o=5.0, theta_o_deg=76.0, mu_ratio=1.0)
CAPS = [
    CapScene(theta_deg=60.0, eta=30.0, bc="clamped"),
    CapScene(theta_deg=60.0, eta=8.5, bc="roller"),
    CapScene(theta_deg=60.0, eta=8.5, bc="roller-point"),
    CapScene(theta_deg=60.0, eta=8.5, bc="ring-roller"),
    CapScene(theta_deg=77.0, eta=12.9, kind="outer"),
    CapScene(theta_deg=120.0, eta=10.0, bc="clamped"),
]


def _id(s):
    return getattr(s, "name", None) or (f"{s.eta_i}-{s.theta_i_deg}-{s.eta_o}-{s.theta_o_deg}" if isinstance(s, Design) else
                      f"{s.kind}-{s.theta_deg}-{s.eta}-{s.bc}")


_cache: dict = {}


def meshed(scene, order=2, nt=4, aspect=2.0) -> Mesh:
    key = (scene, order, nt, aspect)
    if key not in _cache:
        _cache[key] = mesh_scene(scene, MeshSettings(order=order, nt=nt, aspect=aspect))
    return _cache[key]


def scenes():
    return [get_design(n) for n in NAMES] + [Design(**OVERHANG)] + CAPS


# ---------------------------------------------------------------------------------------------
# structural checks
# ---------------------------------------------------------------------------------------------
def element_edges(m: Mesh) -> Counter:
    """Element edges keyed by (sorted corners[, mid]); a mismatched mid node makes two keys."""
    c = Counter()
    for e in m.elements:
        for k in range(4):
            a, b = int(e[k]), int(e[(k + 1) % 4])
            key = (min(a, b), max(a, b)) + ((int(e[4 + k]),) if m.order == 2 else ())
            c[key] += 1
    return c


def check_conforming(m: Mesh, R: float) -> None:
    n = m.n_nodes
    # all nodes used, indices compact
    assert np.array_equal(np.unique(m.elements), np.arange(n))
    # no duplicate nodes
    assert not cKDTree(m.nodes).query_pairs(1e-9 * R)
    # every edge shared by 1 (boundary) or 2 (interior) elements
    edges = element_edges(m)
    assert set(edges.values()) <= {1, 2}
    # no hanging nodes: the boundary edges form ONE closed loop (the solid is simply connected);
    # a hanging node or a mismatched mid node would add a second loop
    bnd = [k for k, v in edges.items() if v == 1]
    deg = Counter()
    adj: dict[int, list[int]] = {}
    for k in bnd:
        deg[k[0]] += 1
        deg[k[1]] += 1
        adj.setdefault(k[0], []).append(k[1])
        adj.setdefault(k[1], []).append(k[0])
    assert set(deg.values()) == {2}
    start = bnd[0][0]
    seen, stack = {start}, [start]
    while stack:
        for q in adj[stack.pop()]:
            if q not in seen:
                seen.add(q)
                stack.append(q)
    assert len(seen) == len(deg), "boundary edges form more than one loop (hanging node?)"


def _toy(nodes, elements) -> Mesh:
    e = np.array(elements, np.int64)
    return Mesh(nodes=np.array(nodes, float), elements=e, order=1, region=np.zeros(len(e), np.int8),
                material=np.zeros(len(e), np.int8), node_sets={}, edge_sets={})


def test_conformity_checks_can_fail():
    square = [[0, 0], [2, 0], [2, 2], [0, 2]]
    ok = _toy(square + [[4, 0], [4, 2]], [[0, 1, 2, 3], [1, 4, 5, 2]])
    check_conforming(ok, 1.0)
    hanging = _toy(square + [[4, 0], [4, 1], [2, 1], [4, 2]], [[0, 1, 2, 3], [1, 4, 5, 6], [6, 5, 7, 2]])
    with pytest.raises(AssertionError):
        check_conforming(hanging, 1.0)
    duplicate = _toy(square + [[2, 0], [4, 0], [4, 2], [2, 2]], [[0, 1, 2, 3], [4, 5, 6, 7]])
    with pytest.raises(AssertionError):
        check_conforming(duplicate, 1.0)


def boundary_keys(m: Mesh) -> set:
    return {k[:2] for k, v in element_edges(m).items() if v == 1}


def on_boundary(m: Mesh, edges: np.ndarray) -> bool:
    b = boundary_keys(m)
    return all((min(int(e[0]), int(e[1])), max(int(e[0]), int(e[1]))) in b for e in edges)


def check_chain(edges: np.ndarray) -> None:
    assert edges.shape[0] > 0
    assert np.array_equal(edges[1:, 0], edges[:-1, 1]), "edge set is not an ordered chain"


def radius(m: Mesh, nodes, cy=0.0):
    return np.hypot(m.nodes[nodes, 0], m.nodes[nodes, 1] - cy)


# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("scene", scenes(), ids=_id)
def test_valid_and_conforming(scene, order):
    m = meshed(scene, order)
    R = scene.R_i if isinstance(scene, Design) else scene.R
    assert m.elements.shape[1] == (4 if order == 1 else 9)
    assert m.nodes.dtype == np.float64 and m.elements.dtype == np.int64
    det = jacobian_dets(m.nodes, m.elements, order)
    assert det.shape == (m.n_elements, 4 if order == 1 else 9)
    assert (det > 0).all()
    check_conforming(m, R)
    assert (m.nodes[:, 0] >= 0).all()
    for name, s in m.node_sets.items():
        assert s.size > 0 or name == "dirichlet_x", name
        assert s.dtype == np.int64 and (s >= 0).all() and (s < m.n_nodes).all()
    for name, e in m.edge_sets.items():
        assert e.shape[1] == order + 1 and e.shape[0] > 0, name
        check_chain(e)
        if not (name == "base" and "ground" in m.node_sets):  # a ring-roller base is glued (interior)
            assert on_boundary(m, e), name
    # axis
    ax = m.node_sets["axis"]
    assert (m.nodes[ax, 0] == 0.0).all()
    assert set(np.flatnonzero(m.nodes[:, 0] < 1e-12 * R)) == set(ax.tolist())
    # bandwidth kept small by the Cuthill-McKee numbering
    assert m.info["half_bandwidth"] < m.n_nodes / 4
    assert m.info["n_nodes"] == m.n_nodes and m.info["order"] == order


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("name", NAMES + ("overhang",))
def test_design_sets(name, order):
    d = Design(**OVERHANG) if name == "overhang" else get_design(name)
    m = meshed(d, order)
    p = design_points(d)
    X, S, E = m.nodes, m.node_sets, m.edge_sets
    tol = 1e-12 * d.R_i
    for key, pt in (("pole_lower", "1"), ("pole_upper", "2"), ("outer_pole_lower", "3"),
                    ("outer_pole_upper", "4"), ("point6", "6i")):
        assert S[key].size == 1, key
        np.testing.assert_allclose(X[S[key][0]], p[pt], atol=tol, err_msg=key)
    assert np.array_equal(S["dirichlet_y"], S["point6"])
    assert S["dirichlet_x"].size == 0
    # ground: ring bottom, from x7 to x9
    g = S["ground"]
    assert np.allclose(X[g, 1], p["8"][1], atol=tol, rtol=0)
    assert X[g, 0].min() == pytest.approx(p["8"][0], abs=tol) and X[g, 0].max() == pytest.approx(p["9"][0], abs=tol)
    assert set(np.unique(E["ground"]).tolist()) == set(g.tolist())
    # cavity: 2 -> 6 along the inner upper surface, then 6 -> 3 along the outer lower surface
    cav = E["cavity"]
    check_chain(cav)
    assert cav[0, 0] == S["pole_upper"][0] and cav[-1, 1] == S["outer_pole_lower"][0]
    assert S["point6"][0] in cav[:, 0]
    assert np.array_equal(cav, np.concatenate([E["inner_upper"], E["outer_lower"][::-1][:, [1, 0, 2][: order + 1]]]))
    # surfaces on their spheres (mid-edge nodes of order 2 included: they lie on the arcs)
    a_i, b_i = d.R_i * (1 - 0.5 / d.eta_i), d.R_i * (1 + 0.5 / d.eta_i)
    a_o, b_o = d.R_o * (1 - 0.5 / d.eta_o), d.R_o * (1 + 0.5 / d.eta_o)
    for key, rad, cy in (("inner_upper", b_i, 0.0), ("inner_lower", a_i, 0.0), ("outer_lower", a_o, d.Delta),
                         ("outer_upper", b_o, d.Delta)):
        np.testing.assert_allclose(radius(m, np.unique(E[key]), cy), rad, rtol=1e-12, err_msg=key)
    assert E["inner_upper"][0, 0] == S["pole_upper"][0] and E["inner_upper"][-1, 1] == S["point6"][0]
    assert E["outer_upper"][0, 0] == S["outer_pole_upper"][0]
    np.testing.assert_allclose(X[E["outer_upper"][-1, 1]], p["5"], atol=tol)
    # regions and materials
    assert set(np.unique(m.region)) == {REGION_INNER_CAP, REGION_RING, REGION_OUTER_CAP}
    assert np.array_equal(m.material, (m.region == REGION_OUTER_CAP).astype(np.int8))
    assert m.cavity_volume_offset == 0.0 and m.scene == "design"
    # through-thickness counts
    assert m.info["nt"]["inner_cap"] == 4 and m.info["nt"]["outer_cap"] == 4
    h = d.t_i / 4
    assert m.info["nt"]["ring"] == max(1, math.ceil(d.t_ring / h - 1e-9))


def test_element_aspect_along_arcs():
    d = get_design("C")
    for aspect in (1.0, 2.0, 3.0):
        m = meshed(d, 1, 4, aspect)
        for key, t in (("inner_upper", d.t_i), ("outer_upper", d.t_o), ("inner_lower", d.t_i)):
            e = m.edge_sets[key]
            L = np.linalg.norm(m.nodes[e[:, 1]] - m.nodes[e[:, 0]], axis=1)
            assert L.max() <= aspect * t / 4 * (1 + 1e-9)
            assert L.max() > 0.5 * aspect * t / 4  # not needlessly fine


def test_point6_shared_by_three_regions():
    for d in (get_design("C"), Design(**OVERHANG)):
        m = meshed(d)
        p6 = m.node_sets["point6"][0]
        regions = set(m.region[(m.elements == p6).any(axis=1)].tolist())
        assert regions == {REGION_INNER_CAP, REGION_RING, REGION_OUTER_CAP}


@pytest.mark.parametrize("order", [1, 2])
def test_overhang(order):
    d = Design(**OVERHANG)
    p = design_points(d)
    assert p["5"][0] > p["10"][0]
    m = meshed(d, order)
    assert m.info["overhang"] is True
    X = m.nodes
    tol = 1e-12 * d.R_i
    # the ring corner 10 is one node shared by the ring and the outer cap
    at10 = np.flatnonzero(np.hypot(X[:, 0] - p["10"][0], X[:, 1] - p["10"][1]) < tol)
    assert at10.size == 1
    regs = set(m.region[(m.elements == at10[0]).any(axis=1)].tolist())
    assert regs == {REGION_RING, REGION_OUTER_CAP}
    # the outer cap's base beyond x10 is a free surface: no ring element reaches past x10
    ring_nodes = np.unique(m.elements[m.region == REGION_RING])
    assert X[ring_nodes, 0].max() == pytest.approx(p["10"][0], abs=tol)
    base_o = np.unique(m.elements[m.region == REGION_OUTER_CAP])
    base_o = base_o[np.abs(X[base_o, 1] - p["5"][1]) < tol]
    assert X[base_o, 0].max() == pytest.approx(p["5"][0], abs=tol)
    assert (X[base_o, 0] > p["10"][0] + tol).sum() >= 1
    v, ex = solid_volumes(m), design_volumes(d)
    lim = 3e-3 if order == 1 else 1e-6  # measured 2.4e-3 / 2.7e-7
    assert abs(v["outer_solid"] / ex["outer_solid"] - 1) < lim
    assert abs(v["inner_solid"] / ex["inner_solid"] - 1) < lim
    # nt = 1: the split outer base needs two elements through the outer cap
    m1 = mesh_scene(d, MeshSettings(order=order, nt=1))
    assert m1.info["nt"]["outer_cap"] == 2
    check_conforming(m1, d.R_i)
    assert (jacobian_dets(m1.nodes, m1.elements, order) > 0).all()


def test_x5_equal_x10():
    """Ring width chosen so that x10 == x5: one shared point, no sliver elements."""
    base = Design(**OVERHANG)
    p = design_points(base)
    d = Design(**{**OVERHANG, "w_ring_frac": (p["5"][0] - p["6i"][0]) / base.R_i})
    m = meshed(d)
    assert abs(m.info["x5_minus_x10"]) < 1e-9 * d.R_i
    check_conforming(m, d.R_i)
    assert (jacobian_dets(m.nodes, m.elements, 2) > 0).all()
    v, ex = solid_volumes(m), design_volumes(d)
    assert abs(v["inner_solid"] / ex["inner_solid"] - 1) < 1e-6


def corner_aspect(m: Mesh) -> np.ndarray:
    """Longest / shortest corner-to-corner edge of each element."""
    c = m.nodes[m.elements[:, :4]]
    L = np.linalg.norm(c - np.roll(c, -1, axis=1), axis=2)
    return L.max(axis=1) / L.min(axis=1)


#: Paper-grid designs whose x5 and x10 nearly coincide: 3.7 um ring side, 8.4 um overhang side.
NEAR = [dict(eta_i=5.6, theta_i_deg=72.5, eta_o=35 / 3, theta_o_deg=76.0, mu_ratio=1.0),
        dict(eta_i=5.0, theta_i_deg=75.0, eta_o=35 / 3, theta_o_deg=78.0, mu_ratio=1.0)]


@pytest.mark.parametrize("params", NEAR, ids=["ring-side", "overhang-side"])
def test_near_coincident_x5_x10_snaps_instead_of_slivers(params):
    d = Design(**params)
    p = design_points(d)
    assert 0 < abs(p["5"][0] - p["10"][0]) < 1e-5
    raw = mesh_scene(d, MeshSettings(), snap=0.0)  # exact geometry: a sliver element
    assert corner_aspect(raw).max() > 100
    assert not raw.info["ring_snapped"]
    m = meshed(d)
    assert m.info["ring_snapped"] and not m.info["overhang"]
    assert corner_aspect(m).max() < 10
    check_conforming(m, d.R_i)
    assert (jacobian_dets(m.nodes, m.elements, 2) > 0).all()
    # the ring's outer face sits on x5; volumes are those of the snapped ring
    g = m.node_sets["ground"]
    assert m.nodes[g, 0].max() == pytest.approx(p["5"][0], abs=1e-12 * d.R_i)
    dm = meshed_design(d, m)
    assert dm.w_ring_frac == pytest.approx((p["5"][0] - p["6i"][0]) / d.R_i, rel=1e-12)
    assert meshed_design(d, raw) is d
    v, ex = solid_volumes(m), design_volumes(dm)
    assert abs(v["inner_solid"] / ex["inner_solid"] - 1) < 1e-6
    assert abs(v["outer_solid"] / ex["outer_solid"] - 1) < 1e-6
    # the snap is at most SNAP_FRAC of an element
    assert abs(dm.w_ring - d.w_ring) < SNAP_FRAC * d.t_ring


def test_paper_grid_sample_quality():
    """Every 9th design of the paper's grid: valid, conforming-by-count, no slivers."""
    grid = [(ei, ti, eo, to) for ei in np.linspace(5, 8, 6) for ti in np.linspace(70, 80, 5)
            for eo in np.linspace(5, 20, 10) for to in np.linspace(76, 90, 8)]
    n = 0
    for ei, ti, eo, to in grid[::9]:
        try:
            d = Design(eta_i=ei, theta_i_deg=ti, eta_o=eo, theta_o_deg=to, mu_ratio=1.0)
        except Exception:
            continue
        m = mesh_scene(d, MeshSettings(order=1, nt=4))  # (at nt = 2 the worst corner aspect is ~11.4)
        assert (jacobian_dets(m.nodes, m.elements, 1) > 0).all()
        assert corner_aspect(m).max() < 10, (ei, ti, eo, to)
        assert set(element_edges(m).values()) <= {1, 2}
        n += 1
    assert n > 150


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("cap", CAPS, ids=_id)
def test_cap_sets(cap, order):
    m = meshed(cap, order)
    cp = cap_points(cap)
    X, S, E = m.nodes, m.node_sets, m.edge_sets
    tol = 1e-12 * cap.R
    yb = cp["base_inner"][1]
    np.testing.assert_allclose(X[S["pole_lower"][0]], cp["pole_lower"], atol=tol)
    np.testing.assert_allclose(X[S["pole_upper"][0]], cp["pole_upper"], atol=tol)
    base = S["base"]
    assert base.size == 4 * order + 1
    assert np.allclose(X[base, 1], yb, atol=tol, rtol=0)
    assert X[base, 0].min() == pytest.approx(cp["base_inner"][0], abs=tol)
    assert X[base, 0].max() == pytest.approx(cp["base_outer"][0], abs=tol)
    dx, dy = S["dirichlet_x"], S["dirichlet_y"]
    cav = E["cavity"]
    check_chain(cav)
    if cap.kind == "outer":
        assert m.scene == "cap-outer"
        assert set(m.region.tolist()) == {REGION_OUTER_CAP} and set(m.material.tolist()) == {1}
        assert np.array_equal(dx, base) and np.array_equal(dy, base)
        # base corner -> pole along the lower surface
        np.testing.assert_allclose(X[cav[0, 0]], cp["base_inner"], atol=tol)
        assert cav[-1, 1] == S["pole_lower"][0]
        np.testing.assert_allclose(radius(m, np.unique(cav)), cap.R * (1 - 0.5 / cap.eta), rtol=1e-12)
        assert np.array_equal(E["outer_lower"], E["inner_lower"])
    else:
        assert m.scene == "cap-inner"
        assert set(m.material.tolist()) == {0}
        assert cav[0, 0] == S["pole_upper"][0]
        np.testing.assert_allclose(X[cav[-1, 1]], cp["base_outer"], atol=tol)
        np.testing.assert_allclose(radius(m, np.unique(cav)), cap.R * (1 + 0.5 / cap.eta), rtol=1e-12)
        if cap.bc == "clamped":
            assert np.array_equal(dx, base) and np.array_equal(dy, base)
        elif cap.bc == "roller":
            assert dx.size == 0 and np.array_equal(dy, base)
        elif cap.bc == "roller-point":
            assert dx.size == 0 and dy.size == 1
            np.testing.assert_allclose(X[dy[0]], cp["base_outer"], atol=tol)
        else:  # ring-roller: u_y = 0 on the cap/ring connection
            assert dx.size == 0 and np.array_equal(dy, base)
            assert set(m.region.tolist()) == {REGION_INNER_CAP, REGION_RING}
            g = S["ground"]
            assert np.allclose(X[g, 1], cp["ring_8"][1], atol=tol, rtol=0)
            assert X[g, 0].max() == pytest.approx(cp["ring_9"][0], abs=tol)
            ring_top = np.unique(m.elements[m.region == REGION_RING])
            ring_top = ring_top[np.abs(X[ring_top, 1] - yb) < tol]
            assert set(base.tolist()) <= set(ring_top.tolist())  # conforming connection
        if cap.bc != "ring-roller":
            assert set(m.region.tolist()) == {REGION_INNER_CAP} and "ground" not in S
    # single caps: V(X) = 0 and the offset is the exact volume under the loaded surface
    V0 = float(cavity_volume(X, cav)) + m.cavity_volume_offset
    under = cap_volumes(cap)["under"]
    assert abs(V0) <= 1e-13 * under
    sign = 1.0 if cap.kind == "inner" else -1.0
    assert sign * m.cavity_volume_offset == pytest.approx(under, rel=3e-3 if order == 1 else 1e-6)


# ---------------------------------------------------------------------------------------------
# volumes
# ---------------------------------------------------------------------------------------------
def _rel_errors(scene, order, nt):
    m = meshed(scene, order, nt)
    v = solid_volumes(m)
    if isinstance(scene, Design):
        ex = design_volumes(scene)
        cav = float(cavity_volume(m.nodes, m.cavity_edges)) + m.cavity_volume_offset
        return {"inner_solid": v["inner_solid"] / ex["inner_solid"] - 1,
                "outer_solid": v["outer_solid"] / ex["outer_solid"] - 1,
                "cavity": cav / ex["cavity"] - 1}
    ex = cap_volumes(scene)
    key = "outer_solid" if scene.kind == "outer" else "inner_solid"
    sign = 1.0 if scene.kind == "inner" else -1.0
    return {key: v[key] / ex["solid"] - 1, "under": sign * m.cavity_volume_offset / ex["under"] - 1}


@pytest.mark.parametrize("order, rate_lo, rate_hi", [(1, 1.7, 2.4), (2, 3.6, 4.6)])
@pytest.mark.parametrize("scene", [get_design("C"), get_design("D"), CAPS[0], CAPS[4]], ids=_id)
def test_volume_convergence(scene, order, rate_lo, rate_hi):
    """Relative volume errors fall like h^2 (Q4, chords) and h^4 (Q9, mid nodes on the arcs)."""
    nts = (2, 4, 8)
    errs = [_rel_errors(scene, order, nt) for nt in nts]
    for key in errs[0]:
        e = np.abs([x[key] for x in errs])
        assert (np.diff(e) < 0).all(), (key, e)
        rate = -np.polyfit(np.log(nts), np.log(e), 1)[0]
        assert rate_lo < rate < rate_hi, (key, rate, e)


@pytest.mark.parametrize("scene", scenes(), ids=_id)
def test_volumes_at_default_density(scene):
    e2 = _rel_errors(scene, 2, 4)
    e1 = _rel_errors(scene, 1, 4)
    for key in e2:
        assert abs(e2[key]) < 1e-5, (key, e2[key])  # order 2 (the default): measured <= 4.3e-6
        if key != "cavity":
            assert abs(e1[key]) < 3e-3, (key, e1[key])  # order 1: measured <= 2.4e-3
        assert abs(e2[key]) < abs(e1[key]) / 50
        if key != "cavity":  # solids at the default density: measured <= 2.7e-7
            assert abs(e2[key]) < 5e-7, (key, e2[key])


def test_element_volumes_exact_for_rings_and_boundary_volume():
    d = get_design("C")
    p = design_points(d)
    for order in (1, 2):
        m = meshed(d, order)
        ring = element_volumes(m)[m.region == REGION_RING].sum()
        exact = math.pi * (p["9"][0] ** 2 - p["8"][0] ** 2) * d.t_ring
        assert ring == pytest.approx(exact, rel=1e-13)
        assert (element_volumes(m) > 0).all()
        for e in m.edge_sets.values():
            assert boundary_volume(m.nodes, e) == pytest.approx(float(cavity_volume(m.nodes, e)), rel=1e-12, abs=1e-20)


def test_deterministic():
    d = get_design("D")
    a = mesh_scene(d)
    b = mesh_scene(d)
    assert np.array_equal(a.nodes, b.nodes) and np.array_equal(a.elements, b.elements)
    assert all(np.array_equal(a.edge_sets[k], b.edge_sets[k]) for k in a.edge_sets)
    assert all(np.array_equal(a.node_sets[k], b.node_sets[k]) for k in a.node_sets)


def test_bad_settings():
    d = get_design("C")
    for kw, msg in ((dict(order=3), "order"), (dict(nt=0), "nt"), (dict(aspect=float("nan")), "aspect")):
        with pytest.raises(ValueError, match=msg):  # the settings refuse bad values themselves
            mesh_scene(d, MeshSettings(**kw))
    with pytest.raises(ValueError, match="snap"):
        mesh_scene(d, snap=1.5)
    with pytest.raises(TypeError):
        mesh_scene("C")  # type: ignore[arg-type]


def test_gmsh_finalized_after_error(monkeypatch):
    import gmsh

    import snapjump_cli.mesh.build as mm

    def boom(*a, **k):
        raise RuntimeError("boom")

    monkeypatch.setattr(mm, "_build", boom)
    with pytest.raises(RuntimeError, match="boom"):
        mm.mesh_scene(get_design("C"))
    assert not gmsh.isInitialized()


# Meshing time is measured in `make bench-mesh` (bench/timings.py), never asserted in a test.


# ---------------------------------------------------------------------------------------------
# output files
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("suffix", [".msh", ".vtu"])
def test_write_mesh(tmp_path, suffix, order):
    meshio = pytest.importorskip("meshio")
    m = meshed(get_design("C"), order)
    path = write_mesh(m, tmp_path / f"c{suffix}")
    assert path.exists() and [p.name for p in tmp_path.iterdir()] == [f"c{suffix}"]
    back = meshio.read(path)
    if suffix == ".vtu":  # the frame of every 3D file: mm, z up, the ground (ring bottom) at z = 0, y = 0
        from snapjump_cli.mesh.io import ground_level

        expect = np.column_stack([m.nodes[:, 0], np.zeros(len(m.nodes)), m.nodes[:, 1] - ground_level(m)]) * 1e3
        np.testing.assert_allclose(back.points, expect, rtol=1e-15, atol=1e-12)
        assert back.points[:, 2].min() == 0.0
    else:
        np.testing.assert_allclose(back.points[:, :2], m.nodes, rtol=1e-15, atol=0)
    cell = "quad" if order == 1 else "quad9"
    conn = np.concatenate([c.data for c in back.cells if c.type == cell])
    assert conn.shape == m.elements.shape
    assert {tuple(sorted(r)) for r in conn.tolist()} == {tuple(sorted(r)) for r in m.elements.tolist()}
    if suffix == ".vtu":
        assert np.array_equal(conn, m.elements)
        assert np.array_equal(back.cell_data["region"][0], m.region)


def test_write_mesh_bad_suffix(tmp_path):
    with pytest.raises(ValueError, match="x.stl"):
        write_mesh(meshed(get_design("C")), tmp_path / "x.stl")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not __import__("os").path.exists("/proc/self/status"), reason="reads /proc (Linux)")
def test_gmsh_session_keeps_the_python_signal_handlers():
    """gmsh's C++ initialisation resets SIGTERM/SIGINT to their defaults; the sweep's clean stop
    (exit 130, finished rows kept, workers shut down) relies on its Python SIGTERM handler."""
    import signal

    from snapjump_cli.mesh.gmsh_session import gmsh_session

    def caught() -> int:
        line = [x for x in open("/proc/self/status").read().splitlines() if x.startswith("SigCgt:")][0]
        return int(line.split()[1], 16)

    old = signal.signal(signal.SIGTERM, lambda signum, frame: None)
    try:
        assert caught() & (1 << (signal.SIGTERM - 1))
        with gmsh_session():
            pass
        assert caught() & (1 << (signal.SIGTERM - 1)), "gmsh removed the SIGTERM handler"
    finally:
        signal.signal(signal.SIGTERM, old)


def test_node_order_cache_gives_the_computed_order_and_a_private_copy():
    from snapjump_cli.mesh import data as meshdata

    # a strip of 6 Q4 elements, 2 x 7 nodes
    conn = np.array([[i, i + 1, i + 8, i + 7] for i in range(6)], dtype=np.int64)
    fixed = np.zeros((14, 2), bool)
    fixed[0, 0] = True
    meshdata._ORDER_CACHE.clear()
    first = meshdata.node_order(14, conn, 0, fixed)
    assert np.array_equal(first, meshdata._node_order(14, conn, 0, fixed))
    first[:] = -1  # the caller's copy: the cache keeps its own
    again = meshdata.node_order(14, conn.astype(np.int32), 0, fixed)
    assert np.array_equal(again, meshdata._node_order(14, conn, 0, fixed))
    assert len(meshdata._ORDER_CACHE) == 1  # the int32 connectivity hit the same entry
    assert sorted(again.tolist()) == list(range(14))
