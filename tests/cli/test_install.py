"""A real (non-editable) install works: build the wheel, install it into a fresh virtual
environment and run ``snapjump mesh --design C`` from a folder outside the repository (the
geometry, gmsh and the kernels' element tables and cavity from the installed copy; the solve
itself is the same code, which every other test runs).

The fresh environment gets the already installed dependencies (numpy, numba, gmsh, ...) through a
``.pth`` file pointing at this environment's site-packages, so nothing is downloaded; snapjump
itself comes only from the wheel (checked: the package imported is the installed copy, and the
named designs are package data).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


#: The environment of every step: no PYTHONPATH or active venv leaking the checkout in.
ENV = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}


def _run(cmd: list[str], cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout, env=ENV)


@pytest.mark.slow
def test_wheel_installs_and_runs_outside_the_repository(tmp_path):
    wheels = tmp_path / "wheels"
    r = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels),
              str(REPO)], cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    (whl,) = wheels.glob("snapjump-*.whl")

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    site = Path(_run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                     cwd=tmp_path).stdout.strip())
    # the dependencies of this environment, appended after the fresh site-packages
    (site / "deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    r = _run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "-q", str(whl)], cwd=tmp_path)
    assert r.returncode == 0, r.stderr

    work = tmp_path / "elsewhere"
    work.mkdir()
    r = _run([str(py), "-c", "import snapjump_cli, snapjump_kernels; print(snapjump_cli.__file__); "
              "print(snapjump_kernels.__file__)"], cwd=work)
    assert r.returncode == 0, r.stderr
    assert all(line.startswith(str(site)) for line in r.stdout.split()), r.stdout  # the wheel, not the checkout

    r = _run([str(env_dir / "bin" / "snapjump"), "mesh", "--design", "C", "--format", "json"], cwd=work)
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)  # design C (package data): its cavity to the exact geometry's
    assert m["name"] == "C" and m["V_cavity_m3"] == pytest.approx(m["V_cavity_exact_m3"], rel=1e-5)
    assert not any(work.iterdir())  # nothing written where it was run
