"""``snapjump curve --shapes/--animation/--export/--revolve``: the files, read back (meshio for the
ParaView time series), and bad input (exit 2, nothing written)."""
from __future__ import annotations

import csv
import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from snapjump_cli.commands.curve import main
from snapjump_cli.geometry.designs import get_design
from snapjump_cli.geometry.caps import design_points

meshio = pytest.importorskip("meshio")

DESIGN_C = ["--design", "C"]
CHEAP = ["--cap", "--theta", "60", "--eta", "8.5", "--bc", "roller-point"]


def _run(capsys, args) -> dict:
    assert main([*args, "--format", "json"]) == 0
    return json.loads(capsys.readouterr().out)


def _csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _pole_z_mm(design: str = "C") -> float:
    """The height of the lower inner pole (point 1) above the ground (point 8, the ring's bottom)
    [mm]: where the export's frame (mm, z up, ground at z = 0) puts it."""
    p = design_points(get_design(design))
    return (p["1"][1] - p["8"][1]) * 1e3


def _pole_row(points: np.ndarray, z1: float) -> int:
    """The point of the lower inner pole (on the axis, at height ``z1`` [mm]) in the exported mesh."""
    d = np.hypot(points[:, 0], points[:, 1]) + np.abs(points[:, 2] - z1)
    k = int(np.argmin(d))
    assert d[k] < 1e-9
    return k


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """Design C exported both ways, with the CSV and the metrics."""
    out = tmp_path_factory.mktemp("export")
    paths = {"csv": out / "c.csv", "pvd": out / "c.pvd", "xdmf": out / "c.xdmf"}
    from click.testing import CliRunner

    from snapjump_cli.cli import cli

    runs = []
    for extra in (["--csv", str(paths["csv"]), "--export", str(paths["pvd"])], ["--export", str(paths["xdmf"])]):
        r = CliRunner().invoke(cli, ["curve", *DESIGN_C, "--format", "json", *extra])
        assert r.exit_code == 0, r.output
        runs.append(json.loads(r.stdout))
    assert runs[0] == {**runs[1], "wall_s": runs[0]["wall_s"], **{k: runs[0][k] for k in runs[0] if k.startswith("t_")
                                                                  or k.endswith("_s")}}
    return paths, runs[0]


def test_pvd_read_back(exported):
    paths, m = exported
    rows = _csv(paths["csv"])
    root = ET.parse(paths["pvd"]).getroot()
    sets = root.find("Collection").findall("DataSet")
    assert len(sets) == len(rows) > m["n_steps"]  # one step per CSV row: the path and its named states
    assert [int(s.get("timestep")) for s in sets] == list(range(len(rows))) == [int(r["step"]) for r in rows]
    z1 = _pole_z_mm()
    meshes = [meshio.read(paths["pvd"].parent / s.get("file")) for s in sets]
    for k, mm in enumerate(meshes):
        assert set(mm.point_data) == {"displacement_mm", "max_principal_stretch"}
        assert mm.point_data["displacement_mm"].shape == (len(mm.points), 3)
        assert set(mm.cell_data) == {"rubber_mean_stress_Pa", "region", "material"}
        assert mm.cells[0].type == "quad9"
        assert int(mm.field_data["step"][0]) == k
        assert float(mm.field_data["p_Pa"][0]) == pytest.approx(float(rows[k]["p_Pa"]), rel=1e-10, abs=1e-9)
        assert float(mm.field_data["V_m3"][0]) == pytest.approx(float(rows[k]["V_m3"]), rel=1e-10)
    assert np.all(meshes[0].point_data["displacement_mm"] == 0.0)
    assert np.allclose(meshes[0].point_data["max_principal_stretch"], 1.0, atol=1e-12)
    # the frame of the STEP/STL solids: mm, z up, the ground (the ring's bottom) at z = 0, section in y = 0
    assert meshes[0].points[:, 2].min() == pytest.approx(0.0, abs=1e-9) and np.all(meshes[0].points[:, 1] == 0.0)
    assert "unit: mm; axis z (up); ground z = 0" in paths["pvd"].read_text()
    codes = [int(mm.field_data["state"][0]) for mm in meshes]
    up, lo = codes.index(3), codes.index(4)
    assert codes.count(3) == codes.count(4) == 1 and rows[up]["state"] == "upper" and rows[lo]["state"] == "lower"
    assert sets[up].get("name") == "upper" and sets[lo].get("name") == "lower"
    assert float(meshes[up].field_data["p_Pa"][0]) == pytest.approx(m["p_star_Pa"], rel=1e-12)
    assert float(meshes[up].field_data["V_m3"][0]) == pytest.approx(m["V_star_m3"], rel=1e-12)
    pole = _pole_row(meshes[0].points, z1)
    dy = meshes[up].point_data["displacement_mm"][pole, 2] - meshes[lo].point_data["displacement_mm"][pole, 2]
    assert dy == pytest.approx(m["dy_pole_m"] * 1e3, rel=1e-12)
    # the stretch and the mean stress are the state's: the upper state is stretched and stressed
    assert meshes[up].point_data["max_principal_stretch"].max() > 1.05
    assert np.isfinite(meshes[up].cell_data["rubber_mean_stress_Pa"][0]).all()
    assert np.abs(meshes[up].cell_data["rubber_mean_stress_Pa"][0]).max() > 1e3


