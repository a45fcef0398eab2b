"""The sweep machinery with cheap fake solvers: statuses, chunks, resume, schema, provenance,
thread caps and surviving a worker that dies."""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import snapjump_fake_solvers as fake
from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.config import load_config, parse_config
from snapjump_cli.sweep.rows import RESULT_KEYS
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.sweep.run import (
    SweepInputError,
    consolidate,
    design_key,
    done_keys,
    parts_dir,
    run_sweep,
)


def _calls(log: Path) -> list[tuple[float, ...]]:
    if not log.exists():
        return []
    return [tuple(float(x) for x in line.split()[:5]) for line in log.read_text().splitlines()]


def _check_complete(out: Path, config) -> "pd.DataFrame":  # noqa: F821
    df = res.read_results(out)
    keys = [design_key(p, config.mesh, config.solver) for p in config.designs()]
    assert sorted(df["key"]) == sorted(keys), "missing or extra rows"
    assert df["key"].is_unique, "duplicated rows"
    assert list(df["index"]) == list(range(config.n_designs))
    return df


#: The key of design (6, 80, 12, 82, 1) on the paper grid's mesh with the default solver settings
#: (KEY_VERSION v2; v1, where ds0 = 0.02 meant a first step of 0.05, gave "ee9521724d224adf09d5c438").
KNOWN_KEY = "d753a211181c40b601bb2872"


def test_design_key_is_stable():
    c = parse_config({"grid": {"eta_i": [6], "theta_i": [80], "eta_o": [12], "theta_o": [82], "mu_ratio": [1]}})
    p = next(c.designs())
    k = design_key(p, c.mesh, c.solver)
    assert k == design_key(p.design_kwargs(), MeshSettings(), SolverSettings())
    same = dict(p.design_kwargs(), eta_i=6, theta_i_deg=80)  # ints hash like floats
    assert design_key(same, c.mesh, c.solver) == k
    assert design_key(p, MeshSettings(order=1), c.solver) != k
    assert design_key(p, c.mesh, SolverSettings(tol=c.solver.tol * 10)) != k
    assert design_key(dict(p.design_kwargs(), mu_ratio=5.8), c.mesh, c.solver) != k
    assert len(k) == 24 and set(k) <= set("0123456789abcdef")
    # the key of a fixed design and settings is fixed across versions (else old results are not reused)
    assert design_key({"eta_i": 6.0, "theta_i_deg": 80.0, "eta_o": 12.0, "theta_o_deg": 82.0, "mu_ratio": 1.0,
                       "R_i": 0.03, "mu_i": 0.35e6, "J_m": 24.0, "t_ring_frac": 1 / 30, "w_ring_frac": 0.1},
                      MeshSettings(order=2, nt=2, aspect=3.0), SolverSettings()) == KNOWN_KEY


def test_statuses_failures_and_invalid_designs(grid_file, tmp_path, monkeypatch):
    log = tmp_path / "calls.log"
    monkeypatch.setenv("SNAPJUMP_FAKE_LOG", str(log))
    cfg = load_config(grid_file())
    out = tmp_path / "r.parquet"
    s = run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.flaky_solve, progress=False)
    df = _check_complete(out, cfg)
    assert s.n_designs == 40 and s.n_solved == 32 and s.n_resumed == 0
    # invalid designs (theta_o = 78 < theta_i = 80) are recorded and never meshed/solved
    inv = df[df["theta_o_deg"] == 78]
    assert (inv["status"] == "invalid_geometry").all() and inv["error"].str.contains("theta_i < theta_o").all()
    assert all(c[3] != 78 for c in _calls(log))
    # SolveFailed in the worker -> failed with the exception text
    f86 = df[df["theta_o_deg"] == 86]
    assert (f86["status"] == "failed").all()
    assert f86["error"].str.startswith("SolveFailed: continuation stalled").all()
    # NaN / inf metric in a snapping result -> failed, never stored as ok
    for th, name in ((88, "dE_J"), (84, "h_imp_m")):
        rows = df[df["theta_o_deg"] == th]
        assert (rows["status"] == "failed").all() and rows["error"].str.contains(name).all()
        assert rows[name].isna().all()
    # no snap (theta_o = 82, mu_ratio = 1)
    ns = df[(df["theta_o_deg"] == 82) & (df["mu_ratio"] == 1)]
    assert (ns["status"] == "no_snap").all() and (~ns["snaps"].astype(bool)).all()
    ok = df[df["status"] == "ok"]
    assert len(ok) == 4
    for k in res.FLOAT_RESULT_KEYS:  # the optional ones (mesh re-solve only) are null or finite
        assert ok[k].map(math.isfinite).all() or (k in res.OPTIONAL_FLOAT_KEYS and ok[k].isna().all()), k
    assert s.counts == {"ok": 4, "no_snap": 4, "invalid_geometry": 8, "failed": 24}


