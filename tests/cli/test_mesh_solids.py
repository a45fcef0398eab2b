"""``snapjump mesh --out FILE.step|.brep|.stl``: the designed solids, re-imported and measured."""
from __future__ import annotations

import json
import re
from collections import Counter

import numpy as np
import pytest

from snapjump_cli.commands.mesh import main
from snapjump_cli.geometry.designs import get_design
from snapjump_cli.geometry.caps import CapScene, cap_volumes, design_volumes
from snapjump_cli.mesh.solids import STL_TOLERANCE_MM

MM3 = 1e-9  # m^3 per mm^3

SCENES = {
    "D": (["--design", "D", "--nt", "3", "--aspect", "1"], lambda: design_volumes(get_design("D"))),
    "cap-ring": (["--cap", "--theta", "60", "--eta", "8.5", "--bc", "ring-roller"],
                 lambda: cap_volumes(CapScene(theta_deg=60, eta=8.5, bc="ring-roller"))),
    "cap-outer": (["--cap", "outer", "--theta", "90", "--eta", "16.5"],
                  lambda: cap_volumes(CapScene(theta_deg=90, eta=16.5, kind="outer"))),
}


def _expected(name: str) -> dict[str, float]:
    """Exact volumes of each named solid [m^3]."""
    v = SCENES[name][1]()
    if name == "D":
        return {"inner_cap": v["inner_cap"], "ring": v["ring"], "outer_cap": v["outer_solid"]}
    kind = "outer_cap" if name == "cap-outer" else "inner_cap"
    out = {kind: v["solid"] - v["ring"]}
    if v["ring"] > 0:
        out["ring"] = v["ring"]
    return out


def _write(capsys, tmp_path, name, suffix) -> tuple[dict, object]:
    path = tmp_path / f"{name}{suffix}"
    assert main([*SCENES[name][0], "--out", str(path), "--format", "json"]) == 0
    return json.loads(capsys.readouterr().out), path


def _import(path) -> dict[str, float]:
    """Volumes [m^3] of the solids of a STEP/BREP file re-imported by OpenCASCADE, by label."""
    from snapjump_cli.mesh.gmsh_session import gmsh_session

    with gmsh_session("reimport") as gmsh:
        gmsh.option.setNumber("Geometry.OCCImportLabels", 1)
        gmsh.model.occ.importShapes(str(path))
        gmsh.model.occ.synchronize()
        vols = gmsh.model.getEntities(3)
        return {gmsh.model.getEntityName(3, t).split("/")[-1] or str(i): gmsh.model.occ.getMass(3, t) * MM3
                for i, (_, t) in enumerate(vols)}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_step_solids_are_named_and_measure_the_design(capsys, tmp_path, name):
    s, path = _write(capsys, tmp_path, name, ".step")
    text = path.read_text()
    assert "SI_UNIT(.MILLI.,.METRE.)" in text and "unit: mm" in text
    got = _import(path)
    want = _expected(name)
    assert list(got) == list(want)  # separate solids, named, in order
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=1e-9)
    # the meshed volumes the command prints (fine enough a mesh for its discretisation error)
    inner = got.get("inner_cap", 0.0) + got.get("ring", 0.0)
    if name == "cap-outer":
        assert got["outer_cap"] == pytest.approx(s["V_outer_solid_m3"], rel=1e-6)
    else:
        assert inner == pytest.approx(s["V_inner_solid_m3"], rel=1e-6)
    if name == "D":
        assert got["outer_cap"] == pytest.approx(s["V_outer_solid_m3"], rel=1e-6)


def test_brep_solids(capsys, tmp_path):
    _, path = _write(capsys, tmp_path, "D", ".brep")
    assert path.read_text().splitlines()[0].startswith("# snapjump D; unit: mm")
    got = list(_import(path).values())
    want = list(_expected("D").values())
    assert got == pytest.approx(want, rel=1e-9)


