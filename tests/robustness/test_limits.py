"""Bounded before it is big: a grid's size from its num values before any axis is built, a YAML
file's size before it is parsed, a points file's rows before it is read, and per design a CPU-time
limit and a mesh-size limit (refused before solving, naming the size) recorded as a failed row
while the sweep goes on."""
from __future__ import annotations

import pytest
import yaml

from conftest import CHEAP_SCENE, run_cli
from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.config import MAX_DESIGNS, load_config
from snapjump_cli.geometry.caps import Design
from snapjump_cli.mesh.build import MeshTooLarge, mesh_scene
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.fe.solve import SolveFailed, solve_design
from snapjump_cli.sweep.checks import YAML_MAX_BYTES

AXES = {"theta_i": [80], "eta_o": [12], "theta_o": [82], "mu_ratio": [5.8]}


def test_a_huge_num_is_refused_from_the_num_values(tmp_path, capsys):
    p = tmp_path / "g.yaml"
    p.write_text(yaml.safe_dump({"grid": {"eta_i": {"start": 5, "stop": 8, "num": 10**9}, **AXES}}))
    code, _, err = run_cli(capsys, "sweep", str(p), "-o", str(tmp_path / "r.parquet"))
    assert code == 2 and "grid: 1000000000 x 1 x 1 x 1 x 1 = 1000000000 designs exceed the limit" in err
    assert not (tmp_path / "r.parquet.parts").exists()
    # 10**9 values would take tens of GB: the axis is never built, even past the limit of a product
    p.write_text(yaml.safe_dump({"grid": {"eta_i": {"start": 5, "stop": 8, "num": 10**9}, **AXES,
                                          "theta_i": {"start": 70, "stop": 80, "num": 10**9}}}))
    with pytest.raises(ValueError, match=r"10{18} designs exceed the limit of 100000"):
        load_config(p)
    assert MAX_DESIGNS == 100_000


