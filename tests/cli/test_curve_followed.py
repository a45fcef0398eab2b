"""Every output of a followed solve shows the snap that happens (design B, ``--harmonics 4
--follow``: the followed snap at 3.93 kPa / 41.71 ml releasing 2.44 mJ, not the axisymmetric
12.46 mJ): one solve (module fixture) writing every output, read back; and the actuator's path
of an axisymmetric solve (no unstable branch walked), on a made-up path."""
from __future__ import annotations

import csv
import json
import xml.etree.ElementTree as ET
from types import SimpleNamespace

import numpy as np
import pytest

meshio = pytest.importorskip("meshio")


@pytest.fixture(scope="module")
def followed_b(tmp_path_factory):
    from click.testing import CliRunner

    from snapjump_cli.cli import cli

    d = tmp_path_factory.mktemp("followed")
    # (the animation along the actuator's path: test_curve_viz and the made-up paths below; a GIF of
    # B's followed path would add ~25 s to the suite)
    files = {"plot": d / "b.svg", "shapes": d / "s.png", "export": d / "b.pvd", "csv": d / "b.csv",
             "jump": d / "j.png"}
    args = ["curve", "--design", "B", "--harmonics", "4", "--follow", "--format", "json", "--revolve", "12"]
    for k, p in files.items():
        args += [f"--{k}", str(p)]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout), files


def test_the_answer_is_the_followed_snap(followed_b):
    """Design B end to end (the independent 3D computation's case): harmonic 1 goes first, its
    branch is subcritical and the actuator snaps at the bifurcation, below the axisymmetric V*,
    releasing less energy with less pole travel (the paper's Fig. S16); the state it lands on is
    found from the bifurcation by the sphere path."""
    m, _ = followed_b
    assert m["followed"] is True and m["follow_n"] == 1 and m["follow_N"] == 4
    assert m["follow_kind"] == "subcritical"
    assert m["V_star_m3"] == pytest.approx(m["follow_V_bif_m3"], rel=1e-9)
    assert 0.85 < m["V_star_m3"] / m["axisym_V_star_m3"] < 0.92  # the independent 3D code: 0.88-0.90
    # landed at the bifurcation's volume by the sphere path, not on the traced branch (no path to
    # integrate: the energy two ways and the reference's traced branch, tests/verification/test_follow.py)
    assert m["lower_state_method"] == "descent" and m["follow_note"].startswith("sphere path"), m["follow_note"]
    assert m["dE_rel_diff"] is None
    assert 0 < m["dE_J"] < 0.5 * m["axisym_dE_J"] and 0 < m["dy_pole_m"] < m["axisym_dy_pole_m"]
    assert m["p_star_Pa"] == pytest.approx(3930, rel=2e-3) and m["V_star_m3"] == pytest.approx(41.71e-6, rel=1e-3)
    assert m["dE_J"] == pytest.approx(2.44e-3, rel=5e-3) and m["axisym_dE_J"] > 4 * m["dE_J"]
    assert m["y_jump_axisym_m"] is not None and m["y_jump_m"] is not None


def test_plot_main_curve_is_the_followed_one(followed_b):
    m, f = followed_b
    svg = f["plot"].read_text()
    assert f"dE = {m['dE_J'] * 1e3:.4g} mJ (the followed snap, reported)" in svg
    assert f"axisymmetric dE = {m['axisym_dE_J'] * 1e3:.4g} mJ (does not happen)" in svg
    assert "pressure p [kPa]" in svg and "cavity volume V [ml]" in svg


