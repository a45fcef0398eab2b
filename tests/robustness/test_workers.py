"""After kill -9 of a sweep, its loky workers end within about a second (they watch their parent)
and joblib's shared-memory entries of that run go with them."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import SWEEP_TESTS

REPO = SWEEP_TESTS.parents[1]


def _children(pid: int) -> list[int]:
    """The pids of the loky workers of ``pid`` (from /proc)."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            cmd = (d / "cmdline").read_bytes()
        except OSError:
            continue
        if int(fields[1]) == pid and b"popen_loky_posix" in cmd:
            out.append(int(d.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _shm(pid: int) -> list[str]:
    shm = Path("/dev/shm")
    return sorted(p.name for p in shm.iterdir() if f"_{pid}_" in p.name or f"-{pid}-" in p.name) if shm.is_dir() else []


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc to find the workers")
def test_workers_die_with_a_killed_sweep(tmp_path):
    grid = tmp_path / "grid.yaml"
    grid.write_text("grid: {eta_i: [6, 7], theta_i: [80], eta_o: [5, 10], theta_o: [82, 84, 86, 88], "
                    "mu_ratio: [1, 5.8]}\nmesh: {order: 1, nt: 2}\n")
    env = dict(os.environ, SNAPJUMP_FAKE_BLOCK_AFTER="2", SNAPJUMP_FAKE_DELAY="0.05",
               PYTHONPATH=os.pathsep.join([str(SWEEP_TESTS), str(REPO), os.environ.get("PYTHONPATH", "")]))
    cmd = [sys.executable, str(SWEEP_TESTS / "fake_sweep_main.py"), "sweep", str(grid), "-o",
           str(tmp_path / "r.parquet"), "-j", "2", "--no-progress"]
    proc = subprocess.Popen(cmd, env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    workers: list[int] = []
    try:
        t0 = time.monotonic()
        while len(workers) < 2 and time.monotonic() - t0 < 120:  # the workers block after 2 designs each
            assert proc.poll() is None
            workers = _children(proc.pid)
            time.sleep(0.1)
        assert len(workers) == 2
        time.sleep(0.5)  # their initializer (the parent watch) has run once they take work
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        t0 = time.monotonic()
        while any(_alive(w) for w in workers) and time.monotonic() - t0 < 30:
            time.sleep(0.1)
        assert not any(_alive(w) for w in workers), "the workers outlived their sweep"
        t0 = time.monotonic()
        while _shm(proc.pid) and time.monotonic() - t0 < 30:  # joblib's resource tracker cleans up
            time.sleep(0.2)
        assert _shm(proc.pid) == []
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=30)
        for w in workers:  # only the workers of this test, by pid
            if _alive(w):
                os.kill(w, signal.SIGKILL)