def test_missing_result_key_or_none_metric_is_failed(grid_file, tmp_path):
    cfg = load_config(grid_file(grid={"eta_o": [7, 9], "theta_o": [82], "mu_ratio": [5.8]}))
    out = tmp_path / "r.parquet"
    run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.flaky_solve, progress=False)
    df = res.read_results(out)
    assert (df["status"] == "failed").all()
    assert df.loc[df["eta_o"] == 7, "error"].str.contains("lacks keys: L0_m").all()
    assert df.loc[df["eta_o"] == 9, "error"].str.contains("dy_pole_upper_m=None").all()


def test_chunks_are_atomic_parts_then_consolidated(grid_file, tmp_path):
    cfg = load_config(grid_file(chunk_size=7))
    out = tmp_path / "r.parquet"
    run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False, consolidate_output=False)
    parts = sorted(parts_dir(out).glob("part-*.parquet"))
    assert [p.name for p in parts] == [f"part-{i:06d}.parquet" for i in range(6)]  # ceil(40 / 7)
    assert [pq.read_metadata(p).num_rows for p in parts] == [7, 7, 7, 7, 7, 5]
    assert not list(parts_dir(out).glob("*.tmp")) and not out.exists()
    assert len(done_keys(out)) == 40
    # a rerun finds everything done, solves nothing and consolidates
    s = run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.broken_if_called, progress=False)
    assert s.n_resumed == 40 and s.n_solved == 0
    _check_complete(out, cfg)
    assert not parts_dir(out).exists()


def test_resume_after_interrupt(grid_file, tmp_path, monkeypatch):
    """Ctrl-C in the middle: finished rows are flushed; the rerun solves only the rest."""
    log = tmp_path / "calls.log"
    monkeypatch.setenv("SNAPJUMP_FAKE_LOG", str(log))
    cfg = load_config(grid_file(chunk_size=5))
    out = tmp_path / "r.parquet"
    fake.INTERRUPT_AFTER[0] = 13
    with pytest.raises(KeyboardInterrupt):
        run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.interrupting_solve, progress=False)
    first = _calls(log)
    assert len(first) == 13
    assert len(done_keys(out)) == 8 + 12  # invalid rows + the 12 finished solves (flushed on the way out)
    s = run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    assert s.n_resumed == 20 and s.n_solved == 20
    second = _calls(log)[13:]
    assert len(second) == 20 and not set(second) & set(first[:12])
    _check_complete(out, cfg)