def test_csv_holds_the_followed_branch(followed_b):
    m, f = followed_b
    with open(f["csv"], newline="") as fh:
        rows = list(csv.DictReader(fh))
    fol = [r for r in rows if r["branch"] == "followed"]
    assert fol and rows[0]["branch"] == "axisymmetric"
    named = {r["state"]: r for r in fol if r["state"]}
    assert set(named) == {"bifurcation", "upper", "lower"}
    assert float(named["upper"]["V_m3"]) == pytest.approx(m["V_star_m3"], rel=1e-9)
    assert float(named["upper"]["p_Pa"]) == pytest.approx(m["p_star_Pa"], rel=1e-9)
    assert float(named["lower"]["V_m3"]) == pytest.approx(m["V_star_m3"], rel=1e-6)
    dy = float(named["upper"]["y_pole_m"]) - float(named["lower"]["y_pole_m"])
    assert dy == pytest.approx(m["dy_pole_m"], rel=1e-6)


def test_export_is_the_actuators_path_in_3d(followed_b):
    m, f = followed_b
    sets = ET.parse(f["export"]).getroot().find("Collection").findall("DataSet")
    meshes = [meshio.read(f["export"].parent / s.get("file")) for s in sets]
    fd = [{k: float(v[0]) for k, v in mm.field_data.items()} for mm in meshes]
    V = np.array([x["V_m3"] for x in fd])
    assert np.all(np.diff(V) >= -1e-15)  # the volume never falls: no unstable branch walked
    codes = [int(x["state"]) for x in fd]
    assert codes[0] == 1 and codes.count(5) == 1 and codes[-2:] == [3, 4]  # start ... bifurcation ... upper, lower
    assert [int(x["jump"]) for x in fd][-1] == 1 and sum(int(x["jump"]) for x in fd) == 1
    up, lo = meshes[-2], meshes[-1]
    assert fd[-2]["V_m3"] == pytest.approx(m["V_star_m3"], rel=1e-9) and fd[-1]["p_Pa"] < fd[-2]["p_Pa"]
    assert {c.type for c in lo.cells} == {"hexahedron", "wedge"}
    assert set(lo.point_data) == {"displacement_mm", "max_principal_stretch"}
    # the lower state is not axisymmetric: the pole (on the axis) moves sideways, and points at phi
    # and phi + pi of one section node move differently in height
    P = lo.points
    axis = np.flatnonzero(np.hypot(P[:, 0], P[:, 1]) < 1e-9)
    assert np.abs(lo.point_data["displacement_mm"][axis, 0]).max() > 1.0
    u_z = lo.point_data["displacement_mm"][:, 2]
    far = np.flatnonzero((np.abs(P[:, 1]) < 1e-9) & (P[:, 0] > 5))  # phi = 0, off the axis
    near = np.flatnonzero((np.abs(P[:, 1]) < 1e-9) & (P[:, 0] < -5))  # phi = pi
    assert abs(u_z[far].mean() - u_z[near].mean()) > 1.0
    # the stretch is the 3D deformation gradient's: no saturated block at the axis (was 7.94)
    assert 1.05 < lo.point_data["max_principal_stretch"].max() < 2.0
    # the undeformed state stands on the ground of the STEP/STL frame
    assert meshes[0].points[:, 2].min() == pytest.approx(0.0, abs=1e-9)


