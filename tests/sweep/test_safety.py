"""A sweep never loses or mixes rows: the output lock, refusing other settings, per-row provenance,
file modes from the umask, filesystem errors, metric validation, the design-count limit and the
progress output (issue 11)."""
from __future__ import annotations

import json
import os
import socket
import stat

import pytest

import snapjump_fake_solvers as fake
from snapjump_cli.sweep import results as res
from snapjump_cli.cli import main as cli_main
from snapjump_cli.sweep.config import load_config
from snapjump_cli.sweep.rows import fill_row
from snapjump_cli.sweep.storage import OutputLock, lock_path
from snapjump_cli.sweep.run import SweepInputError, run_sweep


def _dead_pid() -> int:
    pid = 2**22 - 7
    while True:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return pid
        except PermissionError:
            pass
        pid -= 1


def test_a_second_sweep_into_the_same_output_is_refused_naming_the_holder(grid_file, tmp_path, capsys):
    out = tmp_path / "r.parquet"
    with OutputLock(out):
        with pytest.raises(SweepInputError, match=rf"pid {os.getpid()} on {socket.gethostname()}, started 20"):
            run_sweep(load_config(grid_file()), output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
        code = cli_main(["sweep", str(grid_file()), "-o", str(out), "-j", "1"], solve_fn=fake.fast_solve)
        err = capsys.readouterr().err
        assert code == 2 and "another sweep is writing into this output" in err and str(lock_path(out)) in err
        assert not out.exists() and not (tmp_path / "r.parquet.parts").exists()
    assert not lock_path(out).exists()  # released


def test_a_stale_lock_is_taken_over_with_a_warning(grid_file, tmp_path, caplog):
    out = tmp_path / "r.parquet"
    lock_path(out).write_text(json.dumps({"pid": _dead_pid(), "host": socket.gethostname(), "started_utc": "x"}))
    s = run_sweep(load_config(grid_file()), output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    assert s.n_solved == 32 and len(res.read_results(out)) == 40
    assert "taking over a stale lock" in caplog.text
    assert not lock_path(out).exists()


def test_a_lock_from_another_host_is_respected(grid_file, tmp_path):
    out = tmp_path / "r.parquet"
    lock_path(out).write_text(json.dumps({"pid": _dead_pid(), "host": "elsewhere.example", "started_utc": "x"}))
    with pytest.raises(SweepInputError, match="elsewhere.example"):
        run_sweep(load_config(grid_file()), output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)


def test_other_mesh_is_refused_saying_what_differs(grid_file, tmp_path, capsys):
    out = tmp_path / "r.parquet"
    run_sweep(load_config(grid_file()), output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    before = out.read_bytes()
    g2 = grid_file("b.yaml", mesh={"order": 1, "nt": 3})
    code = cli_main(["sweep", str(g2), "-o", str(out), "-j", "1"], solve_fn=fake.fast_solve)
    err = capsys.readouterr().err
    assert code == 2 and "mesh" in err and "'nt': 2" in err and "'nt': 3" in err and "--append" in err
    assert out.read_bytes() == before
    code = cli_main(["sweep", str(g2), "-o", str(out), "-j", "1", "--append"], solve_fn=fake.fast_solve)
    assert code == 0
    df = res.read_results(out)
    assert len(df) == 80 and sorted(df["mesh_nt"].unique()) == [2, 3]


def test_rows_carry_their_provenance_and_the_umask_mode(grid_file, tmp_path):
    out = tmp_path / "r.parquet"
    old = os.umask(0o027)
    try:
        run_sweep(load_config(grid_file(solver={"tol": 1.0e-7})), output=out, n_jobs=1, solve_fn=fake.fast_solve,
                  progress=False)
    finally:
        os.umask(old)
    assert stat.S_IMODE(out.stat().st_mode) == 0o640
    df = res.read_results(out)
    from snapjump_cli import __version__

    assert (df["snapjump_version"] == __version__).all()
    assert json.loads(df["solver_settings"].iloc[0])["tol"] == 1.0e-7
    assert df["solver_settings"].nunique() == 1 and df["git_commit"].nunique() <= 1


@pytest.mark.parametrize("where", ["file", "readonly"])
def test_unwritable_output_is_exit_2_naming_the_path_and_writes_nothing(grid_file, tmp_path, capsys, where):
    if where == "file":
        f = tmp_path / "a_file"
        f.write_text("x")
        out = f / "r.parquet"
    else:
        out = "/proc/snapjump-test/r.parquet"  # a file system nobody can create files in
    code = cli_main(["sweep", str(grid_file()), "-o", str(out), "-j", "1"], solve_fn=fake.fast_solve)
    err = capsys.readouterr().err
    assert code == 2 and str(out) in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("bad, cause", [
    ({"snaps": float("nan")}, "snaps=nan"),
    ({"snaps": "no"}, "snaps='no'"),
    ({"n_steps": float("nan")}, "n_steps=nan"),
    ({"n_newton": 2.5}, "n_newton=2.5"),
    ({"dE_J": -1e-3}, "dE_J=-0.001 (expected > 0)"),
    ({"dy_pole_m": 0.0}, "dy_pole_m=0.0 (expected > 0)"),
    ({"dE_J": "1e-3"}, "dE_J='1e-3'"),
])
def test_a_bad_metric_makes_the_row_failed_with_its_cause(bad, cause):
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.settings import MeshSettings, SolverSettings

    d = Design(eta_i=6, theta_i_deg=70, eta_o=10, theta_o_deg=80, mu_ratio=5.8)
    good = fake.fast_solve(d, MeshSettings(), SolverSettings())
    row: dict = {}
    fill_row(row, good)
    assert row["status"] == "ok", row["error"]
    row = {}
    fill_row(row, {**good, **bad})
    assert row["status"] == "failed" and cause in row["error"]


def test_too_many_designs_are_refused_before_anything_runs(tmp_path, capsys):
    g = tmp_path / "huge.yaml"
    g.write_text("grid: {eta_i: {start: 5, stop: 8, num: 1000000}, theta_i: [80], eta_o: [10], theta_o: [85],"
                 " mu_ratio: [1]}\n")
    out = tmp_path / "r.parquet"
    code = cli_main(["sweep", str(g), "-o", str(out)], solve_fn=fake.broken_if_called)
    err = capsys.readouterr().err
    assert code == 2 and "1000000 designs exceed the limit of 100000" in err and "--max-designs" in err
    assert not out.exists() and not lock_path(out).exists()


def test_count_and_estimate_are_printed_and_progress_is_plain_lines_off_a_terminal(grid_file, tmp_path, capsys):
    out = tmp_path / "r.parquet"
    code = cli_main(["sweep", str(grid_file()), "-o", str(out), "-j", "1"], solve_fn=fake.fast_solve)
    err = capsys.readouterr().err
    assert code == 0
    assert "sweep: 40 designs (0 already recorded, 8 invalid geometry, 32 to solve on 1 worker, roughly" in err
    assert "\r" not in err and "sweep: 40/40 designs (100 %)" in err


@pytest.mark.parametrize("argv", [["-q", "sweep"], ["sweep", "-q"]])
def test_quiet_means_quiet_before_or_after_the_command(grid_file, tmp_path, capsys, argv):
    out = tmp_path / "r.parquet"
    code = cli_main([*argv, str(grid_file()), "-o", str(out), "-j", "1"], solve_fn=fake.fast_solve)
    cap = capsys.readouterr()
    assert code == 0 and cap.err == "" and "40 designs" in cap.out


def test_verbose_after_the_command(grid_file, tmp_path, caplog):
    import logging

    out = tmp_path / "r.parquet"
    with caplog.at_level(logging.DEBUG):
        code = cli_main(["sweep", "-v", str(grid_file()), "-o", str(out), "-j", "1", "--no-progress"],
                        solve_fn=fake.fast_solve)
    assert code == 0
    assert logging.getLogger("snapjump_cli").level == logging.INFO
    assert any("sweep done" in r.message for r in caplog.records)


def _interrupted_in_a_kernel(after: int):
    """A solver that, from its ``after``-th call on, fails as a compiled kernel does when Ctrl-C
    arrives inside it: a SystemError whose cause is the KeyboardInterrupt."""
    calls = []

    def solve(design, mesh, solver):
        calls.append(design)
        if len(calls) > after:
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt as ki:
                raise SystemError("CPUDispatcher(<function mh_elements>) returned a result with an exception set") from ki
        return fake.fast_solve(design, mesh, solver)

    return solve, calls


def test_an_interruption_inside_a_kernel_stops_the_run_and_records_no_failed_row(grid_file, tmp_path):
    out = tmp_path / "r.parquet"
    cfg = load_config(grid_file(chunk_size=1))
    solve, calls = _interrupted_in_a_kernel(after=2)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(cfg, output=out, n_jobs=1, solve_fn=solve, progress=False)
    parts = sorted((tmp_path / "r.parquet.parts").glob("part-*.parquet"))
    rows = [r for p in parts for r in res.read_results(p).to_dict("records")]
    solved = [r for r in rows if r["status"] != "invalid_geometry"]
    assert len(solved) == 2 and all(r["status"] != "failed" for r in rows)
    # resumed, the interrupted design is solved, not skipped as failed
    run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    df = res.read_results(out)
    assert (df["status"] != "failed").all() and len(df) == len(list(cfg.designs()))


def test_a_systemerror_of_its_own_is_a_failed_row(grid_file, tmp_path):
    from snapjump_cli.sweep.execution import interruption

    try:
        try:
            raise ValueError("bad")
        except ValueError as v:
            raise SystemError("returned a result with an exception set") from v
    except SystemError as e:
        assert interruption(e) is None
    try:
        raise SystemExit(3)
    except SystemExit as e:
        assert interruption(e) is e


def test_the_time_estimate_counts_the_harmonic_check_and_the_followed_branches():
    from snapjump_cli.settings import MeshSettings, SolverSettings
    from snapjump_cli.sweep import run

    m = MeshSettings(order=2, nt=2, aspect=3.0)
    start = run.REF_STARTUP_S
    plain = run.estimate_seconds(100, m, 2)
    assert plain == pytest.approx(start + 100 * run.REF_CPU_S_PER_DESIGN / 2)
    checked = run.estimate_seconds(100, m, 2, SolverSettings(harmonics=4))
    followed = run.estimate_seconds(100, m, 2, SolverSettings(harmonics=4, follow=True, time_limit_s=900))
    assert checked - start == pytest.approx((plain - start) * run.REF_CHECK_FACTOR)
    per_followed = sum(share * cpu for share, cpu in run.REF_FOLLOW.values())
    assert followed == pytest.approx(checked + 100 * per_followed / 2)
    # a followed design costs at most the time limit; nothing to solve costs nothing
    capped = run.estimate_seconds(100, m, 2, SolverSettings(harmonics=4, follow=True, time_limit_s=60))
    assert capped == pytest.approx(checked + 100 * sum(share * min(cpu, 60.0) for share, cpu in run.REF_FOLLOW.values()) / 2)
    assert run.estimate_seconds(0, m, 2) == 0.0


def test_the_time_estimate_scales_with_the_mesh_and_shares_only_the_workers_it_can_use():
    from snapjump_cli.settings import MeshSettings
    from snapjump_cli.sweep import run

    grid = MeshSettings(order=2, nt=2, aspect=3.0)
    assert run.mesh_scale(grid) == pytest.approx(1.0)
    assert run.mesh_scale(MeshSettings(order=2, nt=4, aspect=3.0)) == pytest.approx(4.0)
    assert run.mesh_scale(MeshSettings(order=1, nt=2, aspect=3.0)) == pytest.approx(1 / 3)
    # two designs on eight workers take as long as on two
    assert run.estimate_seconds(2, grid, 8) == pytest.approx(run.estimate_seconds(2, grid, 2))


def test_the_time_estimate_takes_the_load_measured_at_run_time():
    from snapjump_cli.settings import MeshSettings
    from snapjump_cli.sweep import run

    grid = MeshSettings(order=2, nt=2, aspect=3.0)
    assert 1.0 <= run.load_factor() <= 10.0
    assert run.estimate_seconds(100, grid, 2, slowdown=3.0) == pytest.approx(3 * run.estimate_seconds(100, grid, 2))
    assert run.estimate_seconds(100, grid, 2, slowdown=0.5) == pytest.approx(run.estimate_seconds(100, grid, 2))