def test_retry_failed_and_extended_grid(grid_file, tmp_path):
    out = tmp_path / "r.parquet"
    cfg = load_config(grid_file())
    run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.flaky_solve, progress=False)
    s = run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False, retry_failed=True)
    assert s.n_solved == 24 and s.counts["failed"] == 0
    df = _check_complete(out, cfg)
    assert (df.loc[df["theta_o_deg"] == 86, "status"] == "ok").all()
    # extend the grid: only the new designs are solved
    big = load_config(grid_file("big.yaml", grid={"theta_o": [78, 82, 84, 86, 88, 90]}))
    s = run_sweep(big, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    assert (s.n_resumed, s.n_solved) == (40, 8)
    _check_complete(out, big)


def df_rows_commit(out) -> set:
    return {None if v is pd.NA else v for v in res.read_results(out)["git_commit"]}


def test_schema_and_provenance(grid_file, tmp_path):
    cfg = load_config(grid_file())
    out = tmp_path / "r.parquet"
    run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.flaky_solve, progress=False)
    schema = pq.read_schema(out)
    assert schema.names[:4] == ["key", "index", "status", "error"]
    for c in (*res.INPUT_COLUMNS, "R_o", "Delta", "mesh_order", "mesh_nt", "mesh_aspect", *RESULT_KEYS,
              "t_total_s", "finished_utc"):
        assert c in schema.names, c
    assert schema.field("snaps").type == pa.bool_()
    assert schema.field("n_dofs").type == pa.int64()
    assert schema.field("lower_state_method").type == pa.string()
    assert schema.field("dE_J").type == pa.float64()
    assert pq.read_schema(out).equals(res.result_schema(), check_metadata=False)
    meta = res.read_metadata(out)
    assert meta["package"] == "snapjump" and meta["version"]
    assert meta["command"] == "sweep" and meta["solver"].endswith("flaky_solve")
    assert meta["config"]["grid"]["theta_o"] == [78.0, 82.0, 84.0, 86.0, 88.0]
    assert meta["config"]["mesh"] == {"order": 1, "nt": 2, "aspect": 2.0}
    assert set(meta["config"]["solver"]) == set(SolverSettings.field_names())
    assert {"numpy", "pandas", "pyarrow", "joblib"} <= set(meta["dependencies"])
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(res.__file__).parent, capture_output=True, text=True)
    if head.returncode == 0:  # a checkout: the commit is recorded, in the metadata and in every row
        assert meta["git"]["commit"] == head.stdout.strip()
        assert df_rows_commit(out) == {head.stdout.strip() + ("+dirty" if meta["git"]["dirty"] else "")}
    else:  # an installed copy without git: recorded as unknown, not invented
        assert meta["git"] is None and df_rows_commit(out) == {None}
    assert meta["status_counts"]["invalid_geometry"] == 8 and meta["n_rows"] == 40
    df = res.read_results(out)
    ok = df[df["status"] == "ok"].iloc[0]
    assert ok["R_o"] > 0 and math.isfinite(ok["Delta"]) and ok["error"] == ""
    assert ok["mesh_order"] == 1 and ok["n_nodes"] > 0 and ok["t_total_s"] >= 0
    bad = df[df["status"] == "invalid_geometry"].iloc[0]
    assert bad["dE_J"] != bad["dE_J"] and bad["n_steps"] is pd_NA()


def pd_NA():
    import pandas as pd

    return pd.NA


def test_existing_non_result_output_is_refused(grid_file, tmp_path):
    out = tmp_path / "other.parquet"
    pq.write_table(pa.table({"a": [1, 2]}), out)
    with pytest.raises(SweepInputError, match="not a readable snapjump result file"):
        run_sweep(load_config(grid_file()), output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)


def test_loky_pool_caps_threads_and_warms_up_in_parent(grid_file, tmp_path):
    cfg = load_config(grid_file(grid={"eta_i": [6], "eta_o": [10], "theta_o": [82, 84, 86]}))
    out = tmp_path / "r.parquet"
    fake.WARM_UPS.clear()
    run_sweep(cfg, output=out, n_jobs=2, solve_fn=fake.thread_env, warm_up_fn=fake.warm_up, progress=False)
    df = _check_complete(out, cfg)
    import os

    assert fake.WARM_UPS == [os.getpid()]
    assert (df["lower_state_method"] == "OMP_NUM_THREADS=1,OPENBLAS_NUM_THREADS=1,NUMBA_NUM_THREADS=1").all()
    assert (df["pid"] != os.getpid()).all()


