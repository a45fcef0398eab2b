"""Class 5 of issue 38: resume and messages that do not mislead. Only the statuses the sweep
writes count as done; a design named twice in a points list is refused naming both entries; a
failed write says "free some space" only when the disk is full (:func:`snapjump_cli.files.remedy`).
(The lock taken over after a pid was reused: test_locks.py.)"""
from __future__ import annotations

import errno

import pyarrow.parquet as pq
import pyarrow as pa
import yaml

import snapjump_fake_solvers as fake
from conftest import run_cli
from snapjump_cli.sweep.config import load_config
from snapjump_cli.sweep.run import run_sweep


def test_rows_with_a_status_the_tool_does_not_write_are_solved_again(grid_file, tmp_path, caplog):
    out = tmp_path / "r.parquet"
    cfg = load_config(grid_file())
    run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    t = pq.read_table(out)
    status = t.column("status").to_pylist()
    status[1], status[5] = "pending", "OK"  # edited by hand / written by another tool
    pq.write_table(t.set_column(t.schema.get_field_index("status"), "status", pa.array(status)), out)
    s = run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    assert s.n_solved == 2 and s.n_resumed == 6
    assert "2 rows have a status snapjump does not write ('OK', 'pending')" in caplog.text
    assert set(pq.read_table(out).column("status").to_pylist()) <= {"ok", "no_snap"}


def test_a_design_named_twice_in_a_points_list_is_refused(tmp_path, capsys):
    p = tmp_path / "pts.yaml"
    d = {"eta_i": 6, "theta_i": 80, "eta_o": 10, "theta_o": 86, "mu_ratio": 5.8}
    p.write_text(yaml.safe_dump({"points": [d, {**d, "eta_o": 5}, dict(d)]}))
    code, _, err = run_cli(capsys, "sweep", str(p), "-o", str(tmp_path / "r.parquet"), solve_fn=fake.fast_solve)
    assert code == 2 and "points[2]: the same design as points[0]; give each design once" in err
    assert not (tmp_path / "r.parquet").exists()


def _in_the_way(out):
    def solve(design, mesh, solver):
        out.mkdir(exist_ok=True)  # something else takes the output's place while the sweep runs
        return fake.fast_solve(design, mesh, solver)
    return solve


def test_something_in_the_way_is_not_reported_as_a_full_disk(grid_file, tmp_path, capsys):
    out = tmp_path / "r.parquet"
    code, _, err = run_cli(capsys, "sweep", str(grid_file()), "-o", str(out), "-j", "1", solve_fn=_in_the_way(out))
    assert code == 2 and "is a directory" in err
    assert "free some space" not in err and "move what is in the way" in err
    from snapjump_cli.files import remedy

    assert remedy(OSError(errno.ENOSPC, "No space left on device")) == "free some space"
