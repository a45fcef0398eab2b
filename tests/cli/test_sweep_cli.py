"""``snapjump sweep``: help, exit codes, bad configs (exit 2 + key path), a run with the
test-only fake solver injected."""
from __future__ import annotations

from pathlib import Path

import pytest

from snapjump_cli.cli import main as cli_main
from snapjump_cli.commands import sweep as sweep_cmd

FAKES = Path(__file__).resolve().parents[1] / "sweep"
GOOD = "grid: {eta_i: [6], theta_i: [80], eta_o: [10], theta_o: [78, 84, 86], mu_ratio: [1, 5.8]}\nmesh: {order: 1, nt: 2}\n"


_INJECT: dict = {}


@pytest.fixture
def fake_solver(monkeypatch):
    """Inject the test-only fake solver into the CLI (``cli.main(argv, solve_fn=...)``)."""
    monkeypatch.syspath_prepend(str(FAKES))
    import snapjump_fake_solvers as fake

    monkeypatch.setitem(_INJECT, "solve_fn", fake.fast_solve)


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli_main(["sweep", *argv], **_INJECT)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_help(capsys):
    code, out, _ = _run(capsys, "--help")
    assert code == 0
    for word in ("GRID.yaml", "--output", "--jobs", "--scheduler", "resume", "invalid_geometry", "{start, stop, num}"):
        assert word in out, word


def test_module_has_command_and_main():
    assert sweep_cmd.command.name == "sweep"
    assert sweep_cmd.main(["--help"]) == 0


BAD = [
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [10], theta_o: [84], mu_ratio: [1]}\nsolvr: {}\n", "solvr", "unknown key"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [10], theta_o: [84], mu_ratio: [1]}\nmesh: {order: 1, size: 3}\n",
     "mesh.size", "unknown key"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [10], theta_o: [84], mu_ratio: [1]}\nmesh: {nt: two}\n", "mesh.nt", "integer"),
    ("grid: {eta_i: {start: 5, stop: 8, num: 0}, theta_i: [80], eta_o: [10], theta_o: [84], mu_ratio: [1]}\n",
     "grid.eta_i.num", "integer >= 1"),
    ("grid: {eta_i: {start: 8, stop: 5, num: 3}, theta_i: [80], eta_o: [10], theta_o: [84], mu_ratio: [1]}\n",
     "grid.eta_i.stop", "stop >= start"),
    ("grid: {eta_i: [], theta_i: [80], eta_o: [10], theta_o: [84], mu_ratio: [1]}\n", "grid.eta_i", "empty list"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: [ten], theta_o: [84], mu_ratio: [1]}\n", "grid.eta_o[0]", "number"),
    ("grid: {eta_i: [6], theta_i: [80], eta_o: 10, theta_o: [84], mu_ratio: [1]}\n", "grid.eta_o", "list"),
    ("mesh: {order: 1}\n", "grid", "missing"),
    ("grid: {eta_i: [6, theta_i: [80]\n", None, "YAML syntax error at line"),
]


@pytest.mark.parametrize("text,key_path,words", BAD, ids=[b[1] or "yaml-syntax" for b in BAD])
def test_bad_config_exit_2_one_line_with_key_path(tmp_path, capsys, text, key_path, words):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    code, out, err = _run(capsys, str(p), "-o", str(tmp_path / "r.parquet"))
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"Error: {p}: "), err
    if key_path:
        assert f": {key_path}: " in lines[0], err
    assert words in lines[0], err
    assert "Traceback" not in err and not (tmp_path / "r.parquet").exists()
    assert not (tmp_path / "r.parquet.parts").exists()


def test_file_not_found_exit_2(tmp_path, capsys):
    code, _, err = _run(capsys, str(tmp_path / "missing.yaml"))
    assert code == 2 and "missing.yaml: file not found" in err and len(err.strip().splitlines()) == 1


def test_bad_jobs_exit_2(tmp_path, capsys):
    p = tmp_path / "g.yaml"
    p.write_text(GOOD)
    code, _, err = _run(capsys, str(p), "-j", "0")
    assert code == 2 and "-j/--jobs" in err
    code, _, err = _run(capsys, str(p), "-j", "many")
    assert code == 2


def test_output_that_is_not_a_result_file_exit_2(tmp_path, capsys, fake_solver):
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = tmp_path / "g.yaml"
    p.write_text(GOOD)
    other = tmp_path / "other.parquet"
    pq.write_table(pa.table({"x": [1]}), other)
    code, _, err = _run(capsys, str(p), "-o", str(other), "-j", "1", "--no-progress")
    assert code == 2 and "not a readable snapjump result file" in err


def test_sweep_with_fake_solver_hook_then_resume(tmp_path, capsys, fake_solver, monkeypatch):
    from snapjump_cli.sweep.results import read_metadata, read_results

    p = tmp_path / "g.yaml"
    p.write_text(GOOD + "output: results/from_config.parquet\nn_jobs: 1\n")
    monkeypatch.chdir(tmp_path)
    code, out, err = _run(capsys, str(p))  # output and n_jobs from the config, relative to the cwd
    assert code == 0, err
    res_file = tmp_path / "results" / "from_config.parquet"
    assert "6 designs (0 resumed, 4 solved" in out and "invalid_geometry 2" in out
    assert "sweep:" in err and "ok=" in err and "invalid=" in err  # the tqdm bar on stderr
    df = read_results(res_file)
    assert len(df) == 6 and set(df["status"]) == {"ok", "no_snap", "invalid_geometry"}
    assert read_metadata(res_file)["solver"] == "snapjump_fake_solvers:fast_solve"
    # -o overrides the config; rerunning the same command resumes (nothing solved again)
    code, out, _ = _run(capsys, str(p), "-o", str(res_file), "--no-progress")
    assert code == 0 and "(6 resumed, 0 solved" in out
