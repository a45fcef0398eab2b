"""Classes 2 and 5 of issue 38: every command that writes a result holds its output's lock, every
write refuses a file another running process holds, and a lock whose pid was reused by another
process is taken over (the lock records the process's start time): :class:`snapjump_cli.files.OutputLock`."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import pytest

from conftest import run_cli
from snapjump_cli.files import OutputError, OutputLock, lock_path, process_start, write_atomic


@pytest.fixture
def other_process():
    """A live process that is not this one (its pid, for a lock someone else holds)."""
    p = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        yield p.pid
    finally:
        p.kill()
        p.wait()


def _lock(path, pid, **extra):
    lock_path(path).write_text(json.dumps({"pid": pid, "host": socket.gethostname(), "started_utc": "2026-01-01",
                                           "command": "rank", "proc_start": process_start(pid), **extra}))


def test_a_second_rank_into_the_same_output_is_refused(results_file, tmp_path, capsys, other_process):
    out = tmp_path / "ranked.parquet"
    _lock(out, other_process)
    code, _, err = run_cli(capsys, "rank", str(results_file), "-o", str(out))
    assert code == 2 and "another rank is writing into this output" in err and f"pid {other_process}" in err
    assert not out.exists() and "wrote" not in err


def test_rank_holds_its_output_lock_while_it_runs(results_file, tmp_path, capsys, monkeypatch):
    import snapjump_cli.jump.rank as rank_mod

    out = tmp_path / "ranked.parquet"
    seen = []
    real = rank_mod.rank_results

    def spy(*a, **k):
        seen.append(json.loads(lock_path(out).read_text()))
        return real(*a, **k)

    monkeypatch.setattr(rank_mod, "rank_results", spy)
    code, _, err = run_cli(capsys, "rank", str(results_file), "-o", str(out))
    assert code == 0, err
    assert seen and seen[0]["pid"] == os.getpid() and seen[0]["command"] == "rank"
    assert not lock_path(out).exists()  # released


def test_every_write_refuses_a_file_another_process_is_writing(tmp_path, other_process):
    out = tmp_path / "r.parquet"
    _lock(out, other_process, command="sweep")
    with pytest.raises(OutputError, match=rf"another sweep \(pid {other_process} .* is writing this file"):
        write_atomic(out, lambda tmp: tmp.write_text("x"))
    assert not out.exists() and sorted(os.listdir(tmp_path)) == ["r.parquet.lock"]
    with OutputLock(tmp_path / "mine.parquet", "rank"):  # this process's own lock does not stop it
        write_atomic(tmp_path / "mine.parquet", lambda tmp: tmp.write_text("x"))


def test_a_lock_whose_pid_now_belongs_to_another_process_is_taken_over(tmp_path, other_process, caplog):
    out = tmp_path / "r.parquet"
    start = process_start(other_process)
    assert start is not None
    _lock(out, other_process, proc_start=start + 12345)  # same pid, started at another time: not the holder
    with OutputLock(out, "sweep"):
        assert json.loads(lock_path(out).read_text())["pid"] == os.getpid()
    assert "its pid now belongs to another process" in caplog.text
    _lock(out, other_process)  # the same process: respected
    with pytest.raises(OutputError, match="another rank is writing into this output"):
        OutputLock(out, "sweep").acquire()
