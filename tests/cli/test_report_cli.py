"""``snapjump report``: the design card and the sweep report are one self-contained HTML file each
(figures as base64 PNG, no URL fetched at view time) with the content they promise; bad input
exit 2, nothing written."""
from __future__ import annotations

import base64
import re
import sys
from pathlib import Path

import pytest
import yaml

SWEEP_TESTS = Path(__file__).resolve().parents[1] / "sweep"
if str(SWEEP_TESTS) not in sys.path:
    sys.path.insert(0, str(SWEEP_TESTS))

from snapjump_fake_solvers import fast_solve  # noqa: E402

from snapjump_cli.cli import main as cli_main  # noqa: E402
from snapjump_cli.commands.report import main  # noqa: E402

GRID = {"eta_i": [6, 7], "theta_i": [80], "eta_o": [5, 10], "theta_o": [78, 82, 86], "mu_ratio": [1, 5.8]}


def _self_contained(page: str) -> list[bytes]:
    """The page fetches nothing (no src/href to a URL, no @import) and its images decode as PNG."""
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", page), "a URL would be fetched"
    assert "@import" not in page and "<link" not in page
    imgs = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    data = [base64.b64decode(x) for x in imgs]
    assert all(d[:8] == b"\x89PNG\r\n\x1a\n" for d in data)
    return data


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("report")
    cfg = d / "grid.yaml"
    cfg.write_text(yaml.safe_dump({"grid": GRID, "mesh": {"order": 1, "nt": 2}}))
    out = d / "res.parquet"
    assert cli_main(["-q", "sweep", str(cfg), "-o", str(out), "--jobs", "1"], solve_fn=fast_solve, warm_up_fn=None) == 0
    return out


def test_results_page(results, tmp_path, capsys):
    page_path = tmp_path / "r.html"
    assert main([str(results), "-o", str(page_path), "--top", "5"]) == 0
    page = page_path.read_text()
    assert len(_self_contained(page)) == 3  # Fig. 4A, Fig. 4C, the parameters
    assert "Sweep report" in page and "24 designs (ok 12, no_snap 4, invalid_geometry 8)" in page
    assert "Fig. 4A" in page and "Fig. 4C" in page
    assert page.count("<tr>") >= 5 and "y_jump [mm]" in page and 'class="sortable"' in page and "<script>" in page
    assert "Why some designs were not solved" in page and "theta_i &lt; theta_o required" in page
    assert "Best design" in page and "Provenance" in page and "theta_o" in page  # the config
    assert not list(results.parent.glob("*.ranked.parquet"))  # the result file is left as it was


def test_design_card(tmp_path, capsys):
    import json

    from snapjump_cli.commands.curve import main as curve

    page_path = tmp_path / "c.html"
    assert main(["--design", "C", "-o", str(page_path)]) == 0
    assert curve(["--design", "C", "--format", "json"]) == 0
    m = json.loads(capsys.readouterr().out)
    page = page_path.read_text()
    assert len(_self_contained(page)) == 3  # the p-V curve, the states, the jump
    assert "design C" in page
    for value in (f"{m['p_star_Pa'] / 1e3:.4g}", f"{m['V_star_m3'] * 1e6:.4g}", f"{m['dE_J'] * 1e3:.4g}",
                  f"{m['dy_pole_m'] * 1e3:.4g}", f"{m['h_imp_m'] * 1e3:.4g}", f"{m['y_jump_m'] * 1e3:.4g}"):
        assert f"<td class=\"\">{value}</td>" in page, value
    assert "not asked (--follow)" in page and "asymmetric modes not checked" in page
    assert f"snapjump {m['snapjump_version']}" in page and "eta_i" in page  # version and inputs


@pytest.mark.parametrize("args,needle", [
    ([], "give a result file"),
    (["--design", "C", "-o", "x.txt"], "x.txt"),
    (["nothere.parquet", "-o", "r.html"], "nothere.parquet"),
    (["r.parquet", "--design", "C", "-o", "r.html"], "not both"),
])
def test_bad_input(tmp_path, monkeypatch, capsys, args, needle):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "r.parquet").write_bytes(b"x")
    if "-o" not in args:
        args = [*args, "-o", "r.html"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.parquet"]
