"""Never replace what is not an ordinary file (links are followed, FIFOs, sockets, devices and
system folders refused), every output atomic with the umask's mode, all outputs of a command or
none."""
from __future__ import annotations

import os
import re
import socket
import stat
from pathlib import Path

import pytest

import snapjump_fake_solvers as fake
from conftest import CHEAP_SCENE, GRID, run_cli
from snapjump_cli import files
from snapjump_cli.sweep import results as res
from snapjump_cli.files import AtomicFiles, OutputError, output_target, write_atomic


def _write(text: str):
    return lambda tmp: Path(tmp).write_text(text)


# ---- the policy, on the helper ---------------------------------------------------------------------
def test_a_regular_file_is_replaced_atomically_with_the_umask_mode(tmp_path):
    p = tmp_path / "a.txt"
    p.write_text("old")
    os.chmod(p, 0o600)
    old = os.umask(0o027)
    try:
        write_atomic(p, _write("new"))
    finally:
        os.umask(old)
    assert p.read_text() == "new" and stat.S_IMODE(p.stat().st_mode) == 0o640
    assert os.listdir(tmp_path) == ["a.txt"]


def test_a_link_is_followed_and_its_target_replaced_in_its_own_folder(tmp_path):
    shared = tmp_path / "shared"
    shared.mkdir()
    target = shared / "t.csv"
    target.write_text("old")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    write_atomic(link, _write("new"))
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text() == "new" and not target.is_symlink()
    assert sorted(os.listdir(shared)) == ["t.csv"] and sorted(os.listdir(tmp_path)) == ["link.csv", "shared"]
    dangling = tmp_path / "d.csv"
    dangling.symlink_to(shared / "new.csv")  # a dangling link creates its target
    write_atomic(dangling, _write("x"))
    assert dangling.is_symlink() and (shared / "new.csv").read_text() == "x"


def test_fifos_sockets_directories_and_link_loops_are_refused(tmp_path):
    fifo = tmp_path / "f.csv"
    os.mkfifo(fifo)
    sock_path = tmp_path / "s.csv"
    sock = socket.socket(socket.AF_UNIX)
    try:
        sock.bind(str(sock_path))
        loop = tmp_path / "l1"
        loop.symlink_to(tmp_path / "l2")
        (tmp_path / "l2").symlink_to(loop)
        link_to_fifo = tmp_path / "lf.csv"
        link_to_fifo.symlink_to(fifo)
        for p, words in ((fifo, "FIFO"), (sock_path, "socket"), (tmp_path, "directory"), (loop, "link loop"),
                         (link_to_fifo, f"a link to {fifo}): is a FIFO")):
            with pytest.raises(OutputError, match=re.escape(words)):
                write_atomic(p, _write("x"))
        assert stat.S_ISFIFO(fifo.stat().st_mode) and stat.S_ISSOCK(sock_path.stat().st_mode)
    finally:
        sock.close()
    assert sorted(os.listdir(tmp_path)) == ["f.csv", "l1", "l2", "lf.csv", "s.csv"]


def test_devices_and_system_folders_are_refused_without_writing(tmp_path):
    # a device, presented by a fake stat (no device node is needed or touched)
    fake_dev = os.stat_result((stat.S_IFCHR | 0o666, 0, 0, 1, 0, 0, 0, 0, 0, 0))
    p = tmp_path / "out.parquet"
    with pytest.raises(OutputError, match="character device"):
        write_atomic(p, _write("x"), stat_fn=lambda _: fake_dev)
    assert not p.exists() and os.listdir(tmp_path) == []
    # the system folders are refused by name, before anything is opened (no write is attempted)
    for path in ("/dev/full", "/dev/null", "/dev/shm/x.parquet", "/proc/self/x", "/sys/x"):
        with pytest.raises(OutputError, match="system folder"):
            output_target(path)
    link = tmp_path / "full.parquet"
    link.symlink_to("/dev/full")
    with pytest.raises(OutputError, match=r"a link to /dev/full\): refusing to write under /dev"):
        output_target(link)


@pytest.mark.skipif(os.geteuid() != 0, reason="creating a device node needs root")
def test_a_real_device_node_is_refused_by_rank(tmp_path, capsys, results_file):
    dev = tmp_path / "full.parquet"  # a node of /dev/full's numbers, made here: refused before it is opened
    os.mknod(dev, stat.S_IFCHR | 0o600, os.makedev(1, 7))
    code, _, err = run_cli(capsys, "rank", str(results_file), "-o", str(dev))
    assert code == 2 and "character device" in err and len(err.strip().splitlines()) == 1
    assert stat.S_ISCHR(dev.lstat().st_mode)


