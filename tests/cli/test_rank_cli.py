"""``snapjump rank``: the jump model applied to a small result file, the table, the ranked file,
the plots, and bad input."""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from snapjump_cli.sweep import results as res
from snapjump_cli.cli import main as cli_main
from snapjump_cli.commands import rank as rank_cmd
from snapjump_cli.sweep.config import parse_config
from snapjump_cli.jump import JumpParams, jump_height, masses
from snapjump_cli.jump.rank import RANK_COLUMNS, rank_results
from snapjump_cli.sweep.run import run_sweep

FAKES = Path(__file__).resolve().parents[1] / "sweep"


@pytest.fixture(scope="module")
def results_file(tmp_path_factory):
    """A 16-design result file from the fake solver: ok, no_snap, invalid_geometry and failed rows."""
    sys.path.insert(0, str(FAKES))
    try:
        import snapjump_fake_solvers as fake
    finally:
        sys.path.remove(str(FAKES))
    cfg = parse_config({"grid": {"eta_i": [6], "theta_i": [80], "eta_o": [8, 12], "theta_o": [78, 82, 85, 86],
                                 "mu_ratio": [1, 5.8]}, "mesh": {"order": 1, "nt": 2}})
    out = tmp_path_factory.mktemp("rank") / "r.parquet"
    run_sweep(cfg, output=out, n_jobs=1, solve_fn=fake.flaky_solve, progress=False)
    return out


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli_main(["rank", *argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_rank_results_applies_the_jump_model(results_file):
    df = res.read_results(results_file)
    assert set(df["status"]) == {"ok", "no_snap", "invalid_geometry", "failed"}
    ranked = rank_results(df)
    assert len(ranked) == len(df) and all(c in ranked.columns for c in RANK_COLUMNS)
    ok = ranked[ranked["status"] == "ok"]
    for _, r in ok.iterrows():
        m_i, m_o = masses(r["V_inner_solid_m3"], r["V_outer_solid_m3"], 1000.0)
        jr = jump_height(r["dE_J"], r["dy_pole_m"], r["h_imp_m"], m_i, m_o, JumpParams())
        assert r["y_jump_m"] == pytest.approx(jr.y_jump_m, rel=1e-12)
        assert r["m_i_kg"] == pytest.approx(m_i) and r["k_s"] == pytest.approx(2 * r["dE_J"] / r["dy_pole_m"] ** 2)
        assert r["y_jump_norm"] == pytest.approx(r["y_jump_m"] / r["R_i"])
    ns = ranked[ranked["status"] == "no_snap"]
    assert len(ns) and (ns["y_jump_m"] == 0).all() and (ns["jump_reason"] == "no snap").all()
    assert (~ns["jumped"].astype(bool)).all()
    bad = ranked[ranked["status"].isin(["invalid_geometry", "failed"])]
    assert bad["y_jump_m"].isna().all() and bad["rank"].isna().all()
    assert bad["jump_reason"].str.contains("eq 5|SolveFailed|non-finite").all()
    y = ranked["y_jump_m"].to_numpy(dtype=float)
    fin = y[~np.isnan(y)]
    assert (np.diff(fin) <= 0).all() and np.isnan(y[len(fin):]).all()  # sorted, NaN last
    assert list(ranked["rank"][: len(fin)]) == list(range(1, len(fin) + 1))


def test_rank_results_survives_a_jump_model_error(results_file):
    df = res.read_results(results_file)

    def boom(*a, **k):
        raise ValueError("h_imp_m must be >= 0")

    ranked = rank_results(df, JumpParams(), jump_fn=boom, masses_fn=masses)
    ok = ranked[ranked["status"] == "ok"]
    assert ok["y_jump_m"].isna().all() and ok["jump_reason"].str.contains("jump model failed").all()


def test_rank_cli_table_file_and_plots(results_file, tmp_path, capsys):
    out = tmp_path / "ranked.parquet"
    plots = tmp_path / "figs"
    code, stdout, err = _run(capsys, str(results_file), "--top", "3", "-o", str(out), "--plots", str(plots))
    assert code == 0, err
    assert "y_jump_mm" in stdout and "rank" in stdout and f"wrote {out}" in stdout
    table_rows = [ln for ln in stdout.splitlines() if ln.strip().startswith(("1 ", "2 ", "3 "))]
    assert len(table_rows) == 3
    ranked = res.read_results(out)
    assert list(ranked.columns[:1]) == ["rank"] and "y_jump_m" in ranked.columns
    meta = res.read_metadata(out)
    assert meta["rank"]["jump_params"]["rho"] == 1000.0 and meta["command"] == "sweep"  # sweep provenance kept
    for name in ("fig4a.png", "fig4c.png", "jump_vs_parameters.png"):
        f = plots / name
        assert f.exists() and f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    assert not list(tmp_path.glob(".*.tmp"))


def test_rank_cli_default_output_and_options(results_file, capsys):
    code, stdout, err = _run(capsys, str(results_file), "--top", "0", "--rho", "1100", "--alpha", "0.3")
    assert code == 0, err
    out = results_file.with_name("r.ranked.parquet")
    assert out.exists() and res.read_metadata(out)["rank"]["jump_params"]["alpha"] == 0.3
    assert "y_jump_mm" not in stdout


def test_rank_cli_bad_input(tmp_path, capsys, results_file):
    code, _, err = _run(capsys, str(tmp_path / "nope.parquet"))
    assert code == 2 and "nope.parquet: file not found" in err
    junk = tmp_path / "junk.parquet"
    junk.write_text("not parquet")
    code, _, err = _run(capsys, str(junk))
    assert code == 2 and "not a readable parquet file" in err
    other = tmp_path / "other.parquet"
    pd.DataFrame({"a": [1]}).to_parquet(other)
    code, _, err = _run(capsys, str(other))
    assert code == 2 and "missing column(s) status" in err
    code, _, err = _run(capsys, str(results_file), "--alpha", "2")
    assert code == 2 and "alpha" in err
    code, _, err = _run(capsys, str(results_file), "-o", str(results_file))
    assert code == 2 and "overwrite" in err


def test_rank_module_has_command_and_main(capsys):
    assert rank_cmd.command.name == "rank"
    assert rank_cmd.main(["--help"]) == 0
    out = capsys.readouterr().out
    for word in ("--top", "--plots", "Fig. 4A", "no_snap", "--output"):
        assert word in out, word


def test_plots_with_no_snapping_design(tmp_path):
    from snapjump_cli.viz.figures import make_plots

    df = pd.DataFrame({"status": ["no_snap"], "dE_J": [0.0], "dy_pole_m": [math.nan], "R_i": [0.03],
                       "mu_i": [0.35e6], "mu_ratio": [1.0], "eta_i": [6.0], "theta_i_deg": [80.0], "eta_o": [10.0],
                       "theta_o_deg": [84.0], "y_jump_m": [0.0]})
    files = make_plots(df, tmp_path)
    assert all(f.exists() for f in files)


@pytest.mark.parametrize("where", ["output", "plots"])
def test_unwritable_output_or_plots_is_exit_2_and_writes_nothing(tmp_path, capsys, results_file, where):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    out = tmp_path / "ranked.parquet"
    argv = [str(results_file), "-o", str(blocker / "r.parquet") if where == "output" else str(out)]
    if where == "plots":
        argv += ["--plots", str(blocker / "plots")]
    code, _, err = _run(capsys, *argv)
    assert code == 2 and str(blocker) in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_right_columns_wrong_types_is_exit_2_naming_the_column(tmp_path, capsys, results_file):
    df = res.read_results(results_file)
    bad = tmp_path / "bad.parquet"
    df.assign(dE_J=df["dE_J"].astype(str)).to_parquet(bad)
    code, _, err = _run(capsys, str(bad), "-o", str(tmp_path / "o.parquet"), "--plots", str(tmp_path / "plots"))
    assert code == 2 and "column 'dE_J' has type" in err and "expected numbers" in err
    assert not (tmp_path / "o.parquet").exists() and not (tmp_path / "plots").exists()  # no folder either


def test_rank_says_when_a_file_mixes_settings(tmp_path, capsys, results_file):
    df = res.read_results(results_file)
    mixed = tmp_path / "mixed.parquet"
    df.assign(mesh_nt=[2] * (len(df) - 3) + [3] * 3).to_parquet(mixed)
    code, _, err = _run(capsys, str(mixed), "-o", str(tmp_path / "o.parquet"))
    assert code == 0 and "mixes rows computed with different settings: mesh_nt: 2 (13 rows), 3 (3 rows)" in err
    code, _, err = _run(capsys, str(results_file), "-o", str(tmp_path / "o2.parquet"))
    assert code == 0 and "mixes" not in err


def test_table_shows_the_flags_and_formats(tmp_path, capsys, results_file):
    code, out, _ = _run(capsys, str(results_file), "-o", str(tmp_path / "a.parquet"), "--top", "3")
    header = out.splitlines()[1].split()
    assert code == 0 and {"self_crossing", "mesh_sensitive", "jump_complete", "lower_state"} <= set(header)
    code, out, err = _run(capsys, str(results_file), "-o", str(tmp_path / "b.parquet"), "--top", "3", "--format", "csv")
    lines = out.strip().splitlines()
    assert code == 0 and len(lines) == 4 and lines[0].startswith("rank,eta_i,theta_i,")
    assert "wrote" in err and "wrote" not in out
    code, out, err = _run(capsys, str(results_file), "-o", str(tmp_path / "c.parquet"), "--top", "2", "--format", "json")
    doc = json.loads(out)
    assert code == 0 and doc["n_designs"] == 16 and len(doc["top"]) == 2 and doc["top"][0]["rank"] == 1
    assert doc["top"][0]["y_jump_mm"] >= doc["top"][1]["y_jump_mm"] and doc["files"] == [str(tmp_path / "c.parquet")]


def test_existing_outputs_are_kept_unless_overwrite(tmp_path, capsys, results_file):
    out = tmp_path / "r.parquet"
    assert _run(capsys, str(results_file), "-o", str(out))[0] == 0
    before = out.read_bytes()
    code, _, err = _run(capsys, str(results_file), "-o", str(out))
    assert code == 2 and f"{out}: exists; pass --overwrite" in err and out.read_bytes() == before
    assert _run(capsys, str(results_file), "-o", str(out), "--overwrite")[0] == 0
    plots = tmp_path / "plots"
    assert _run(capsys, str(results_file), "-o", str(tmp_path / "p1.parquet"), "--plots", str(plots))[0] == 0
    code, _, err = _run(capsys, str(results_file), "-o", str(tmp_path / "p2.parquet"), "--plots", str(plots))
    assert code == 2 and "fig4a.png: exists" in err and not (tmp_path / "p2.parquet").exists()


def test_asymmetric_designs_are_flagged_or_excluded(tmp_path, capsys, results_file):
    df = res.read_results(results_file)
    ok = df.index[df["status"] == "ok"]
    asym = df.copy()
    asym["asym_first"] = pd.array([False] * len(df), dtype="boolean")
    asym["asym_n"] = pd.array([None] * len(df), dtype="Int64")
    asym.loc[ok[0], "asym_first"], asym.loc[ok[0], "asym_n"] = True, 2
    f = tmp_path / "asym.parquet"
    asym.to_parquet(f)
    code, out, _ = _run(capsys, str(f), "-o", str(tmp_path / "a.parquet"), "--format", "json", "--top", "20")
    rows = json.loads(out)["top"]
    assert code == 0 and sum(r["asym_n"] == 2 for r in rows) == 1  # flagged, still ranked
    n_ranked = sum(r["rank"] is not None for r in rows)
    code, out, _ = _run(capsys, str(f), "-o", str(tmp_path / "b.parquet"), "--format", "json", "--top", "20",
                        "--exclude-asymmetric")
    rows = json.loads(out)["top"]
    assert code == 0 and sum(r["rank"] is not None for r in rows) == n_ranked - 1
    ranked = res.read_results(tmp_path / "b.parquet")
    assert ranked["jump_reason"].str.contains("harmonic n = 2 loses stability").sum() == 1
    code, out, _ = _run(capsys, str(f), "-o", str(tmp_path / "t.parquet"), "--top", "20")
    assert code == 0 and "<NA>" not in out  # the stable designs' empty asym_n shows as "-"
    col = out.splitlines()[1].split().index("asym_n")
    cells = [line.split()[col] for line in out.splitlines()[2:] if len(line.split()) > col]
    assert cells.count("2") == 1 and set(cells) <= {"2", "-"}
    code, out, _ = _run(capsys, str(results_file), "-o", str(tmp_path / "c.parquet"))
    assert "asym_n" not in out  # no harmonic check in the file: no column
    assert "followed" not in out and "axisym_y_mm" not in out  # no branch followed: no columns


def test_followed_rows_rank_by_the_followed_answer_and_show_the_axisymmetric_one(tmp_path, capsys, results_file):
    df = res.read_results(results_file)
    ok = df.index[df["status"] == "ok"]
    fol = df.copy()
    j = df.loc[ok, "dE_J"].astype(float).idxmax()  # the strongest snap: it jumps, and less with half dE
    fol["asym_first"] = pd.array([False] * len(df), dtype="boolean")
    fol["asym_n"] = pd.array([None] * len(df), dtype="Int64")
    fol["followed"] = pd.array([False] * len(df), dtype="boolean")
    for k in ("dE_J", "dy_pole_m", "h_imp_m"):
        fol["axisym_" + k] = df[k]
    # row j went asymmetric first: its followed snap releases half the energy of the axisymmetric one
    fol.loc[j, "asym_first"], fol.loc[j, "asym_n"], fol.loc[j, "followed"] = True, 1, True
    fol.loc[j, "dE_J"] = 0.5 * df.loc[j, "dE_J"]
    f = tmp_path / "followed.parquet"
    fol.to_parquet(f)
    for extra in ((), ("--exclude-asymmetric",)):  # a followed row is never excluded: its snap happens
        out_file = tmp_path / f"r{len(extra)}.parquet"
        code, out, _ = _run(capsys, str(f), "-o", str(out_file), *extra)
        assert code == 0 and "axisym_y_mm" in out.splitlines()[1] and "followed" in out.splitlines()[1]
        ranked = res.read_results(out_file)
        row = ranked[ranked["followed"].fillna(False).astype(bool)].iloc[0]
        assert row["rank"] is not pd.NA and row["y_jump_m"] > 0
        # the followed answer ranks; the axisymmetric answer's jump is shown beside it
        assert row["y_jump_axisym_m"] > row["y_jump_m"]
        others = ranked[~ranked["followed"].fillna(False).astype(bool) & (ranked["status"] == "ok")]
        assert (others["y_jump_axisym_m"] == others["y_jump_m"]).all()


def test_follow_needs_the_harmonic_check():
    from snapjump_cli.commands.curve import main as curve_main
    from snapjump_cli.settings import SettingsError, SolverSettings

    with pytest.raises(SettingsError, match="follow"):
        SolverSettings(follow=True)
    assert SolverSettings(harmonics=4, follow=True).follow
    assert curve_main(["--design", "B", "--follow"]) == 2
