"""Class 1 of issue 38: the tool removes only what it wrote and never follows a link inside its own
working folders (``OUT.parts/``); the one mechanism is :func:`snapjump_cli.files.own_files` /
:func:`~snapjump_cli.files.remove_own` / :func:`~snapjump_cli.files.own_folder`."""
from __future__ import annotations

import os

import snapjump_fake_solvers as fake
from conftest import run_cli
from snapjump_cli.sweep import results as res


def _victim(tmp_path):
    """A folder of someone else's files, with names a sweep would use."""
    v = tmp_path / "victim"
    v.mkdir()
    for name in ("notes.txt", "part-000000.parquet", "0123456789abcdef01234567"):
        (v / name).write_text("precious\n")
    return v


def _intact(v) -> bool:
    return sorted(os.listdir(v)) == sorted(["notes.txt", "part-000000.parquet", "0123456789abcdef01234567"]) and all(
        (v / n).read_text() == "precious\n" for n in os.listdir(v))


def test_a_link_named_running_in_the_parts_folder_is_never_followed(grid_file, tmp_path, capsys):
    out = tmp_path / "r.parquet"
    victim = _victim(tmp_path)
    parts = tmp_path / "r.parquet.parts"
    parts.mkdir()
    (parts / "running").symlink_to(victim)
    code, _, err = run_cli(capsys, "sweep", str(grid_file()), "-o", str(out), "-j", "1", solve_fn=fake.fast_solve)
    assert _intact(victim)
    assert code == 2 and "running: is a symbolic link" in err
    assert (parts / "running").is_symlink()  # the link is not ours either: left in place


def test_a_parts_folder_that_is_a_link_is_refused_and_its_target_untouched(grid_file, tmp_path, capsys):
    out = tmp_path / "r.parquet"
    victim = _victim(tmp_path)
    (tmp_path / "r.parquet.parts").symlink_to(victim)
    code, _, err = run_cli(capsys, "sweep", str(grid_file()), "-o", str(out), "-j", "1", solve_fn=fake.fast_solve)
    assert _intact(victim)
    assert code == 2 and "is a symbolic link" in err and "r.parquet.parts" in err


def test_links_and_foreign_entries_among_the_parts_are_ignored_and_kept(grid_file, tmp_path, capsys, caplog):
    out = tmp_path / "r.parquet"
    victim = _victim(tmp_path)
    parts = tmp_path / "r.parquet.parts"
    parts.mkdir()
    (parts / "part-000007.parquet").symlink_to(victim / "part-000000.parquet")
    (parts / "running").mkdir()
    (parts / "running" / "0123456789abcdef01234567").symlink_to(victim / "0123456789abcdef01234567")
    code, _, err = run_cli(capsys, "sweep", str(grid_file()), "-o", str(out), "-j", "1", solve_fn=fake.fast_solve)
    assert code == 0, err
    assert _intact(victim)
    assert len(res.read_results(out)) == 8  # the link's "rows" were never read
    assert (parts / "part-000007.parquet").is_symlink()  # left where it was, with a warning
    assert "snapjump did not write; ignored and left in place" in caplog.text


def test_the_removal_primitives_touch_regular_files_only(tmp_path):
    from snapjump_cli.files import own_files, remove_own, remove_own_folder

    victim = _victim(tmp_path)
    d = tmp_path / "work"
    d.mkdir()
    (d / "part-000001.parquet").write_text("mine")
    (d / "part-000002.parquet").symlink_to(victim / "notes.txt")
    (d / "part-000003.parquet").mkdir()
    assert [p.name for p in own_files(d, r"part-\d+\.parquet")] == ["part-000001.parquet"]
    assert not remove_own(d / "part-000002.parquet") and not remove_own(d / "part-000003.parquet")
    assert remove_own(d / "part-000001.parquet")
    assert not remove_own_folder(d, r"part-\d+\.parquet")  # not empty: the link and the folder stay
    link = tmp_path / "link"
    link.symlink_to(victim)
    assert not remove_own_folder(link, r".*")
    assert _intact(victim)
