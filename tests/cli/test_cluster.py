"""docs/cluster.md's recipes, run on this machine: a sweep on a dask scheduler and workers started
as separate processes talking over TCP (recipe 1), and the page's own code block run with
dask-jobqueue's ``LocalCluster`` (recipe 2: the machinery of ``SLURMCluster``, the job script run
with bash); the SLURM and PBS job scripts it would submit are checked. The fake solver stands in
for the FE solve (tests/sweep/snapjump_fake_solvers.py)."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[2]
SWEEP_TESTS = ROOT / "tests" / "sweep"
if str(SWEEP_TESTS) not in sys.path:
    sys.path.insert(0, str(SWEEP_TESTS))

import snapjump_fake_solvers as fake  # noqa: E402

from snapjump_cli.cli import main as cli_main  # noqa: E402
from snapjump_cli.sweep import results as res  # noqa: E402

GRID = {"eta_i": [6, 7], "theta_i": [80], "eta_o": [10], "theta_o": [78, 86], "mu_ratio": [1, 5.8]}


def _grid(tmp_path: Path) -> Path:
    p = tmp_path / "grid.yaml"
    p.write_text(yaml.safe_dump({"grid": GRID, "mesh": {"order": 1, "nt": 2}}))
    return p


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SWEEP_TESTS), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def _recipe() -> str:
    """The code block of docs/cluster.md that the page says is tested."""
    text = (ROOT / "docs" / "cluster.md").read_text()
    m = re.search(r"<!-- the block below is executed by tests/cli/test_cluster.py -->\s*```python\n(.*?)```", text,
                  re.S)
    assert m, "docs/cluster.md lost its tested recipe"
    return m.group(1)


def test_recipe_1_scheduler_and_workers_over_tcp(tmp_path, capsys):
    """`dask scheduler` and `dask worker` as their own processes (as batch jobs would start them),
    `snapjump sweep --scheduler tcp://...`: every design solved on the worker, then resumed."""
    sched_file = tmp_path / "scheduler.json"
    py = sys.executable
    procs = [subprocess.Popen([py, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--scheduler-file", str(sched_file)], env=_env(),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 120
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        # two single-threaded workers: with one thread in all, joblib's dask backend runs the designs
        # in the sweep's own process (docs/cluster.md, "One worker is not enough")
        procs.append(subprocess.Popen([py, "-m", "distributed.cli.dask_worker", address, "--nworkers", "2",
                                       "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1"],
                                      env={**_env(), "OMP_NUM_THREADS": "1"},
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from dask.distributed import Client

        with Client(address, timeout=60) as c:
            c.wait_for_workers(2, timeout=120)
            worker_pids = set(c.run(os.getpid).values())
        out = tmp_path / "r.parquet"
        grid = _grid(tmp_path)
        code = cli_main(["sweep", str(grid), "-o", str(out), "--scheduler", address, "--no-progress"],
                        solve_fn=fake.fast_solve)
        assert code == 0, capsys.readouterr().err
        df = res.read_results(out)
        assert len(df) == 8 and df["status"].value_counts().to_dict() == {"ok": 4, "invalid_geometry": 4}
        solved = df[df["status"] != "invalid_geometry"]
        assert set(solved["pid"].astype(int)) <= worker_pids  # solved by the workers, not here
        assert res.read_metadata(out)["scheduler"] == address
        capsys.readouterr()
        assert cli_main(["sweep", str(grid), "-o", str(out), "--scheduler", address, "--no-progress"],
                        solve_fn=fake.broken_if_called) == 0
        assert "0 solved" in capsys.readouterr().out
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


def _bash_queue(tmp_path: Path):
    """A dask-jobqueue cluster class whose "batch system" is bash on this machine: the job script
    (shebang, prologue, worker command; what sbatch would get) is submitted by a script that starts
    it in its own session and prints its id, and cancelled by killing that session. The rest is
    dask-jobqueue's own machinery (``JobQueueCluster``, ``Job``), as with ``SLURMCluster``.
    (dask-jobqueue's ``LocalCluster`` runs the script's words as one command: no prologue.)"""
    from dask_jobqueue.core import Job, JobQueueCluster

    submit = tmp_path / "submit.sh"
    # a copy first, as sbatch keeps the script: dask-jobqueue deletes its file once submitted
    submit.write_text('#!/bin/bash\njob="%s/job-$$.sh"\ncp "$1" "$job"\nsetsid bash "$job" > "$job.log" 2>&1 < /dev/null &\n'
                      'echo "Submitted job $!"\n' % tmp_path)
    cancel = tmp_path / "cancel.sh"
    cancel.write_text('#!/bin/bash\nfor j in "$@"; do kill -TERM -- "-$j" 2>/dev/null; done\nexit 0\n')

    class BashJob(Job):
        config_name = "local"
        submit_command = f"bash {submit}"
        cancel_command = f"bash {cancel}"

        def __init__(self, *args, walltime=None, **kwargs):  # (sbatch's -t: bash has no wall time)
            super().__init__(*args, shebang="#!/usr/bin/env bash", **kwargs)
            self.job_header = "# (a batch system's #SBATCH lines go here)"

    class BashQueueCluster(JobQueueCluster):
        job_cls = BashJob

    return BashQueueCluster


def test_recipe_2_dask_jobqueue(tmp_path, monkeypatch):
    """docs/cluster.md's code, on a queue that runs the job scripts with bash (workers over TCP)."""
    pytest.importorskip("dask_jobqueue")
    ns: dict = {"__name__": "recipe"}
    exec(compile(_recipe(), "docs/cluster.md", "exec"), ns)
    real = ns["run_sweep"]
    ns["run_sweep"] = lambda cfg, **kw: real(cfg, solve_fn=fake.fast_solve, progress=False, **kw)
    cluster = ns["make_cluster"](_bash_queue(tmp_path), cores=2, memory_per_worker_gb=1, walltime="00:10:00",
                                 scheduler_options={"host": "127.0.0.1", "dashboard_address": None},
                                 prologue=[f"export PYTHONPATH={_env()['PYTHONPATH']}"])
    script = cluster.job_script()
    assert "export OMP_NUM_THREADS=1" in script and "--nthreads 1" in script and sys.executable in script
    out = tmp_path / "r.parquet"
    s = ns["sweep_on"](cluster, str(_grid(tmp_path)), str(out), jobs=1, wait_s=300)
    assert (s.n_designs, s.n_solved) == (8, 4)
    df = res.read_results(out)
    pids = set(df.loc[df["status"] == "ok", "pid"].astype(int))
    assert len(df) == 8 and os.getpid() not in pids  # solved by the job's workers


@pytest.mark.parametrize("kind", ["SLURMCluster", "PBSCluster"])
def test_recipe_2_job_scripts(kind):
    """The job script the recipe would submit: one job of N single-threaded workers of this venv."""
    jq = pytest.importorskip("dask_jobqueue")
    ns: dict = {"__name__": "recipe"}
    exec(compile(_recipe(), "docs/cluster.md", "exec"), ns)
    cluster = ns["make_cluster"](getattr(jq, kind), cores=8, queue="compute", account="proj",
                                 scheduler_options={"host": "127.0.0.1", "dashboard_address": None})
    try:
        script = cluster.job_script()
    finally:
        cluster.close()
    assert sys.executable in script and "--nthreads 1" in script and "--nworkers 8" in script
    assert "export OMP_NUM_THREADS=1" in script and "NUMBA_NUM_THREADS=1" in script
    if kind == "SLURMCluster":
        assert "#SBATCH -p compute" in script and "#SBATCH -A proj" in script and "#SBATCH -t 04:00:00" in script
        assert "#SBATCH --mem=" in script
    else:
        assert "#PBS -q compute" in script and "#PBS -A proj" in script and "walltime=04:00:00" in script
