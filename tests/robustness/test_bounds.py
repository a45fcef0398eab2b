"""Class 3 of issue 38: every size, count and time has a bound stated in --help, and every long
computation is under a limit: part files carry the designs once (not N^2), ``-j`` / ``n_jobs`` /
``--budget`` are bounded, a FIFO given as an input is refused before it is read, the margins
computation is under the design's CPU-time limit, and the jump model's work is bounded
(:attr:`snapjump_cli.jump.JumpParams.max_samples`)."""
from __future__ import annotations

import math
import os
import threading
import time

import pyarrow.parquet as pq
import pytest
import yaml

import snapjump_fake_solvers as fake
from conftest import run_cli
from snapjump_cli.sweep.config import load_config
from snapjump_cli.sweep.run import run_sweep
from snapjump_cli.sweep.storage import part_files, parts_dir


def _points(n):
    return [{"eta_i": 6 + 0.001 * j, "theta_i": 80, "eta_o": 10, "theta_o": 86, "mu_ratio": 5.8} for j in range(n)]


def _part_meta_size(tmp_path, n):
    p = tmp_path / f"pts{n}.yaml"
    p.write_text(yaml.safe_dump({"points": _points(n), "mesh": {"order": 1, "nt": 2}}))
    out = tmp_path / f"r{n}.parquet"
    run_sweep(load_config(p), output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False, chunk_size=20,
              consolidate_output=False)
    parts = part_files(parts_dir(out))
    assert len(parts) == n // 20
    return p, out, len(pq.read_schema(parts[0]).metadata[b"snapjump"])


def test_part_files_carry_the_designs_once_not_per_part(tmp_path, capsys):
    _, _, small = _part_meta_size(tmp_path, 40)
    p, out, large = _part_meta_size(tmp_path, 1200)
    assert large - small < 200  # the same few kB whatever the number of designs (was ~70 bytes per design)
    # the digest still tells another list of designs from the one the parts were made for
    p.write_text(yaml.safe_dump({"points": _points(1100), "mesh": {"order": 1, "nt": 2}}))
    code, _, err = run_cli(capsys, "sweep", str(p), "-o", str(out), "-j", "1", solve_fn=fake.fast_solve)
    assert code == 2 and "holds 100 rows that this run would not produce (the designs (grid or points))" in err


@pytest.mark.parametrize("jobs", ["100000", "-1000", str(10**30)])
def test_jobs_beyond_the_machine_are_refused(grid_file, tmp_path, capsys, jobs):
    code, _, err = run_cli(capsys, "sweep", str(grid_file()), "-o", str(tmp_path / "r.parquet"), "-j", jobs,
                           solve_fn=fake.fast_solve)
    assert code == 2 and err.startswith("Error: -j/--jobs: expected 1 to ") and "per core" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "r.parquet.parts").exists()
    code, _, err = run_cli(capsys, "sweep", str(grid_file(n_jobs=100000)), "-o", str(tmp_path / "r.parquet"),
                           solve_fn=fake.fast_solve)
    assert code == 2 and "grid.yaml: n_jobs: expected 1 to" in err


def test_revolve_beyond_its_bound_is_refused_before_the_solve(tmp_path, capsys):
    out = tmp_path / "x.pvd"
    code, _, err = run_cli(capsys, "curve", "--design", "D", "--export", str(out), "--revolve", "1000000000")
    assert code == 2 and "--revolve" in err and "720" in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_an_optimize_budget_beyond_the_limit_is_refused(tmp_path, capsys):
    code, _, err = run_cli(capsys, "optimize", str(tmp_path / "none.yaml"), "--budget", "1000001")
    assert code == 2 and "1000001" in err and "100000" in err


def _no_hang(fn, fifo):
    """Run ``fn`` in a thread; if it still blocks on the FIFO after 20 s, release it and fail."""
    box = {}
    t = threading.Thread(target=lambda: box.setdefault("r", fn()), daemon=True)
    t.start()
    t.join(20)
    if t.is_alive():
        fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)  # a writer that closes: the reader sees the end
        os.close(fd)
        t.join(20)
        pytest.fail("the FIFO was read (blocked)")
    return box["r"]


def test_a_points_file_or_config_that_is_a_fifo_is_refused(tmp_path, capsys):
    fifo = tmp_path / "pts.csv"
    os.mkfifo(fifo)
    p = tmp_path / "g.yaml"
    p.write_text("points: pts.csv\n")
    code, _, err = _no_hang(lambda: run_cli(capsys, "sweep", str(p), "-o", str(tmp_path / "r.parquet")), fifo)
    assert code == 2 and "pts.csv: expected a regular file, got a FIFO" in err
    cfg = tmp_path / "cfg.yaml"
    os.mkfifo(cfg)
    code, _, err = _no_hang(lambda: run_cli(capsys, "sweep", str(cfg), "-o", str(tmp_path / "r.parquet")), cfg)
    assert code == 2 and "cfg.yaml: expected a regular file, got a FIFO" in err


def test_the_margins_computation_is_under_the_design_time_limit():
    from snapjump_cli.fe.limits import TimeLimitExceeded, time_limit
    from snapjump_cli.fe.stability.margins import state_margins

    with time_limit(1e-9):
        t0 = time.thread_time()
        while time.thread_time() - t0 < 1e-3:
            pass
        with pytest.raises(TimeLimitExceeded):  # before any eigen-solve (the model is never touched)
            state_margins(None, None, 0.0, 3)


def _scaled(R):
    from snapjump_cli.jump.trajectory import masses

    s = R / 0.03
    return (2e-3 * s**3, 0.004 * s, 0.006 * s, *masses(2e-6 * s**3, 4e-6 * s**3))


def test_the_jump_model_work_is_bounded_and_answers_below_the_bound_unchanged():
    from snapjump_cli.jump import JumpParams, jump_height
    from snapjump_cli.jump.params import MAX_SAMPLES

    tiny = jump_height(*_scaled(1e-5), JumpParams(max_samples=1e5))  # unbounded: ~10^9 samples, hours
    assert not tiny.complete and math.isfinite(tiny.y_jump_m)
    assert JumpParams().max_samples == MAX_SAMPLES
    for R in (0.03, 0.01, 0.003):  # a design that ends before the bound takes the same steps
        a = jump_height(*_scaled(R), JumpParams())
        b = jump_height(*_scaled(R), JumpParams(max_samples=1e15))
        assert a == b and a.complete
    with pytest.raises(ValueError, match="max_samples"):
        JumpParams(max_samples=0)
