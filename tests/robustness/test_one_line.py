"""Class 4 of issue 38: bad input ends in exit 2 and one line naming the file, the column or the
value and what to do, never a traceback. The one reader of result files
(:func:`snapjump_cli.sweep.results.read_table` / ``read_metadata``), the one number check of the
YAML settings (:meth:`snapjump_cli.sweep.checks.CheckContext.number`) and the scheduler address
checked before anything is written (:func:`snapjump_cli.sweep.execution.check_scheduler`)."""
from __future__ import annotations

import os

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import snapjump_fake_solvers as fake
from conftest import GRID, run_cli


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _variant(src, dst, column=None, values=None, meta=None):
    t = pq.read_table(src)
    if column is not None:
        t = t.set_column(t.schema.get_field_index(column), column, pa.array(values))
    if meta is not None:
        md = dict(t.schema.metadata)
        md[b"snapjump"] = meta
        t = t.replace_schema_metadata(md)
    pq.write_table(t, dst)
    return dst


@pytest.mark.parametrize("column, values, words", [
    ("status", list(range(8)), "column 'status' has type int64, expected text"),
    ("asym_n", ["x"] * 8, "column 'asym_n' has type string, expected integers"),  # an optional column
])
def test_a_column_of_the_wrong_kind_is_named(results_file, tmp_path, capsys, column, values, words):
    bad = _variant(results_file, tmp_path / "bad.parquet", column, values)
    code, _, err = run_cli(capsys, "rank", str(bad), "-o", str(tmp_path / "out.parquet"))
    assert code == 2 and words in _one_line(err) and "bad.parquet" in err
    assert not (tmp_path / "out.parquet").exists()


def test_a_part_file_with_a_column_of_the_wrong_kind_is_named_on_resume(grid_file, tmp_path, capsys):
    out = tmp_path / "r.parquet"
    code, _, _ = run_cli(capsys, "sweep", str(grid_file()), "-o", str(out), "-j", "1", solve_fn=fake.fast_solve)
    parts = tmp_path / "r.parquet.parts"
    parts.mkdir()
    t = pq.read_table(out).slice(0, 2)
    pq.write_table(t.set_column(t.schema.get_field_index("n_steps"), "n_steps", pa.array(["a", "b"])),
                   parts / "part-000000.parquet")
    code, _, err = run_cli(capsys, "sweep", str(grid_file()), "-o", str(out), "-j", "1", solve_fn=fake.fast_solve)
    line = _one_line(err.replace("sweep: 8 designs", "").split("\n", 1)[-1] if err.startswith("sweep:") else err)
    assert code == 2 and "part-000000.parquet" in line and "'n_steps' has type string, expected integers" in line


def test_provenance_that_is_not_json_is_named(results_file, tmp_path, capsys):
    bad = _variant(results_file, tmp_path / "bad.parquet", meta=b"{not json")
    code, _, err = run_cli(capsys, "rank", str(bad), "-o", str(tmp_path / "out.parquet"))
    assert code == 2 and "bad.parquet: its provenance (parquet metadata key 'snapjump') is not JSON" in _one_line(err)


def test_a_ranked_file_given_to_rank_again_is_named(results_file, tmp_path, capsys):
    ranked = tmp_path / "ranked.parquet"
    assert run_cli(capsys, "rank", str(results_file), "-o", str(ranked))[0] == 0
    code, _, err = run_cli(capsys, "rank", str(ranked), "-o", str(tmp_path / "again.parquet"))
    assert code == 2 and "is a ranked table (written by snapjump rank from" in _one_line(err)
    assert "give rank the results file of the sweep" in err


def test_a_csv_given_to_rank_says_what_rank_needs(tmp_path, capsys):
    csv = tmp_path / "designs.csv"
    csv.write_text("eta_i,theta_i,eta_o,theta_o,mu_ratio\n6,80,10,86,5.8\n")
    code, _, err = run_cli(capsys, "rank", str(csv))
    line = _one_line(err)
    assert code == 2 and "is a text (CSV) file" in line and "snapjump sweep" in line and "magic" not in line


def test_a_file_name_that_is_not_utf8_is_read_and_written(results_file, tmp_path, capsys):
    src = os.fsdecode(bytes(tmp_path) + b"/r\xff.parquet")
    os.link(results_file, src)
    out = os.fsdecode(bytes(tmp_path) + b"/o\xfe.parquet")
    code, stdout, err = run_cli(capsys, "rank", src, "-o", out)
    assert code == 0, err
    assert os.path.exists(os.fsencode(out))


@pytest.mark.parametrize("block, key, value", [("solver", "ds0", "1e-320"), ("mesh", "aspect", 5e-324),
                                              ("materials", "mu_i", "4e-310")])
def test_subnormal_settings_are_refused_naming_the_key(grid_file, tmp_path, capsys, block, key, value):
    code, _, err = run_cli(capsys, "sweep", str(grid_file(**{block: {key: value}})), "-o", str(tmp_path / "r.parquet"),
                           solve_fn=fake.fast_solve)
    assert code == 2 and f"{block}.{key}: expected" in _one_line(err) and "subnormal" in err


def test_subnormal_jump_parameters_are_refused(results_file, tmp_path, capsys):
    code, _, err = run_cli(capsys, "rank", str(results_file), "--rho", "1e-320", "-o", str(tmp_path / "o.parquet"))
    assert code == 2 and "rho must be a normal number" in _one_line(err)


@pytest.mark.parametrize("address", ["http://127.0.0.1:1", "127.0.0.1:1 tcp", "tcp://"])
def test_a_scheduler_address_of_the_wrong_form_is_refused_before_anything_is_written(grid_file, tmp_path, capsys,
                                                                                      address):
    out = tmp_path / "r.parquet"
    grid = grid_file(grid={**GRID, "theta_o": [78, 82]})  # with invalid designs: rows that need no solver
    code, _, err = run_cli(capsys, "sweep", str(grid), "-o", str(out), "--scheduler", address, solve_fn=fake.fast_solve)
    assert code == 2 and _one_line(err).startswith(f"Error: --scheduler: {address!r}")
    assert sorted(os.listdir(tmp_path)) == ["grid.yaml"]  # no part file, no lock, no folder