def test_a_huge_yaml_is_refused_before_it_is_parsed(tmp_path, capsys):
    p = tmp_path / "huge.yaml"
    line = "  - {eta_i: 6.2, theta_i: 80, eta_o: 12.1, theta_o: 82, mu_ratio: 5.8}\n"
    p.write_text("points:\n" + line * (YAML_MAX_BYTES // len(line) + 1))
    code, _, err = run_cli(capsys, "sweep", str(p), "-o", str(tmp_path / "r.parquet"))
    assert code == 2 and "larger than 1 MB" in err and "CSV or parquet" in err
    assert "unexpected" not in err  # refused on its size, not after parsing it


def test_a_long_points_file_is_refused_before_it_is_parsed(tmp_path, capsys):
    csv = tmp_path / "pts.csv"
    csv.write_text("eta_i,theta_i,eta_o,theta_o,mu_ratio\n" + "6.2,80,12.1,82,5.8\n" * 30)
    p = tmp_path / "g.yaml"
    p.write_text("points: pts.csv\n")
    code, _, err = run_cli(capsys, "sweep", str(p), "-o", str(tmp_path / "r.parquet"), "--max-designs", "20")
    assert code == 2 and "pts.csv: about 30 designs exceed the limit of 20" in err


def test_a_mesh_over_the_node_limit_is_refused_before_meshing_or_solving():
    thin = Design(eta_i=10**6, theta_i_deg=80, eta_o=12, theta_o_deg=82, mu_ratio=5.8)
    with pytest.raises(MeshTooLarge, match="at least .* nodes \\(counted before meshing\\)") as e:
        mesh_scene(thin, MeshSettings(), max_nodes=20_000)
    assert e.value.estimated and e.value.n_nodes > 10**6
    c = Design(eta_i=8.5, theta_i_deg=60, eta_o=16.5, theta_o_deg=90, mu_ratio=5.8)
    n = mesh_scene(c, MeshSettings()).n_nodes
    with pytest.raises(MeshTooLarge, match=f"the mesh has {n} nodes, more than the limit of {n - 1}"):
        mesh_scene(c, MeshSettings(), max_nodes=n - 1)
    with pytest.raises(SolveFailed, match=f"not solved: the mesh has {n} nodes"):
        solve_design(c, MeshSettings(), SolverSettings(max_nodes=n - 1))


def test_the_time_limit_stops_a_design_with_its_cause():
    c = Design(eta_i=8.5, theta_i_deg=60, eta_o=16.5, theta_o_deg=90, mu_ratio=5.8)
    with pytest.raises(SolveFailed, match=r"time limit of 1e-06 CPU-s reached \(setting time_limit_s\)"):
        solve_design(c, MeshSettings(order=1, nt=1, aspect=4.0), SolverSettings(time_limit_s=1e-6))


def test_the_limits_are_sweep_settings_failed_rows_and_the_sweep_goes_on(tmp_path, capsys):
    small = {"eta_i": 8.5, "theta_i": 60, "eta_o": 16.5, "theta_o": 90, "mu_ratio": 5.8}
    thin = {**small, "eta_i": 1000.0}  # 1065 nodes at this mesh (design C: 28)
    p = tmp_path / "g.yaml"
    p.write_text(yaml.safe_dump({"points": [thin, small], "mesh": {"order": 1, "nt": 1, "aspect": 4.0},
                                 "solver": {"max_nodes": 500}}))
    out = tmp_path / "r.parquet"
    code, stdout, err = run_cli(capsys, "sweep", str(p), "-o", str(out), "-j", "1", "--no-progress")
    assert code == 0, err
    df = res.read_results(out).set_index("eta_i")
    assert df.loc[1000.0, "status"] == "failed" and "more than the limit of 500 nodes" in df.loc[1000.0, "error"]
    assert df.loc[8.5, "status"] == "ok"
    # the limits are not part of a design's key: raising one and retrying the failed rows resumes
    p.write_text(yaml.safe_dump({"points": [thin, small], "mesh": {"order": 1, "nt": 1, "aspect": 4.0},
                                 "solver": {"max_nodes": 5000, "time_limit_s": 1e-6}}))
    code, stdout, err = run_cli(capsys, "sweep", str(p), "-o", str(out), "-j", "1", "--no-progress", "--retry-failed")
    assert code == 0 and "1 resumed" in stdout, err
    df = res.read_results(out).set_index("eta_i")
    assert df.loc[1000.0, "status"] == "failed" and "time limit of 1e-06 CPU-s" in df.loc[1000.0, "error"]
    assert df.loc[8.5, "status"] == "ok"
    assert "time_limit_s" not in df.loc[8.5, "solver_settings"]


def test_the_defaults_are_far_above_the_paper_grid():
    s = SolverSettings()
    # the paper grid's largest mesh has 333 nodes (1707 at nt 4), its slowest design takes ~1.3 CPU-s
    assert s.max_nodes >= 10 * 1707 and s.time_limit_s >= 100 * 1.3
    largest = Design(eta_i=8, theta_i_deg=80, eta_o=20, theta_o_deg=90, mu_ratio=5.8)
    assert mesh_scene(largest, MeshSettings(order=2, nt=4, aspect=2.0)).n_nodes < s.max_nodes


def test_curve_and_mesh_name_the_size_they_refuse(capsys):
    code, _, err = run_cli(capsys, "curve", *CHEAP_SCENE, "--max-nodes", "50")
    assert code == 1 and "more than the limit of 50 nodes" in err and len(err.strip().splitlines()) == 1
    code, _, err = run_cli(capsys, "mesh", "--eta-i", "1e6", "--theta-i", "80", "--eta-o", "12", "--theta-o", "82")
    assert code == 1 and "counted before meshing" in err
    code, _, err = run_cli(capsys, "curve", *CHEAP_SCENE, "--time-limit", "1e-6")
    assert code == 1 and "time limit of 1e-06 CPU-s reached" in err