def test_xdmf_read_back(exported):
    paths, m = exported
    rows = _csv(paths["csv"])
    z1 = _pole_z_mm()
    with meshio.xdmf.TimeSeriesReader(paths["xdmf"]) as r:
        points, cells = r.read_points_cells()
        assert r.num_steps == len(rows)
        data = [r.read_data(k) for k in range(r.num_steps)]
    assert cells[0].type == "quad9"
    assert [t for t, _, _ in data] == [float(k) for k in range(len(rows))]
    for _, pd, cd in data:
        assert set(pd) == {"displacement_mm", "max_principal_stretch"} and pd["displacement_mm"].shape == (len(points), 3)
        assert set(cd) == {"rubber_mean_stress_Pa", "region", "material"}
    assert np.all(data[0][1]["displacement_mm"] == 0.0)
    # the per-step values are Information elements of each step
    root = ET.parse(paths["xdmf"]).getroot()
    grids = root.find("Domain").find("Grid").findall("Grid")
    info = [{i.get("Name"): i.get("Value") for i in g.findall("Information")} for g in grids]
    states = [int(i["state"]) for i in info]
    up, lo = states.index(3), states.index(4)
    assert rows[up]["state"] == "upper" and rows[lo]["state"] == "lower"
    assert float(info[up]["p_Pa"]) == pytest.approx(m["p_star_Pa"], rel=1e-12)
    pole = _pole_row(points, z1)
    dy = data[up][1]["displacement_mm"][pole, 2] - data[lo][1]["displacement_mm"][pole, 2]
    assert dy == pytest.approx(m["dy_pole_m"] * 1e3, rel=1e-12)


