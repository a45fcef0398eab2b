"""Fixtures of the robustness suite: what a demanding user may type must not lose data, damage the
system or run forever. The fake solvers of ``tests/sweep`` stand in for the FE solver where the
solve itself does not matter."""
from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

HERE = Path(__file__).resolve().parent
SWEEP_TESTS = HERE.parent / "sweep"
if str(SWEEP_TESTS) not in sys.path:  # the fake solvers must be importable by reference (loky)
    sys.path.insert(0, str(SWEEP_TESTS))

#: 2 x 1 x 2 x 2 x 1 = 8 valid designs (theta_o > theta_i would be invalid).
GRID = {"eta_i": [6, 7], "theta_i": [80], "eta_o": [5, 10], "theta_o": [82, 86], "mu_ratio": [5.8]}

#: The cheapest real scene (a thin clamped cap: a few hundredths of a second).
CHEAP_SCENE = ["--cap", "--theta", "60", "--eta", "30", "--bc", "clamped"]


def run_cli(capsys, *argv: str, **inject) -> tuple[int, str, str]:
    """``snapjump ARGV`` in this process: (exit code, stdout, stderr)."""
    from snapjump_cli.cli import main

    code = main(list(argv), **inject)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.fixture
def grid_file(tmp_path):
    def make(name: str = "grid.yaml", **top) -> Path:
        doc = {"grid": dict(GRID), "mesh": {"order": 1, "nt": 2}, **top}
        p = tmp_path / name
        p.write_text(yaml.safe_dump(doc))
        return p

    return make


@pytest.fixture
def results_file(tmp_path, grid_file):
    """A finished (fake) sweep's result file."""
    import snapjump_fake_solvers as fake
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.sweep.run import run_sweep

    out = tmp_path / "r.parquet"
    run_sweep(load_config(grid_file()), output=out, n_jobs=1, solve_fn=fake.fast_solve, progress=False)
    return out


def _mount(d: Path, size: str) -> str:
    if os.geteuid() != 0:
        return "mounting a tmpfs needs root"
    if shutil.which("mount") is None or shutil.which("umount") is None:
        return "no mount/umount command"
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(d)], capture_output=True, text=True)
    return "" if r.returncode == 0 else f"cannot mount a tmpfs here ({r.stderr.strip() or r.returncode})"


class TinyFS:
    """A small tmpfs: ``fill()`` takes every free byte (a filler file), ``free()`` gives them back."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.filler = root / "filler"

    def fill(self, leave: int = 0) -> None:
        """Take every free byte, then give back ``leave`` bytes (room for a lock file, not a table)."""
        with open(self.filler, "ab", buffering=0) as fh:
            for n in (65536, 4096, 512, 1):  # down to the last byte
                while True:
                    try:
                        if fh.write(b"\0" * n) == 0:
                            break
                    except OSError as e:
                        assert e.errno == errno.ENOSPC, e
                        break
            if leave:
                fh.truncate(max(0, os.fstat(fh.fileno()).st_size - leave))

    def free(self) -> None:
        self.filler.unlink(missing_ok=True)

    def stray(self) -> list[str]:
        """Files other than the filler (temporary files must never be left behind)."""
        return sorted(str(p.relative_to(self.root)) for p in self.root.rglob("*") if p.is_file() and p != self.filler)


@pytest.fixture
def tiny_fs(tmp_path):
    """A 4 MB tmpfs mounted for the test (root only; skipped with the reason elsewhere), unmounted after."""
    d = tmp_path / "tiny"
    d.mkdir()
    why = _mount(d, "4m")
    if why:
        pytest.skip(why)
    try:
        yield TinyFS(d)
    finally:
        r = subprocess.run(["umount", str(d)], capture_output=True)
        if r.returncode != 0:
            subprocess.run(["umount", "-l", str(d)], capture_output=True)