def test_a_worker_that_dies_is_recorded_as_failed(grid_file, tmp_path):
    cfg = load_config(grid_file(grid={"eta_i": [6], "eta_o": [10], "theta_o": [82, 84, 85, 86], "mu_ratio": [5.8]}))
    out = tmp_path / "r.parquet"
    s = run_sweep(cfg, output=out, n_jobs=2, solve_fn=fake.crash_solve, progress=False)
    df = _check_complete(out, cfg)
    dead = df[df["theta_o_deg"] == 85]
    assert (dead["status"] == "failed").all() and dead["error"].str.contains("worker process died").all()
    assert (df.loc[df["theta_o_deg"] != 85, "status"] == "ok").all()
    assert s.counts["failed"] == 1


def test_other_grid_is_refused_unless_appended_then_kept(grid_file, tmp_path):
    out = tmp_path / "r.parquet"
    a = load_config(grid_file("a.yaml", grid={"theta_o": [82]}))
    b = load_config(grid_file("b.yaml", grid={"theta_o": [84]}))
    run_sweep(a, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    with pytest.raises(SweepInputError, match="8 rows that this run would not produce .*the designs.*--append"):
        run_sweep(b, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    assert len(res.read_results(out)) == 8  # refused before anything was written
    run_sweep(b, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False, append=True)
    df = res.read_results(out)
    assert len(df) == 16 and df["key"].is_unique
    assert list(df["theta_o_deg"][:8]) == [84.0] * 8  # this grid first, in grid order
    counts = consolidate(out, {"x": 1})
    assert sum(counts.values()) == 16


def test_warm_up_failure_is_a_sweep_error(grid_file, tmp_path):
    from snapjump_cli.sweep.run import SweepError

    def bad_warm_up():
        raise RuntimeError("numba: cannot compile")

    with pytest.raises(SweepError, match="warm-up .* failed: RuntimeError: numba: cannot compile"):
        run_sweep(load_config(grid_file()), output=tmp_path / "r.parquet", n_jobs=1, solve_fn=fake.fast_solve,
                  warm_up_fn=bad_warm_up, progress=False)


def test_progress_counts_invalid_designs_as_done_from_the_start(grid_file, tmp_path, capsys, monkeypatch):
    """The log-file progress (stderr not a terminal) ends at the full count with the statuses, and
    its rate covers the solved designs only: the 8 invalid ones are done before the first solve."""
    import snapjump_cli.sweep.run as sw

    cfg = load_config(grid_file())
    made = []
    real = sw.make_progress

    def spy(total, initial, stack, **kw):
        made.append((total, initial))
        return real(total, initial, stack, **kw)

    monkeypatch.setattr(sw, "make_progress", spy)
    run_sweep(cfg, output=tmp_path / "r.parquet", n_jobs=1, solve_fn=fake.flaky_solve, progress=True)
    assert made == [(40, 8)]
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("sweep: 40/40 designs (100 %)"), last
    assert "ok=4, no_snap=4, invalid=8, failed=24" in last, last


def test_result_files_are_read_without_arrows_thread_pool(grid_file, tmp_path, monkeypatch):
    """Every parquet read of a resumed sweep (its parts, then the output it merges) passes
    ``use_threads=False``: a pool worker alive at interpreter exit can abort a finished sweep with
    SIGABRT (docs/reliability.md)."""
    import pyarrow.parquet as pq

    cfg = load_config(grid_file(chunk_size=4))
    out = tmp_path / "r.parquet"
    monkeypatch.setattr(fake, "INTERRUPT_AFTER", [5])
    monkeypatch.setattr(fake, "_N_CALLS", [0])
    with pytest.raises(KeyboardInterrupt):
        run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.interrupting_solve, progress=False)
    seen = []
    real = pq.read_table

    def spy(*args, **kw):
        seen.append(kw.get("use_threads", True))
        return real(*args, **kw)

    monkeypatch.setattr(pq, "read_table", spy)
    s = run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    assert s.n_resumed > 0 and len(res.read_results(out)) == 40
    assert len(seen) >= 2 and not any(seen), seen
