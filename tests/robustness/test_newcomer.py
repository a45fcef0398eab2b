"""Item 7 of issue 37: the errors a newcomer meets. Angles that look like radians in a degree field
get a warning naming the key; sweep and rank print the reasons of invalid and failed designs,
grouped (:func:`snapjump_cli.sweep.results.failure_reasons`); optimize creates its output's folder
as sweep and rank do. (rank on a CSV: test_one_line.py; Ctrl-C: test_interrupts.py.)"""
from __future__ import annotations

import json

import yaml

import snapjump_fake_solvers as fake
from conftest import GRID, run_cli


def test_angles_that_look_like_radians_are_named(tmp_path, capsys, caplog):
    p = tmp_path / "g.yaml"
    p.write_text(yaml.safe_dump({"grid": {**GRID, "theta_i": [1.2, 1.4], "theta_o": [1.45]},
                                 "mesh": {"order": 1, "nt": 2}}))
    code, _, err = run_cli(capsys, "sweep", str(p), "-o", str(tmp_path / "r.parquet"), "-j", "1",
                           solve_fn=fake.fast_solve)
    assert code == 0
    assert "grid.theta_i: 1.2, 1.4 look like radians, but this angle is in degrees" in caplog.text
    assert "grid.theta_o: 1.45 look like radians" in caplog.text
    caplog.clear()
    q = tmp_path / "pts.yaml"
    q.write_text(yaml.safe_dump({"points": [{"eta_i": 6, "theta_i": 80, "eta_o": 10, "theta_o": 1.5, "mu_ratio": 5.8}]}))
    run_cli(capsys, "sweep", str(q), "-o", str(tmp_path / "q.parquet"), "-j", "1", solve_fn=fake.fast_solve)
    assert "points (column theta_o): 1.5 look like radians" in caplog.text and "theta_i" not in caplog.text


def test_sweep_and_rank_print_the_reasons_of_invalid_and_failed_designs(grid_file, tmp_path, capsys):
    grid = grid_file(grid={**GRID, "theta_o": [78, 82, 86]})  # 78 < theta_i = 80: invalid; 86 fails
    out = tmp_path / "r.parquet"
    code, stdout, err = run_cli(capsys, "sweep", str(grid), "-o", str(out), "-j", "1", solve_fn=fake.flaky_solve)
    assert code == 0, err
    assert "invalid_geometry: 4 designs, why:" in err
    assert "failed: 4 designs, why:\n  4 x SolveFailed: continuation stalled at step # (ds below ds_min)" in err
    code, stdout, err = run_cli(capsys, "rank", str(out), "-o", str(tmp_path / "k.parquet"))
    assert code == 0 and "failed: 4 designs, why:" in err and "invalid_geometry: 4 designs" in err
    code, stdout, err = run_cli(capsys, "rank", str(out), "-o", str(tmp_path / "j.parquet"), "--format", "json")
    assert any(line.startswith("failed: 4") for line in json.loads(stdout)["reasons"])


def test_optimize_creates_the_folder_of_its_output(tmp_path, capsys):
    spec = tmp_path / "s.yaml"
    spec.write_text(yaml.safe_dump({"bounds": {"eta_i": [6, 7], "theta_i": 80, "eta_o": 10, "theta_o": 86,
                                               "mu_ratio": 5.8}, "budget": 3, "confirm": False,
                                    "mesh": {"order": 1, "nt": 2}}))
    out = tmp_path / "new" / "deeper" / "o.parquet"
    code, _, err = run_cli(capsys, "optimize", str(spec), "-o", str(out), "-j", "1", "--no-plots",
                           solve_fn=fake.fast_solve, warm_up_fn=None)
    assert "lock" not in err and code in (0, 1), err
    assert out.exists()
