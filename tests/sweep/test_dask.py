"""``--scheduler``: the same sweep on a dask.distributed LocalCluster (loopback only)."""
from __future__ import annotations

import pytest

import snapjump_fake_solvers as fake
from snapjump_cli.sweep import results as res
from snapjump_cli.cli import main as cli_main
from snapjump_cli.sweep.config import load_config
from snapjump_cli.sweep.run import design_key, run_sweep

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cluster():
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, host="127.0.0.1", protocol="tcp",
                      dashboard_address=None) as c:
        yield c


def test_sweep_on_a_dask_cluster_then_resume(grid_file, tmp_path, cluster):
    cfg = load_config(grid_file(chunk_size=4))
    out = tmp_path / "dask.parquet"
    s = run_sweep(cfg, output=out, scheduler=cluster.scheduler_address, solve_fn=fake.flaky_solve, progress=False)
    assert (s.n_designs, s.n_solved) == (40, 32)
    df = res.read_results(out)
    assert df["key"].is_unique and set(df["key"]) == {design_key(p, cfg.mesh, cfg.solver) for p in cfg.designs()}
    assert s.counts == {"ok": 4, "no_snap": 4, "invalid_geometry": 8, "failed": 24}
    assert res.read_metadata(out)["scheduler"] == cluster.scheduler_address
    again = run_sweep(cfg, output=out, scheduler=cluster.scheduler_address, solve_fn=fake.broken_if_called,
                      progress=False)
    assert again.n_solved == 0 and again.n_resumed == 40


def test_cli_scheduler_option(grid_file, tmp_path, cluster, capsys, monkeypatch):
    grid = grid_file(grid={"eta_i": [6], "eta_o": [10]})
    out = tmp_path / "cli.parquet"
    code = cli_main(["sweep", str(grid), "-o", str(out), "--scheduler", cluster.scheduler_address, "--no-progress"],
                    solve_fn=fake.fast_solve)
    cap = capsys.readouterr()
    assert code == 0, cap.err
    assert "10 designs (0 resumed, 8 solved" in cap.out
    assert len(res.read_results(out)) == 10


def test_unreachable_scheduler_is_bad_input(grid_file, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("snapjump_cli.sweep.execution._CONNECT_TIMEOUT_S", 1.0)
    grid = grid_file(grid={"eta_i": [6], "eta_o": [10]})
    out = tmp_path / "x.parquet"
    code = cli_main(["sweep", str(grid), "-o", str(out), "--scheduler", "tcp://127.0.0.1:9", "--no-progress"],
                    solve_fn=fake.fast_solve)
    err = capsys.readouterr().err
    assert code == 2 and "cannot connect to the dask scheduler" in err
    # the invalid designs were recorded before the connection attempt: a later run resumes from them
    assert not out.exists()
