"""bench.followed_fig4: the grid with the followed sample merged in, and its report."""
from __future__ import annotations

import numpy as np
import pandas as pd

from bench import followed_fig4 as ff


def _grid(n: int = 6) -> pd.DataFrame:
    return pd.DataFrame({
        "status": ["ok"] * n, "eta_i": 5.0 + np.arange(n), "theta_i_deg": 75.0, "eta_o": 10.0, "theta_o_deg": 85.0,
        "mu_ratio": 1.0, "R_i": 0.03, "mu_i": 0.35e6, "dE_J": 0.01 * (1 + np.arange(n)), "dy_pole_m": 0.01,
        "asym_first": pd.array([True] * n, dtype="boolean"),
    })


def test_only_ok_followed_rows_of_grid_designs_replace_and_a_near_zero_snap_is_refused():
    g = _grid()
    f = g.iloc[[0, 1, 2]].copy()
    f["followed"] = pd.array([True, True, False], dtype="boolean")
    f["axisym_dE_J"] = f["dE_J"]
    f["dE_J"] = [0.004, 1e-9, 0.001]  # row 1: a "snap" of < 1 % of the axisymmetric dE (an old row)
    stray = f.iloc[[0]].copy()
    stray["eta_i"] = 99.0  # not a design of the grid
    merged, n, missing = ff.merge(g, [f, stray])
    assert n == 1 and missing == 1
    assert merged.loc[0, "dE_J"] == 0.004 and bool(merged.loc[0, "followed"])
    assert merged.loc[1, "dE_J"] == g.loc[1, "dE_J"] and merged.loc[2, "dE_J"] == g.loc[2, "dE_J"]


def test_report_gives_the_followed_over_axisymmetric_ratios():
    r = _grid(4)
    r["followed"] = pd.array([True, True, False, False], dtype="boolean")
    r["follow_n"] = [1, 2, None, None]
    r["axisym_dE_J"], r["axisym_dy_pole_m"], r["axisym_V_star_m3"] = 2 * r["dE_J"], 0.02, 1.0
    r["V_star_m3"] = 0.5
    r["y_jump_m"], r["y_jump_axisym_m"] = [0.01, 0.03, 0.2, 0.1], [0.04, 0.06, 0.2, 0.1]
    text = "\n".join(ff.report(r.sort_values("y_jump_m", ascending=False), top=2))
    assert "followed designs: 2" in text
    assert "| dE | 0.50 | 0.50 - 0.50 |" in text and "| jump | 0.38 | 0.25 - 0.50 |" in text
    assert "n = 1 (1 designs)" in text and "n = 2 (1 designs)" in text
    assert "top 2: 2 of 2 the same" in text


def test_report_counts_lift_offs_with_both_answers():
    r = _grid(4)
    r["followed"] = pd.array([True, True, True, False], dtype="boolean")
    r["follow_n"] = [1, 1, 1, None]
    r["axisym_dE_J"], r["axisym_dy_pole_m"], r["axisym_V_star_m3"], r["V_star_m3"] = r["dE_J"], 0.01, 1.0, 1.0
    r["y_jump_m"], r["y_jump_axisym_m"] = [0.01, 0.02, 0.03, 0.2], [0.04, 0.05, 0.06, 0.2]
    r["jumped"] = pd.array([False, True, False, True], dtype="boolean")
    axi = r.copy()
    axi["jumped"] = pd.array([True, True, False, True], dtype="boolean")
    text = "\n".join(ff.report(r, top=2, axisym=axi))
    assert "lift off: 1 of 3 (with their axisymmetric answers: 2)" in text


def test_the_designs_not_followed_are_listed_with_why():
    r = _grid(4)
    r["index"] = [10, 11, 12, 13]
    r["asym_n"] = [1, 1, 2, 2]
    r["follow_n"] = [1, 2, 2, 2]
    r["followed"] = pd.array([True, True, True, False], dtype="boolean")
    r["follow_note"] = ["", "harmonic 2 bifurcates first", "", "sphere path: stable state; the pole moves up"]
    text = "\n".join(ff.followed_or_not([r]))
    assert "asymmetric first: 4, followed 3; another harmonic than the check's followed (it bifurcates first): " \
           "1, 1 of them followed" in text
    assert "not followed: index 13: the pole moves up" in text and "index 12" not in text
