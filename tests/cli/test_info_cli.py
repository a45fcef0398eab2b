"""``snapjump info RESULTS.parquet``: counts by status, the grouped reasons, provenance; text and
JSON; bad input exit 2. The result file comes from a sweep with the fake solver (no FE)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import yaml

SWEEP_TESTS = Path(__file__).resolve().parents[1] / "sweep"
if str(SWEEP_TESTS) not in sys.path:
    sys.path.insert(0, str(SWEEP_TESTS))

from snapjump_fake_solvers import fast_solve  # noqa: E402

from snapjump_cli.cli import main as cli_main  # noqa: E402
from snapjump_cli.commands.info import main  # noqa: E402
from snapjump_cli.sweep.results import group_failures as group_reasons  # noqa: E402

#: theta_o 78 < theta_i 80 is invalid: 4 designs with one reason, numbers differing.
GRID = {"eta_i": [6, 7], "theta_i": [80], "eta_o": [5, 10], "theta_o": [78, 82, 86], "mu_ratio": [1]}


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("info")
    cfg = d / "grid.yaml"
    cfg.write_text(yaml.safe_dump({"grid": GRID, "mesh": {"order": 1, "nt": 2}}))
    out = d / "res.parquet"
    assert cli_main(["-q", "sweep", str(cfg), "-o", str(out), "--jobs", "1"], solve_fn=fast_solve, warm_up_fn=None) == 0
    return out


def test_info_json(results, capsys):
    assert main([str(results), "--format", "json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["n_rows"] == 12
    assert s["status_counts"] == {"ok": 4, "no_snap": 4, "invalid_geometry": 4}
    assert len(s["reasons"]) == 1 and s["reasons"][0]["count"] == 4
    assert s["reasons"][0]["status"] == "invalid_geometry" and "#" in s["reasons"][0]["reason"]
    assert s["config"]["grid"]["theta_o"] == [78, 82, 86]
    assert s["command"] == "sweep" and s["version"] and s["created_utc"] and s["hosts"]
    assert s["ranked"] is False and s["best"] is None


def test_info_text(results, capsys):
    assert main([str(results)]) == 0
    out = capsys.readouterr().out
    assert "designs          12: ok 4, no_snap 4, invalid_geometry 4" in out
    assert "why not solved" in out and "invalid_geometry" in out
    assert "config" in out and "theta_o" in out and "hosts" in out


def test_info_ranked(results, tmp_path, capsys):
    ranked = tmp_path / "r.parquet"
    assert cli_main(["-q", "rank", str(results), "-o", str(ranked)]) == 0
    capsys.readouterr()
    assert main([str(ranked), "--format", "json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["ranked"] is True and s["best"]["y_jump_m"] >= 0


def test_group_reasons_masks_numbers():
    g = group_reasons(["failed", "failed", "ok", "invalid_geometry"],
                      ["Newton failed at step 12 (p = 1.5e3)", "Newton failed at step 7 (p = 2e3)", None, None])
    assert g[0] == {"status": "failed", "reason": "Newton failed at step # (p = #)", "count": 2,
                    "example": "Newton failed at step 12 (p = 1.5e3)"}
    assert g[1]["reason"] == "(no reason recorded)"


@pytest.mark.parametrize("make", ["missing", "dir", "csv"])
def test_info_bad_input(tmp_path, capsys, make):
    p = tmp_path / "x.parquet"
    if make == "dir":
        p.mkdir()
    elif make == "csv":
        p.write_text("a,b\n1,2\n")
    assert main([str(p)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(p) in err[0]
