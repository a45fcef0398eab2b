"""A full disk (or any I/O error) gives one line naming the path, exit 2, and loses nothing: the
finished rows are kept and the same command resumes once there is space. On a real tiny tmpfs
where the test may mount one (root), and with a simulated ENOSPC everywhere else."""
from __future__ import annotations

import errno
import os

import pytest

import snapjump_fake_solvers as fake
from conftest import CHEAP_SCENE, run_cli
from snapjump_cli import files
from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.config import load_config
from snapjump_cli.sweep.storage import done_keys, parts_dir
from snapjump_cli.sweep.run import run_sweep


def _one_line(err: str) -> str:
    """The one error line of a command's stderr (besides its announcement), never a traceback."""
    lines = [line for line in err.strip().splitlines() if not line.startswith("sweep: ")]
    assert len(lines) == 1 and lines[0].startswith("Error: ") and "Traceback" not in err, err
    return lines[0]


def _sweep(capsys, grid, out, *extra):
    return run_cli(capsys, "sweep", str(grid), "-o", str(out), "-j", "1", "--no-progress", "--chunk-size", "2", *extra,
                   solve_fn=fake.fast_solve)


# ---- a real full file system -------------------------------------------------------------------------
def test_sweep_and_its_merge_on_a_full_disk_keep_every_row_and_resume(tiny_fs, grid_file, capsys):
    out = tiny_fs.root / "r.parquet"
    tiny_fs.fill()  # not even room for the lock
    code, _, err = _sweep(capsys, grid_file(), out)
    line = _one_line(err)
    assert code == 2 and "r.parquet.lock: cannot write the lock file (no space left on the device)" in line
    assert tiny_fs.stray() == []  # no empty lock left to block the next run
    tiny_fs.free()
    tiny_fs.fill(leave=8192)  # room for the lock, not for a part
    code, _, err = _sweep(capsys, grid_file(), out)
    line = _one_line(err)
    assert code == 2 and "no space left on the device" in line and str(tiny_fs.root) in line
    assert "finished designs are kept" in line and "run the same command again" in line
    assert tiny_fs.stray() == []  # no temporary file, no half-written part, no lock
    tiny_fs.free()

    # some rows on disk (parts), then the disk fills up before the merge
    run_sweep(load_config(grid_file()), output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False,
              chunk_size=2, consolidate_output=False)
    kept = done_keys(out)
    assert len(kept) == 8 and not out.exists()
    tiny_fs.fill(leave=8192)
    code, _, err = _sweep(capsys, grid_file(), out)
    line = _one_line(err)
    assert code == 2 and "no space left on the device" in line and "finished designs are kept" in line
    assert done_keys(out) == kept and not out.exists()
    assert [p for p in tiny_fs.stray() if not p.startswith("r.parquet.parts/part-")] == []
    tiny_fs.free()
    code, stdout, err = _sweep(capsys, grid_file(), out)
    assert code == 0 and "8 resumed, 0 solved" in stdout, err
    assert len(res.read_results(out)) == 8 and not parts_dir(out).exists()


def test_rank_optimize_and_curve_on_a_full_disk(tiny_fs, results_file, tmp_path, capsys):
    import yaml

    tiny_fs.fill()
    code, _, err = run_cli(capsys, "rank", str(results_file), "-o", str(tiny_fs.root / "ranked.parquet"))
    assert code == 2 and "no space left on the device" in _one_line(err) and "ranked.parquet" in err
    code, _, err = run_cli(capsys, "curve", *CHEAP_SCENE, "--csv", str(tiny_fs.root / "c.csv"))
    assert code == 2 and "c.csv" in _one_line(err) and "no space left" in err
    spec = tmp_path / "s.yaml"
    spec.write_text(yaml.safe_dump({"bounds": {"eta_i": [5.5, 7.5], "theta_i": 80, "eta_o": [5, 10], "theta_o": 86,
                                               "mu_ratio": 5.8}, "objective": "dE_J", "budget": 4, "confirm": False,
                                    "mesh": {"order": 1, "nt": 2}}))
    tiny_fs.free()
    tiny_fs.fill(leave=16384)  # room for its two locks (the output's and its cache's)
    code, _, err = run_cli(capsys, "optimize", str(spec), "-o", str(tiny_fs.root / "o.parquet"), "-j", "1",
                           "--no-progress", solve_fn=fake.fast_solve, warm_up_fn=None)
    line = _one_line(err)
    assert code == 2 and "no space left" in line and "finished solves are kept" in line
    assert tiny_fs.stray() == []


# ---- a simulated one, on any machine ---------------------------------------------------------------
@pytest.fixture
def enospc(monkeypatch):
    """Every file flushed by the atomic writer fails as on a full disk."""
    def full(path):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(files, "_fsync_file", full)


def test_simulated_full_disk_one_line_exit_2_nothing_half_written(tmp_path, capsys, grid_file, results_file, enospc):
    before = sorted(p.name for p in tmp_path.iterdir())
    cases = [
        (["sweep", str(grid_file("g2.yaml")), "-o", str(tmp_path / "s.parquet"), "-j", "1", "--no-progress"],
         "finished designs are kept"),
        (["rank", str(results_file), "-o", str(tmp_path / "k.csv")], "k.csv"),
        (["curve", *CHEAP_SCENE, "--csv", str(tmp_path / "c.csv")], "c.csv"),
        (["mesh", "--design", "C", "--out", str(tmp_path / "m.vtu")], "m.vtu"),
    ]
    for argv, words in cases:
        code, _, err = run_cli(capsys, *argv, solve_fn=fake.fast_solve)
        line = _one_line(err)
        assert code == 2 and "no space left on the device" in line and words in line, (argv, err)
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted([*before, "g2.yaml", "s.parquet.parts"]), left
    assert list((tmp_path / "s.parquet.parts").iterdir()) == []