def test_revolve_writes_the_solid_of_revolution(capsys, tmp_path):
    out = tmp_path / "r.pvd"
    m = _run(capsys, [*CHEAP, "--export", str(out), "--revolve", "8"])
    sets = ET.parse(out).getroot().find("Collection").findall("DataSet")
    section = tmp_path / "s.pvd"
    _run(capsys, [*CHEAP, "--export", str(section)])
    ssets = ET.parse(section).getroot().find("Collection").findall("DataSet")
    assert len(sets) == len(ssets)
    k = [s.get("name") for s in sets].index("upper")
    solid = meshio.read(tmp_path / sets[k].get("file"))
    sec = meshio.read(tmp_path / ssets[k].get("file"))
    assert {c.type for c in solid.cells} == {"hexahedron", "wedge"}
    on_axis = np.abs(sec.points[:, 0]) < 1e-12
    assert len(solid.points) == on_axis.sum() + 8 * (~on_axis).sum()
    # the radius of every point is a section node's, and its displacement is that node's turned by phi
    r = np.hypot(solid.points[:, 0], solid.points[:, 1])
    phi = np.arctan2(solid.points[:, 1], solid.points[:, 0])
    key = {(round(a, 9), round(b, 9)): i for i, (a, b) in enumerate(sec.points[:, [0, 2]])}
    idx = np.array([key[(round(a, 9), round(b, 9))] for a, b in zip(r, solid.points[:, 2])])
    u = sec.point_data["displacement_mm"][idx]
    assert np.all(u[:, 1] == 0.0)  # the section lies in the plane y = 0
    expect = np.column_stack([u[:, 0] * np.cos(phi), u[:, 0] * np.sin(phi), u[:, 2]])
    assert np.allclose(solid.point_data["displacement_mm"], expect, rtol=0, atol=1e-12)
    assert np.array_equal(solid.point_data["max_principal_stretch"], sec.point_data["max_principal_stretch"][idx])
    # every cell has a positive volume with VTK's orderings (hexahedra: 5 tetrahedra; wedges: 3)
    for block in solid.cells:
        tets = {"hexahedron": [(0, 1, 3, 4), (1, 2, 3, 6), (1, 4, 5, 6), (3, 4, 6, 7), (1, 3, 4, 6)],
                "wedge": [(0, 2, 1, 3), (1, 3, 5, 4), (1, 2, 5, 3)]}[block.type]
        P = solid.points[block.data]
        for a, b, c, d in tets:
            vol = np.einsum("ij,ij->i", np.cross(P[:, b] - P[:, a], P[:, c] - P[:, a]), P[:, d] - P[:, a])
            assert (vol > 0).all(), block.type
    assert m["snaps"]


def test_shapes_and_animation(capsys, tmp_path, monkeypatch):
    from PIL import Image

    from snapjump_cli.viz import animation

    # 24 frames instead of MAX_FRAMES: the GIF is written the same way, in a third of the time
    monkeypatch.setitem(animation.write_animation.__kwdefaults__, "max_frames", 24)
    png, gif = tmp_path / "s.png", tmp_path / "a.gif"
    _run(capsys, [*CHEAP, "--shapes", str(png), "--animation", str(gif)])
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(gif) as im:
        assert im.format == "GIF" and im.n_frames > 10
    assert gif.stat().st_size < 5e6


@pytest.mark.parametrize("args,needle", [
    (["--shapes", "s.jpg"], "s.jpg"),
    (["--plot", "c.gif"], "c.gif"),
    (["--jump", "j.gif"], "j.gif"),
    (["--animation", "a.mp4"], "a.mp4"),
    (["--export", "e.vtu"], "e.vtu"),
    (["--revolve", "8"], "--export"),
    (["--export", "e.pvd", "--revolve", "2"], "--revolve"),
    (["--shapes", "nodir/s.png"], "nodir"),
])
def test_bad_outputs_exit_2(capsys, tmp_path, monkeypatch, args, needle):
    monkeypatch.chdir(tmp_path)
    assert main([*CHEAP, "--csv", "c.csv", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err
    assert list(tmp_path.iterdir()) == []


def test_existing_outputs_kept_and_none_written(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "e_steps").mkdir()
    assert main([*CHEAP, "--csv", "c.csv", "--export", "e.pvd"]) == 2
    assert "e_steps" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e_steps"]
    (tmp_path / "s.png").write_text("old")
    assert main([*CHEAP, "--csv", "c.csv", "--shapes", "s.png"]) == 2
    assert (tmp_path / "s.png").read_text() == "old" and not (tmp_path / "c.csv").exists()


def test_a_failing_output_leaves_nothing(capsys, tmp_path, monkeypatch):
    """Every file is rendered before any is put in place: a failure in the last leaves none."""
    import snapjump_cli.viz.export as export

    monkeypatch.chdir(tmp_path)

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(export, "_write_pvd", boom)
    assert main([*CHEAP, "--csv", "c.csv", "--shapes", "s.png", "--export", "e.pvd"]) != 0
    capsys.readouterr()
    assert list(tmp_path.iterdir()) == []


def test_missing_optional_package_is_bad_input(capsys, tmp_path, monkeypatch):
    import sys

    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "meshio", None)
    assert main([*CHEAP, "--export", "e.pvd"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "meshio" in err
