"""Class 6 of issue 38 and item 7 of issue 37: an interrupted command leaves nothing but what it
had finished, and Ctrl-C at any moment gives exit 130 and one line. The one write path
(:class:`snapjump_cli.files.AtomicFiles`) turns SIGTERM into an interruption while temporary files
are pending, so they are removed; :func:`snapjump_cli.cli.main` turns Ctrl-C into ``interrupted``."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

from conftest import run_cli

WRITER = textwrap.dedent("""
    import sys, time
    from snapjump_cli.files import AtomicFiles

    def slow(tmp):
        tmp.write_bytes(b"x" * 100000)
        print("ready", flush=True)
        time.sleep(60)

    with AtomicFiles() as out:
        out.add(sys.argv[1] + "/a.vtu", lambda tmp: tmp.write_bytes(b"done"))
        out.add(sys.argv[1] + "/b.vtu", slow)
""")


def test_sigterm_while_outputs_are_staged_leaves_no_temporary_file(tmp_path):
    target = tmp_path / "out"
    target.mkdir()
    p = subprocess.Popen([sys.executable, "-c", WRITER, str(target)], stdout=subprocess.PIPE,
                         stderr=subprocess.DEVNULL, text=True)
    try:
        assert p.stdout.readline().strip() == "ready"
        assert len(os.listdir(target)) == 2  # the two staged temporary files
        p.send_signal(signal.SIGTERM)
        p.wait(30)
    finally:
        p.kill()
    assert os.listdir(target) == []  # neither the outputs (all or none) nor any temporary file


def test_ctrl_c_in_a_command_is_one_line_and_exit_130(results_file, tmp_path, capsys, monkeypatch):
    import snapjump_cli.jump.rank as rank_mod

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(rank_mod, "rank_results", interrupted)
    code, out, err = run_cli(capsys, "rank", str(results_file), "-o", str(tmp_path / "o.parquet"))
    assert code == 130 and err.strip() == "interrupted"
    assert sorted(os.listdir(tmp_path)) == sorted([results_file.name, "grid.yaml"])  # no output, no lock


def test_ctrl_c_while_the_program_starts_is_one_line_and_exit_130(tmp_path):
    exe = os.path.join(os.path.dirname(sys.executable), "snapjump")
    # stop it inside its imports: the handler of the start-up is in place once snapjump_cli.cli is imported
    code = textwrap.dedent(f"""
        import os, signal, sys
        sys.argv[0] = {exe!r}
        import snapjump_cli.cli
        os.kill(os.getpid(), signal.SIGINT)
        import time; time.sleep(10)
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 130 and r.stderr == "interrupted\n"


def test_sweep_workers_ignore_ctrl_c_their_parent_stops_them():
    from snapjump_cli.sweep.execution import die_with_parent

    code = textwrap.dedent("""
        import os, signal, time
        from snapjump_cli.sweep.execution import die_with_parent
        die_with_parent(os.getppid())
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.2)
        print("alive")
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.stdout.strip() == "alive" and "Traceback" not in r.stderr
    assert die_with_parent  # (imported: the initializer every loky worker runs)