def test_shapes_and_jump(followed_b):
    _, f = followed_b
    assert f["shapes"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f["jump"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


class _Steps(SimpleNamespace):
    def __len__(self) -> int:
        return len(self.state)

    def index(self, name):
        return self.state.index(name) if name in self.state else None


def _steps(V, p, state, on_path=None):
    n = len(V)
    return _Steps(U=np.zeros((n, 3, 2)) + np.arange(n)[:, None, None], V_m3=np.asarray(V, float),
                  p_Pa=np.asarray(p, float), state=state,
                  on_path=np.ones(n, bool) if on_path is None else np.asarray(on_path))


def test_actuator_path_skips_the_unstable_branch():
    """Up to V*, the snap at V* as a jump to the lower state, then the states beyond V*: never the
    states where the traced path's volume falls back (design D's path back to 49 ml)."""
    from snapjump_cli.viz.actuator import actuator_path

    V = [0, 1, 2, 3, 2.5, 1.5, 2.0, 3.0, 3.5]
    p = [0, 5, 7, 6, 3, 1, 2, 4, 5]
    state = ["start", "", "p_max", "upper", "", "", "", "lower", ""]
    res = SimpleNamespace(model=SimpleNamespace(mesh=SimpleNamespace(nodes=np.zeros((3, 2)))), follow=None,
                          metrics={})
    act = actuator_path(res, _steps(V, p, state))
    assert list(act.V_m3) == [0, 1, 2, 3, 3.0, 3.5]
    assert act.state == ["start", "", "p_max", "upper", "lower", ""]
    assert list(act.jump) == [False, False, False, False, True, False]
    assert [float(a[0, 0]) for a in act.A] == [0, 1, 2, 3, 7, 8]  # the steps' own displacements


def test_animation_frames_blend_the_jump():
    from snapjump_cli.viz.actuator import ActuatorPath
    from snapjump_cli.viz.animation import JUMP_FRAMES, animation_frames

    A = [np.full((3, 2), k, float) for k in range(4)]
    act = ActuatorPath([np.zeros(1)] * 4, A, np.array([0, 5, 6, 2.0]), np.array([0, 1, 2, 2.0]),
                       ["start", "", "upper", "lower"], np.array([False, False, False, True]), ["axisymmetric"] * 4,
                       np.zeros((3, 2)))
    frames = animation_frames(act, max_frames=40)
    jump = [t for k, t in frames if k == 3 and t < 1]
    assert len(jump) == JUMP_FRAMES and jump == sorted(jump)
    ks = [k for k, _ in frames]
    assert ks == sorted(ks) and ks[0] == 0 and ks[-1] == 3


def test_actuator_path_of_an_imperfect_actuator():
    """An imperfect actuator (``--imperfection``) is drawn from rest along its own path, up to its
    volume limit, then the jump to its lower state; its states keep their Fourier amplitudes."""
    from snapjump_cli.viz.actuator import actuator_path, branch_rows

    def pt(V, p, s, a):
        return SimpleNamespace(u=np.full(15, float(a)), p=p, zeta=np.array([V]), s=s)

    pts = [pt(0, 0, 0, 0), pt(1, 3, 1, 1), pt(2, 4, 2, 2), pt(1.5, 2, 3, 3), pt(2.5, 3, 4, 4)]
    up, lo = pt(2.2, 4.1, 2.5, 9), pt(2.2, 1.0, float("nan"), 10)
    mh = SimpleNamespace(hn=np.array([0, 1]), L=1.0, S=1.0, X=np.zeros((3, 2)),
                         mesh=SimpleNamespace(node_sets={"pole_lower": np.array([0])}),
                         total_amplitudes=lambda u: u.reshape(3, 5), energy=lambda u: float(u.sum()))
    r = SimpleNamespace(model=mh, states=SimpleNamespace(upper=up, lower=lo, lower_method="descent"),
                        tracer=SimpleNamespace(sc=np.array([1.0])), path=SimpleNamespace(points=pts))
    res = SimpleNamespace(model=SimpleNamespace(mesh=SimpleNamespace(nodes=np.zeros((3, 2)))), follow=None,
                          metrics={})
    steps = _steps([0, 1, 2], [0, 1, 2], ["start", "p_max", "upper"])
    act = actuator_path(res, steps, branch=r, kind="imperfect")
    assert list(act.V_m3) == [0, 1, 2, 2.2, 2.2] and act.state == ["start", "", "", "upper", "lower"]
    assert list(act.jump) == [False, False, False, False, True] and set(act.branch) == {"imperfect"}
    assert act.followed and act.A[-1].shape == (3, 5) and act.A[-1][0, 0] == 10.0
    rows = branch_rows(res, r, "imperfect")
    assert rows["state"] == ["", "", "", "upper", "", "", "lower"]  # the upper state at its arc length
    assert rows["on_path"][-1] == 0 and rows["V_m3"][3] == 2.2 and np.isnan(rows["arc_length"][-1])
