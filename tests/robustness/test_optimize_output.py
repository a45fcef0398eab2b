"""optimize keeps what is not its own: it takes the output's lock, refuses a file that is not a
run of the same spec (a sweep's results, another spec's run) unless --overwrite, leaves foreign
plots alone, and writes its plots with the umask's mode."""
from __future__ import annotations

import os
import stat

import pyarrow.parquet as pq
import yaml

import snapjump_fake_solvers as fake
from conftest import run_cli
from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.storage import OutputLock

SPEC = {"bounds": {"eta_i": [5.5, 7.5], "theta_i": 80, "eta_o": [5, 10], "theta_o": 86, "mu_ratio": 5.8},
        "objective": "dE_J", "budget": 6, "seed": 1, "search": {"starts": 1}, "confirm": False,
        "mesh": {"order": 1, "nt": 2, "aspect": 4.0}}


def _spec(tmp_path, name: str = "s.yaml", **changes) -> str:
    p = tmp_path / name
    p.write_text(yaml.safe_dump({**SPEC, **changes}))
    return str(p)


def _optimize(capsys, spec: str, out, *extra: str):
    return run_cli(capsys, "optimize", spec, "-o", str(out), "-j", "1", "--no-progress", *extra,
                   solve_fn=fake.fast_solve, warm_up_fn=None)


def test_a_sweeps_results_are_never_replaced_without_overwrite(tmp_path, capsys, results_file):
    before = results_file.read_bytes()
    code, _, err = _optimize(capsys, _spec(tmp_path), results_file)
    assert code == 2 and "holds the results of snapjump sweep" in err and "--overwrite" in err
    assert len(err.strip().splitlines()) == 1 and results_file.read_bytes() == before
    assert not (tmp_path / "r.evals.parquet").exists()  # refused before anything ran
    code, _, err = _optimize(capsys, _spec(tmp_path), results_file, "--overwrite")
    assert code == 0, err
    assert res.read_metadata(results_file)["command"] == "optimize"


def test_the_output_of_a_running_sweep_is_locked(tmp_path, capsys):
    out = tmp_path / "busy.parquet"
    with OutputLock(out):  # a sweep writing into it
        code, _, err = _optimize(capsys, _spec(tmp_path), out)
    assert code == 2 and "another sweep is writing into this output" in err and f"pid {os.getpid()}" in err
    assert not out.exists() and not (tmp_path / "busy.evals.parquet").exists()


def test_a_rerun_of_the_same_spec_replaces_its_own_files_others_are_refused(tmp_path, capsys):
    out = tmp_path / "o.parquet"
    old = os.umask(0o027)
    try:
        code, _, err = _optimize(capsys, _spec(tmp_path), out)
    finally:
        os.umask(old)
    assert code == 0, err
    progress = tmp_path / "o.progress.png"
    assert stat.S_IMODE(progress.stat().st_mode) == 0o640 == stat.S_IMODE(out.stat().st_mode)
    # the same search (a larger budget continues it): its own files are replaced
    code, _, err = _optimize(capsys, _spec(tmp_path, budget=8), out)
    assert code == 0, err
    # another spec: refused, naming what differs; nothing replaced
    before = {p.name: p.read_bytes() for p in tmp_path.glob("o.*")}
    code, _, err = _optimize(capsys, _spec(tmp_path, "t.yaml", seed=2), out)
    assert code == 2 and "another spec (seed differ)" in err
    assert {p.name: p.read_bytes() for p in tmp_path.glob("o.*")} == before
    code, _, err = _optimize(capsys, _spec(tmp_path, "t.yaml", seed=2), out, "--overwrite")
    assert code == 0, err
    assert pq.read_schema(out).metadata is not None


def test_plots_of_someone_else_are_kept(tmp_path, capsys):
    out = tmp_path / "new.parquet"
    theirs = tmp_path / "new.progress.png"
    theirs.write_bytes(b"someone's figure")
    code, _, err = _optimize(capsys, _spec(tmp_path), out)
    assert code == 2 and "new.progress.png: exists" in err and theirs.read_bytes() == b"someone's figure"
    assert not out.exists()
    code, _, err = _optimize(capsys, _spec(tmp_path), out, "--overwrite")
    assert code == 0 and theirs.read_bytes() != b"someone's figure"
