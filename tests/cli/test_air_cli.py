"""Air as the inflating fluid on the command line and in a sweep: ``curve --air-ml``, ``fluid:`` in
the YAML, ``rank`` on the air answer (docs/air.md)."""
from __future__ import annotations

import csv
import json

import pandas as pd
import pytest

from snapjump_cli.cli import main as cli_main
from snapjump_cli.commands.curve import main

AIR_KEYS = ("fluid", "air_V0_m3", "p_before_Pa", "p_after_Pa", "dV_snap_m3", "dE_J", "dy_pole_m", "h_imp_m",
            "water_dE_J", "water_dy_pole_m", "y_jump_m", "water_y_jump_m")


def test_curve_air_json_csv_and_plot(capsys, tmp_path):
    csv_path, png = tmp_path / "c.csv", tmp_path / "c.png"
    rc = main(["--design", "C", "--air-ml", "45", "--gamma", "1.4", "--format", "json", "--csv", str(csv_path),
               "--plot", str(png)])
    assert rc == 0
    m = json.loads(capsys.readouterr().out)
    assert all(k in m for k in AIR_KEYS)
    assert m["fluid"] == "air" and m["air_V0_m3"] == pytest.approx(45e-6) and m["air_gamma"] == 1.4
    assert m["p_before_Pa"] > m["p_after_Pa"] > 0 and m["dV_snap_m3"] > 0
    assert m["dE_J"] != m["water_dE_J"] and m["y_jump_m"] > m["h_imp_m"] and m["water_y_jump_m"] > 0
    rows = list(csv.DictReader(csv_path.read_text().splitlines()))
    assert list(rows[0])[-1] == "V_disp_m3" and float(rows[0]["V_disp_m3"]) == pytest.approx(0.0, abs=1e-12)
    up = next(r for r in rows if r["state"] == "upper")  # the named states are the air snap's
    # the CSV writes 12 significant digits: the same state's pressure, written the same way
    assert up["p_Pa"] == f"{m['p_before_Pa']:.12g}"
    assert float(up["V_disp_m3"]) == pytest.approx(m["V_disp_m3"], rel=1e-9)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_curve_water_reports_the_fluid_only(capsys):
    assert main(["--cap", "--theta", "60", "--eta", "8.5", "--bc", "roller-point", "--format", "json"]) == 0
    m = json.loads(capsys.readouterr().out)
    assert m["fluid"] == "water" and m["p_before_Pa"] is None
    assert m["y_jump_m"] is None  # the jump is reported with water too (issue 37); a cap alone has none


def test_curve_air_text(capsys):
    assert main(["--design", "C", "--air-ml", "100"]) == 0
    out = capsys.readouterr().out
    assert "air snap" in out and "eq 9" in out and "water snap" in out and "jump" in out


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--gamma", "1.4"], "--gamma needs --air-ml"),
        (["--p0", "1e5"], "--p0 needs --air-ml"),
        (["--air-ml", "0"], "--air-ml"),
        (["--air-ml", "inf"], "--air-ml"),
        (["--air-ml", "45", "--gamma", "0.5"], "--gamma"),
        (["--air-ml", "45", "--p0", "-1"], "--p0"),
        (["--air-ml", "45", "--harmonics", "2"], "--harmonics"),
    ],
)
def test_curve_air_bad_input_exit_2(capsys, tmp_path, monkeypatch, args, needle):
    monkeypatch.chdir(tmp_path)
    assert main(["--design", "C", *args, "--plot", "c.png"]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_sweep_and_rank_use_the_air_answer(tmp_path, capsys):
    """A sweep with ``fluid: air`` records the air snap (and the water one beside it); ``rank``
    computes the jump from the air snap and shows the fluid."""
    from snapjump_cli import jump

    cfg = tmp_path / "air.yaml"
    cfg.write_text("points:\n  - {eta_i: 8.5, theta_i: 60, eta_o: 16.5, theta_o: 90, mu_ratio: 5.8}\n"
                   "fluid: {kind: air, V0_ml: 100}\nn_jobs: 1\n")
    out = tmp_path / "air.parquet"
    assert cli_main(["sweep", str(cfg), "-o", str(out), "-q"]) == 0
    capsys.readouterr()
    df = pd.read_parquet(out)
    r = df.iloc[0]
    assert r["status"] == "ok" and r["fluid"] == "air" and r["air_V0_m3"] == pytest.approx(1e-4)
    assert r["dE_J"] > r["water_dE_J"] > 0 and '"fluid":{"V0_ml":100.0' in r["solver_settings"]
    assert cli_main(["rank", str(out), "--top", "3", "--format", "json"]) == 0
    row = json.loads(capsys.readouterr().out)["top"][0]
    mi, mo = jump.masses(r["V_inner_solid_m3"], r["V_outer_solid_m3"])
    y_air = jump.jump_height(r["dE_J"], r["dy_pole_m"], r["h_imp_m"], mi, mo).y_jump_m
    y_water = jump.jump_height(r["water_dE_J"], r["water_dy_pole_m"], r["water_h_imp_m"], mi, mo).y_jump_m
    assert row["fluid"] == "air"
    assert row["y_jump_mm"] == pytest.approx(y_air * 1e3, rel=1e-9) and abs(y_air - y_water) > 1e-4
