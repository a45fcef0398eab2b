"""Every input checked where it enters: radii that overflow, a missing matplotlib, hand-made
invalid rows, output formats by suffix, excluded designs not counted as jumps, an unreachable
scheduler, damaged part files."""
from __future__ import annotations

import sys

import pandas as pd
import pytest

import snapjump_fake_solvers as fake
from conftest import CHEAP_SCENE, GRID, run_cli
from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.storage import parts_dir


@pytest.mark.parametrize("command", ["curve", "mesh"])
@pytest.mark.parametrize("radius", ["1e200", "1e-30"])
def test_absurd_radii_are_refused_where_they_enter(capsys, command, radius):
    code, _, err = run_cli(capsys, command, "--design", "C", "--radius-mm", radius)
    assert code == 2 and err.strip() == f"Error: --radius-mm must lie in [0.001, 1e+06], got {float(radius):g}"


def test_a_sweeps_radius_is_checked_in_the_config(tmp_path, capsys, grid_file):
    code, _, err = run_cli(capsys, "sweep", str(grid_file(R_i=1e197)), "-o", str(tmp_path / "r.parquet"))
    assert code == 2 and "R_i: expected a radius in [1e-06, 1000] m, got 1e+197" in err


def test_curve_plot_without_matplotlib_is_one_line_before_solving(tmp_path, capsys, monkeypatch):
    import snapjump_cli.fe.solve as solve

    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    monkeypatch.setattr(solve, "solve_checked", lambda *a, **k: pytest.fail("solved before checking matplotlib"))
    code, _, err = run_cli(capsys, "curve", *CHEAP_SCENE, "--plot", str(tmp_path / "c.png"))
    assert code == 2 and "--plot needs matplotlib" in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def _edited(results_file, **changes) -> str:
    df = res.read_results(results_file)
    ok = df.index[df["status"] == "ok"]
    for col, value in changes.items():
        df.loc[ok[1], col] = value
    res.write_frame_atomic(df, results_file, res.read_metadata(results_file))
    return df.loc[ok[1], "key"]


def test_rank_rechecks_rows_an_invalid_ok_row_is_never_ranked(results_file, capsys, caplog):
    key = _edited(results_file, dE_J=-5.0)
    code, _, err = run_cli(capsys, "rank", str(results_file), "--format", "json")
    assert code == 0, err
    ranked = res.read_results(results_file.with_name("r.ranked.parquet")).set_index("key")
    assert pd.isna(ranked.loc[key, "rank"]) and pd.isna(ranked.loc[key, "y_jump_m"])
    assert ranked.loc[key, "jump_reason"] == "invalid ok row: dE_J=-5 (expected > 0)"
    assert pd.isna(ranked.loc[key, "jumped"])
    assert "1 ok row(s) break the row contract" in caplog.text


def test_rank_writes_the_format_its_suffix_names(results_file, tmp_path, capsys):
    out = tmp_path / "t.csv"
    code, _, err = run_cli(capsys, "rank", str(results_file), "-o", str(out))
    assert code == 0, err
    assert out.read_text().startswith("rank,") and len(pd.read_csv(out)) == 8
    code, _, err = run_cli(capsys, "rank", str(results_file), "-o", str(tmp_path / "t.xlsx"))
    assert code == 2 and "expected a .parquet or .csv file name" in err
    assert sorted(p.name for p in tmp_path.glob("t.*")) == ["t.csv"]


def test_excluded_asymmetric_designs_are_not_counted_as_jumps(results_file, capsys):
    df = res.read_results(results_file)
    df["asym_first"] = pd.array([True] * len(df), dtype="boolean")
    df["asym_n"] = pd.array([1] * len(df), dtype="Int64")
    res.write_frame_atomic(df, results_file, res.read_metadata(results_file))
    code, out, err = run_cli(capsys, "rank", str(results_file), "--exclude-asymmetric", "--format", "json",
                             "-o", str(results_file.with_name("x.parquet")))
    assert code == 0, err
    import json

    doc = json.loads(out)
    assert doc["n_jumped"] == 0
    ranked = res.read_results(results_file.with_name("x.parquet"))
    assert ranked["rank"].isna().all() and ranked["jumped"].isna().all()
    code, out, err = run_cli(capsys, "rank", str(results_file), "--format", "json", "--overwrite",
                             "-o", str(results_file.with_name("x.parquet")))
    assert json.loads(out)["n_jumped"] > 0  # without the option they are ranked and jump


def test_an_unreachable_scheduler_leaves_no_parts_folder(tmp_path, capsys, grid_file, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr("snapjump_cli.sweep.execution._CONNECT_TIMEOUT_S", 1.0)
    out = tmp_path / "x.parquet"
    code, _, err = run_cli(capsys, "sweep", str(grid_file()), "-o", str(out), "--scheduler", "tcp://127.0.0.1:1",
                           "--no-progress", solve_fn=fake.fast_solve)
    assert code == 2 and "cannot connect to the dask scheduler" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grid.yaml"]


def test_a_damaged_part_file_is_named_with_what_to_do(tmp_path, capsys, grid_file):
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.sweep.run import run_sweep

    out = tmp_path / "r.parquet"
    run_sweep(load_config(grid_file()), output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False, chunk_size=2,
              consolidate_output=False)
    part = sorted(parts_dir(out).glob("part-*.parquet"))[1]
    part.write_bytes(part.read_bytes()[:100])  # truncated
    code, _, err = run_cli(capsys, "sweep", str(grid_file()), "-o", str(out), "-j", "1", "--no-progress",
                           solve_fn=fake.fast_solve)
    assert code == 2 and f"{part}: damaged part file" in err and "delete this file and run the same command" in err
    part.unlink()
    code, stdout, err = run_cli(capsys, "sweep", str(grid_file()), "-o", str(out), "-j", "1", "--no-progress",
                                solve_fn=fake.fast_solve)
    assert code == 0 and "6 resumed, 2 solved" in stdout, err
    assert len(res.read_results(out)) == len(GRID["eta_i"]) * len(GRID["eta_o"]) * len(GRID["theta_o"])


def test_special_files_are_refused_as_inputs(tmp_path, capsys):
    import os

    fifo = tmp_path / "r.parquet"
    os.mkfifo(fifo)  # reading it would block until someone writes
    code, _, err = run_cli(capsys, "rank", str(fifo))
    assert code == 2 and "expected a parquet file, got a FIFO (named pipe)" in err
    spec = tmp_path / "s.yaml"
    spec.write_text("bounds: {eta_i: [5, 8], theta_i: 80, eta_o: 12, theta_o: 82, mu_ratio: 5.8}\n")
    code, _, err = run_cli(capsys, "optimize", str(spec), "--from", str(fifo), "-o", str(tmp_path / "o.parquet"))
    assert code == 2 and "got a special file" in err


def test_rank_plots_without_matplotlib_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, monkeypatch, results_file):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    out = tmp_path / "ranked.parquet"
    code, _, err = run_cli(capsys, "rank", str(results_file), "-o", str(out), "--plots", str(tmp_path / "p"))
    assert code == 2 and "--plots needs matplotlib" in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path / "p").exists()