def _stl_solids(path) -> dict[str, np.ndarray]:
    """The triangles (m, 3, 3) of each ``solid NAME`` block of an ASCII STL."""
    out, name, verts = {}, None, []
    for line in path.read_text().splitlines():
        w = line.split()
        if w and w[0] == "solid":
            name, verts = w[1], []
            assert "unit: mm" in line
        elif w and w[0] == "vertex":
            verts.append([float(x) for x in w[1:]])
        elif w and w[0] == "endsolid":
            out[name] = np.array(verts).reshape(-1, 3, 3)
    return out


@pytest.mark.parametrize("name", sorted(SCENES))
def test_stl_is_watertight_and_encloses_the_volume(capsys, tmp_path, name):
    _, path = _write(capsys, tmp_path, name, ".stl")
    solids = _stl_solids(path)
    want = _expected(name)
    assert list(solids) == list(want)
    for k, T in solids.items():
        # every edge is shared by exactly two triangles, once in each direction (closed, oriented)
        keys = {tuple(v) for v in T.reshape(-1, 3).round(9).tolist()}
        index = {v: i for i, v in enumerate(sorted(keys))}
        tri = np.array([[index[tuple(v)] for v in t.round(9).tolist()] for t in T])
        assert (tri[:, 0] != tri[:, 1]).all() and (tri[:, 1] != tri[:, 2]).all() and (tri[:, 0] != tri[:, 2]).all()
        directed = Counter((int(a), int(b)) for t in tri for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])))
        assert max(directed.values()) == 1
        assert all(directed[(b, a)] == 1 for a, b in directed)
        # the enclosed volume (divergence theorem) within the facets' distance from the surface
        vol = np.einsum("ij,ij->i", T[:, 0], np.cross(T[:, 1], T[:, 2])).sum() / 6.0
        area = 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1).sum()
        exact = want[k] / MM3
        assert vol > 0
        assert abs(vol - exact) <= STL_TOLERANCE_MM * area
        assert abs(vol - exact) > 0  # a triangulation, not the exact surface
    # the ground at z = 0, nothing below it
    assert min(T[..., 2].min() for T in solids.values()) == pytest.approx(0.0, abs=1e-9)


def test_solids_help_names_the_unit(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"unit\s+mm", out) and ".step" in out and ".stl" in out


def test_volumes_add_up_in_the_headers(capsys, tmp_path):
    """The STEP and STL headers name each solid's volume so that inner_cap + ring = the inner solid
    (``snapjump mesh``'s ``V inner solid``, the jump model's m_i) and outer_cap = the outer solid."""
    m, step = _write(capsys, tmp_path, "D", ".step")
    _, stl = _write(capsys, tmp_path, "D", ".stl")
    head = re.sub(r"\s*\n\s*", " ", step.read_text()[:2000])
    nums = {k: float(v) for k, v in re.findall(r"(inner_cap|ring|inner solid|outer_cap) ([0-9.]+)", head)}
    assert nums["inner_cap"] + nums["ring"] == pytest.approx(nums["inner solid"], rel=1e-5)
    assert nums["inner solid"] * 1e-6 == pytest.approx(m["V_inner_solid_m3"], rel=1e-5)
    assert nums["outer_cap"] * 1e-6 == pytest.approx(m["V_outer_solid_m3"], rel=1e-5)
    assert "= inner solid" in stl.read_text().splitlines()[0]


def test_vtu_overlays_the_solids(capsys, tmp_path):
    """The mesh's .vtu and the STL share one frame (mm, z up, ground at z = 0): the section's
    extent in r and z is the solids'."""
    meshio = pytest.importorskip("meshio")
    _, stl = _write(capsys, tmp_path, "D", ".stl")
    assert main([*SCENES["D"][0], "--out", str(tmp_path / "c.vtu")]) == 0
    capsys.readouterr()
    P = meshio.read(tmp_path / "c.vtu").points
    T = np.concatenate(list(_stl_solids(stl).values())).reshape(-1, 3)
    assert np.all(P[:, 1] == 0.0)
    assert P[:, 2].min() == pytest.approx(0.0, abs=1e-9) == T[:, 2].min()
    assert P[:, 2].max() == pytest.approx(T[:, 2].max(), abs=0.05)
    assert P[:, 0].max() == pytest.approx(np.hypot(T[:, 0], T[:, 1]).max(), abs=0.05)