def test_rank_into_a_system_folder_is_refused(tmp_path, capsys, results_file, monkeypatch):
    fake_dev = tmp_path / "dev"  # the /dev rule, on a folder of our own (the real /dev is never written)
    fake_dev.mkdir()
    monkeypatch.setattr(files, "SYSTEM_FOLDERS", (str(fake_dev),))
    code, _, err = run_cli(capsys, "rank", str(results_file), "-o", str(fake_dev / "full.parquet"))
    assert code == 2 and "system folder" in err and os.listdir(fake_dev) == []


# ---- the commands ------------------------------------------------------------------------------------
def test_rank_mesh_and_curve_refuse_a_fifo_output(tmp_path, capsys, results_file):
    fifo = tmp_path / "fifo.parquet"
    os.mkfifo(fifo)
    for argv in (["rank", str(results_file), "-o", str(fifo)],
                 ["mesh", "--design", "C", "--out", str(tmp_path / "f.vtu")],
                 ["curve", *CHEAP_SCENE, "--csv", str(tmp_path / "fifo.csv")]):
        if argv[0] != "rank":
            os.mkfifo(argv[-1])
        for extra in ([], ["--overwrite"]):
            code, _, err = run_cli(capsys, *argv, *extra)
            assert code == 2 and "FIFO" in err and len(err.strip().splitlines()) == 1, (argv, err)
            assert stat.S_ISFIFO(Path(argv[-1]).stat().st_mode)


def test_a_sweep_into_a_link_keeps_the_link_and_writes_the_shared_target(tmp_path, capsys, grid_file):
    shared = tmp_path / "shared"
    shared.mkdir()
    target = shared / "grid.parquet"
    link = tmp_path / "link.parquet"
    link.symlink_to(target)
    g = grid_file()
    code, _, err = run_cli(capsys, "sweep", str(g), "-o", str(link), "-j", "1", "--no-progress",
                           solve_fn=fake.fast_solve)
    assert code == 0, err
    assert link.is_symlink() and target.is_file() and len(res.read_results(target)) == 8
    # a resumed run through the link finds the rows of the target and keeps both in step
    g2 = grid_file("g2.yaml", grid={**GRID, "eta_i": [6, 7, 8]})
    code, out, err = run_cli(capsys, "sweep", str(g2), "-o", str(link), "-j", "1", "--no-progress",
                             solve_fn=fake.fast_solve)
    assert code == 0 and "8 resumed" in out, err
    assert link.is_symlink() and len(res.read_results(link)) == 12 == len(res.read_results(target))
    assert sorted(os.listdir(shared)) == ["grid.parquet"]  # no lock or parts left, beside the target either


def test_curve_writes_both_outputs_or_neither(tmp_path, capsys, monkeypatch):
    import snapjump_cli.viz.figures as plots

    csv, png = tmp_path / "c.csv", tmp_path / "c.png"

    def broken_plot(*a, **k):
        raise RuntimeError("the plot cannot be drawn")

    monkeypatch.setattr(plots, "plot_pv_curve", broken_plot)
    with pytest.raises(RuntimeError, match="cannot be drawn"):
        run_cli(capsys, "curve", *CHEAP_SCENE, "--csv", str(csv), "--plot", str(png))
    assert os.listdir(tmp_path) == []  # no CSV without its plot, no temporary file
    monkeypatch.undo()
    old = os.umask(0o027)
    try:
        code, _, err = run_cli(capsys, "curve", *CHEAP_SCENE, "--csv", str(csv), "--plot", str(png))
    finally:
        os.umask(old)
    assert code == 0, err
    assert sorted(os.listdir(tmp_path)) == ["c.csv", "c.png"]
    assert {stat.S_IMODE(p.stat().st_mode) for p in (csv, png)} == {0o640}


def test_atomic_files_replace_all_or_none(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.write_text("old a")
    with pytest.raises(ValueError):
        with AtomicFiles() as out:
            out.add(a, _write("new a"))
            out.add(b, lambda tmp: (_ for _ in ()).throw(ValueError("b fails")))
    assert a.read_text() == "old a" and not b.exists() and os.listdir(tmp_path) == ["a"]
    with AtomicFiles() as out:
        out.add(a, _write("new a"))
        out.add(b, _write("new b"))
    assert a.read_text() == "new a" and b.read_text() == "new b"
