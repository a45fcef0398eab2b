"""Kill a real ``python -m snapjump_cli sweep`` process mid-run, rerun it, and check that the
result has every design exactly once and that finished designs were not solved again.

The subprocess runs the real CLI through ``fake_sweep_main.py``, which injects the test-only fake
solver ``snapjump_fake_solvers.slow_solve`` (it sleeps ``SNAPJUMP_FAKE_DELAY`` seconds).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.config import load_config
from snapjump_cli.sweep.run import design_key, done_keys, parts_dir

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]


def _env(log: Path, delay: float, block_after: int = 0) -> dict[str, str]:
    env = dict(os.environ)
    env.update(
        SNAPJUMP_FAKE_BLOCK_AFTER=str(block_after),
        SNAPJUMP_FAKE_DELAY=str(delay),
        SNAPJUMP_FAKE_LOG=str(log),
        PYTHONPATH=os.pathsep.join([str(HERE), str(REPO), env.get("PYTHONPATH", "")]),
    )
    return env


def _start(grid: Path, out: Path, env: dict[str, str], jobs: int) -> subprocess.Popen:
    cmd = [sys.executable, str(HERE / "fake_sweep_main.py"), "sweep", str(grid), "-o", str(out), "-j", str(jobs), "--no-progress"]
    return subprocess.Popen(cmd, env=env, cwd=grid.parent, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)


def _wait_for_rows(out: Path, n: int, proc: subprocess.Popen, timeout: float = 60.0) -> int:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        assert proc.poll() is None, proc.communicate()
        try:
            done = len(done_keys(out))
        except Exception:  # noqa: BLE001 - a part file may appear between listing and reading
            done = 0
        if done >= n:
            return done
        time.sleep(0.05)
    raise AssertionError(f"no {n} rows after {timeout} s")


def _kill_group(proc: subprocess.Popen, sig: int) -> None:
    try:
        os.killpg(proc.pid, sig)  # the sweep process and its loky workers (same new session)
    except ProcessLookupError:
        pass


def _calls(log: Path) -> list[tuple[float, ...]]:
    return [tuple(float(x) for x in line.split()[:5]) for line in log.read_text().splitlines()] if log.exists() else []


def _recorded(out: Path) -> set[tuple[float, ...]]:
    rows = set()
    for f in sorted(parts_dir(out).glob("part-*.parquet")):
        t = pq.read_table(f, columns=["eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio", "status"]).to_pylist()
        rows |= {(r["eta_i"], r["theta_i_deg"], r["eta_o"], r["theta_o_deg"], r["mu_ratio"]) for r in t
                 if r["status"] != "invalid_geometry"}
    return rows


def test_kill_then_resume_has_no_missing_and_no_duplicate_rows(grid_file, tmp_path):
    grid = grid_file(chunk_size=2)  # 40 designs, 32 to solve
    cfg = load_config(grid)
    out = tmp_path / "res.parquet"
    log = tmp_path / "calls.log"

    # 1. parallel run (loky workers): SIGKILL the whole process group (no cleanup at all) once
    #    some chunks are on disk (each worker blocks after 6 designs: the run cannot finish first,
    #    however loaded the machine is)
    p1 = _start(grid, out, _env(log, 0.05, block_after=6), jobs=2)
    try:
        _wait_for_rows(out, 8 + 4, p1)  # the 8 invalid rows + at least 4 solved ones
    finally:
        _kill_group(p1, signal.SIGKILL)
        p1.wait(timeout=30)
    assert not out.exists()
    done1 = _recorded(out)
    assert 4 <= len(done1) <= 12
    n_calls1 = len(_calls(log))

    # 2. SIGTERM the sweep process only: it stops cleanly, keeps its finished rows, exit 130
    #    (in-process run, -j 1, to keep the test fast; it blocks after 4 designs)
    p2 = _start(grid, out, _env(log, 0.05, block_after=4), jobs=1)
    try:
        _wait_for_rows(out, 8 + len(done1) + 4, p2)  # all 4 on disk; the 5th call blocks
        os.kill(p2.pid, signal.SIGTERM)
        _, err2 = p2.communicate(timeout=30)
    finally:
        _kill_group(p2, signal.SIGKILL)
    assert p2.returncode == 130, err2.decode()
    assert b"run the same command again to resume" in err2
    calls2 = _calls(log)[n_calls1:]
    assert not set(calls2) & done1, "designs recorded by run 1 were solved again"
    done2 = _recorded(out)
    assert done1 < done2 and len(done2) == len(done1) + 4
    n_calls2 = n_calls1 + len(calls2)

    # 3. run to the end
    p3 = _start(grid, out, _env(log, 0.0), jobs=1)
    o3, e3 = p3.communicate(timeout=60)
    assert p3.returncode == 0, e3.decode()
    calls3 = _calls(log)[n_calls2:]
    assert not set(calls3) & done2, "designs recorded by runs 1-2 were solved again"
    assert len(calls3) == 32 - len(done2)
    assert b"40 designs" in o3

    df = res.read_results(out)
    keys = {design_key(p, cfg.mesh, cfg.solver) for p in cfg.designs()}
    assert len(df) == 40 and df["key"].is_unique and set(df["key"]) == keys
    assert not parts_dir(out).exists()
    assert (df["status"] != "failed").all()
