"""bench/: the tools no make target runs answer ``--help`` (and the profiles find the library
functions they call), so a move in the library cannot leave them broken unnoticed."""
from __future__ import annotations

import importlib
import pkgutil

import pytest

import bench.profile

#: every module of bench/profile/, plus the bench tools that no make target runs
TOOLS = ["bench.grid_compare", "bench.followed_fig4", "bench.followed_grid_time", "bench.arbiter"] + [
    f"bench.profile.{m.name}" for m in pkgutil.iter_modules(bench.profile.__path__)]


@pytest.mark.parametrize("name", TOOLS)
def test_help(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    mod = importlib.import_module(name)
    with pytest.raises(SystemExit) as e:
        mod.main(["--help"])
    assert e.value.code == 0
    assert "usage:" in capsys.readouterr().out


def test_profiles_listed() -> None:
    assert "bench.profile.follow" in TOOLS


def test_follow_profile_stages_are_library_functions() -> None:
    """The stages ``--cprofile`` reports are found by function name: each must still exist."""
    from bench.profile import follow

    names = set()
    for m in pkgutil.walk_packages(importlib.import_module("snapjump_cli.fe").__path__, "snapjump_cli.fe."):
        mod = importlib.import_module(m.name)
        names |= {n for n, v in vars(mod).items() if callable(v)}
        names |= {n for c in vars(mod).values() if isinstance(c, type) for n in vars(c)}
    assert set(follow.STAGES) <= names, set(follow.STAGES) - names


def test_followed_grid_time_leaves_the_re_solved_rows_out_of_the_class_means(tmp_path, capsys) -> None:
    """The class means without the rows re-solved one mesh finer, the design wall at those means
    over the grid's rows, and the estimate's mean per harmonic weighted by each class's rows."""
    import pandas as pd

    from bench import followed_grid_time

    rows = [  # (status, followed, follow_n, mu_ratio, mesh_check, wall_s)
        ("ok", True, 1, 1.0, "", 2.0), ("ok", True, 1, 1.0, "", 4.0),
        ("ok", True, 2, 5.8, "", 10.0), ("ok", True, 2, 5.8, "lower state by descent; not re-checked: ...", 30.0),
        ("ok", True, 2, 5.8, "lower state by descent; re-solved at nt=3", 300.0),
        ("ok", False, None, 1.0, "", 1.0), ("invalid_geometry", None, None, 1.0, None, 0.0),
    ]
    d = pd.DataFrame(rows, columns=["status", "followed", "follow_n", "mu_ratio", "mesh_check", "wall_s"])
    d["followed"] = d["followed"].astype("boolean")
    d["follow_n"] = d["follow_n"].astype("Int64")
    path = tmp_path / "f.parquet"
    d.to_parquet(path)
    assert followed_grid_time.main([str(path)]) == 0
    out = capsys.readouterr().out
    # n = 2, mu 5.8 without the re-solved row: mean 20 s over its 3 rows; n = 1: 3 s over 2
    assert "design wall at those class means: 67 s" in out  # 2 x 3 + 3 x 20 + 1 (+ 0)
    assert "REF_FOLLOW[1]: share 2 / 6, mean wall 3.00 s" in out
    assert "REF_FOLLOW[2]: share 3 / 6, mean wall 20.00 s" in out


def test_ratios_summarises_the_followed_rows() -> None:
    """The median and 90th percentile of the followed rows' ratios (rows that stay axisymmetric have
    none), and the designs at the per-design limit."""
    from bench.profile.ratios import summary

    rows = [{"design": f"d{i}", "ratio": float(i), "cpu_followed_s": 10.0 * i} for i in range(1, 11)]
    rows.append({"design": "axisymmetric", "cpu_axisym_check_s": 0.1})
    rows.append({"design": "slow", "ratio": 3000.0, "cpu_followed_s": 300.0})
    s = summary(rows, 300.0)
    assert s["designs"] == 11 and s["median"] == 6.0 and s["largest"] == 3000.0
    assert s["p90"] == 10.0 and s["at_limit"] == ["slow"]


def test_answers_compares_the_designs_followed_in_both_runs() -> None:
    """Designs matched by their row, relative differences against the second run, and whether
    both landed the same way; a design not followed in one run is left out."""
    from bench.profile.answers import compare

    def row(i, dE, kind="jump", note="sphere path: stable state"):
        return {"design": f"s#{i}", "dE_J": dE, "dy_pole_m": 1.0, "V_star_m3": 2.0, "p_star_Pa": 3.0,
                "follow_kind": kind, "branches": [{"lower_note": note}]}

    a = [row(0, 1.01), row(1, 2.0, "subcritical"), {"design": "s#2", "dE_J": None}]
    b = [row(0, 1.0), row(1, 2.0), row(2, 5.0)]
    out = compare(a, b)
    assert [r["design"] for r in out] == ["0", "1"]
    assert out[0]["dE_J"] == pytest.approx(0.01) and out[0]["dy_pole_m"] == 0.0 and out[0]["same_way"]
    assert not out[1]["same_way"]


def test_follow_profile_repeats_the_followed_solve(tmp_path) -> None:
    """``--repeat-followed K``: the followed answer computed K times (the same answer values each
    time, else the tool stops), the least CPU the ratio's numerator."""
    import json

    from bench.profile import follow

    out = tmp_path / "f.json"
    assert follow.main(["--sample", "bench/harmonics_sample/follow_strata.yaml", "--rows", "7", "--repeat", "1",
                        "--repeat-followed", "2", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    (row,) = doc["rows"] if isinstance(doc, dict) else doc
    assert row["followed"] and len(row["cpu_followed_runs_s"]) == 2
    assert row["cpu_followed_s"] == min(row["cpu_followed_runs_s"])
    assert row["ratio"] == pytest.approx(row["cpu_followed_s"] / row["cpu_axisym_check_s"])
