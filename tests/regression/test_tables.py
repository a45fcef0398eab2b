"""The tables the README and docs quote (``bench.tables``: ``make scenes-table``, ``make
named-jumps``, ``make harmonics-counts``): each row is the solve's answer, formatted as the docs
show it."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from bench import tables
from snapjump_cli.fe.solve import solve_design, solve_scene
from snapjump_cli.geometry.designs import FIG1_CAPS, get_design
from snapjump_cli.jump import JumpParams, jump_height, masses
from snapjump_cli.settings import MeshSettings, SolverSettings


def test_levels_and_scenes():
    assert tables.parse_levels("2:2:2,1:3:2.5") == [(2, 2, 2.0), (1, 3, 2.5)]
    sc = tables.scenes()
    assert set("ABCD") <= set(sc) and set(FIG1_CAPS) <= set(sc)
    assert sc["A"][1] is None and sc["cap30-clamped"][1] == FIG1_CAPS["cap30-clamped"][2]


def test_a_scene_row_is_the_curve_solve():
    row = tables.scene_row("cap30-clamped", (2, 2, 2.0))
    m = solve_scene(tables.scenes()["cap30-clamped"][0], MeshSettings(order=2, nt=2, aspect=2.0), SolverSettings()).metrics
    assert row["snaps"] and row["dE_norm"] == m["dE_norm"] and row["dy_pole_norm"] == m["dy_pole_norm"]
    line = tables.scene_line(row)
    paper = FIG1_CAPS["cap30-clamped"][2]
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[:2] == ["cap30-clamped", "2/2/2"]
    assert cells[2] == f"{m['dE_norm']:.3e} muR^3" and cells[3] == f"{m['dy_pole_norm']:.4f} R"
    assert cells[4] == f"{paper[0]:.3g} muR^3" and cells[5] == f"{paper[1]:.3g} R"
    assert len(cells) == tables.SCENES_HEADER.splitlines()[0].count("|") - 1


def test_a_failed_or_snapless_scene_says_so():
    from snapjump_cli.fe.solve import SolveFailed

    def failing(scene, mesh, solver):
        raise SolveFailed("no volume limit")

    row = tables.scene_row("A", (2, 2, 2.0), solve=failing)
    assert row["error"] == "no volume limit" and "failed: no volume limit" in tables.scene_line(row)
    flat = {**row, "snaps": False, "dE_rel_diff": None, "lower_state_method": None, "n_steps": 12}
    del flat["error"]
    assert "| no snap | - |" in tables.scene_line(flat)


def test_a_named_jump_row_is_the_sweep_solve_then_the_jump_model():
    row = tables.named_jump_row("C")
    m = solve_design(get_design("C"))
    p = JumpParams()
    mi, mo = masses(m["V_inner_solid_m3"], m["V_outer_solid_m3"], p.rho)
    j = jump_height(m["dE_J"], m["dy_pole_m"], m["h_imp_m"], mi, mo, p)
    assert row["dE_J"] == m["dE_J"] and row["y_jump_m"] == j.y_jump_m and row["jumped"] is bool(j.jumped)
    assert row["jumped"] and row["y_jump_m"] > row["h_imp_m"]
    cells = [c.strip() for c in tables.named_jump_line(row).strip("|").split("|")]
    assert cells[0] == "C" and cells[1] == f"{m['dE_J'] * 1e3:.4g}" and cells[6] == f"{j.y_jump_m * 1e3:.4g}"
    assert cells[7] == "yes"


def _checked_rows() -> pd.DataFrame:
    """Six rows of a sweep with the harmonic check: 4 ok (2 asymmetric first, n = 2 and 3; one of
    them self-crossing; one stable design self-crossing), one no-snap, one invalid."""
    ok = dict(status="ok", eta_i=6.0, theta_i_deg=80.0, eta_o=10.0, theta_o_deg=82.0, V_star_m3=2.0, p_max_Pa=10.0)
    rows = [
        {**ok, "mu_ratio": 1.0, "asym_first": True, "asym_n": 2, "asym_V_m3": 1.0, "asym_p_Pa": 5.0,
         "asym_lower_stable": True, "self_crossing": True, "dE_J": 0.010},
        {**ok, "mu_ratio": 5.8, "asym_first": True, "asym_n": 3, "asym_V_m3": 1.5, "asym_p_Pa": 9.0,
         "asym_lower_stable": False, "self_crossing": False, "dE_J": 0.030},
        {**ok, "mu_ratio": 5.8, "asym_first": False, "asym_n": None, "asym_V_m3": None, "asym_p_Pa": None,
         "asym_lower_stable": True, "self_crossing": True, "dE_J": 0.020},
        {**ok, "mu_ratio": 5.8, "asym_first": False, "asym_n": None, "asym_V_m3": None, "asym_p_Pa": None,
         "asym_lower_stable": None, "self_crossing": False, "dE_J": 0.040},
        {**ok, "status": "no_snap", "mu_ratio": 1.0},
        {**ok, "status": "invalid_geometry", "mu_ratio": 1.0},
    ]
    df = pd.DataFrame(rows)
    for k in ("asym_first", "asym_lower_stable", "self_crossing"):
        df[k] = df[k].astype("boolean")
    df["asym_n"] = df["asym_n"].astype("Int64")
    return df


def test_harmonics_counts():
    c = tables.harmonics_counts(_checked_rows())
    assert c["status"] == {"ok": 4, "no_snap": 1, "invalid_geometry": 1}
    assert c["ok"] == 4 and c["asym_first"] == 2 and c["unchecked"] == 0
    assert c["first_n"] == {2: 1, 3: 1}
    assert c["by_mu_ratio"] == {1.0: (1, 1), 5.8: (1, 3)}
    assert np.allclose(c["V_over_Vstar"], [0.5, 0.75]) and np.allclose(c["p_over_pmax"], [0.5, 0.9])
    assert (c["lower_stable"], c["lower_unstable"], c["lower_unchecked"]) == (2, 1, 1)
    assert c["confusion"] == {"not self-crossing": (1, 1), "self-crossing": (1, 1)} and c["agree"] == 2
    assert c["median_dE_J"] == pytest.approx((0.020, 0.030))
    lines = "\n".join(tables.harmonics_lines(c))
    assert "valid (ok): 4; a harmonic unstable before V*: 2 (50.0%)" in lines
    assert "| all | 2 | 2 | 4 |" in lines and "agreement of the two: 2/4 = 50%" in lines
    assert not math.isnan(c["median_dE_J"][0])
