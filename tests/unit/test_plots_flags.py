"""The rank figures mark the flags (each its own marker, counted in the legend) and the best design."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("matplotlib")

from snapjump_cli.viz import figures as plots  # noqa: E402


def _ranked(n: int = 40, checked: bool = True) -> pd.DataFrame:
    rng = np.random.default_rng(1)
    d = pd.DataFrame({
        "status": ["ok"] * n,
        "eta_i": rng.choice([5.0, 6.5, 8.0], n), "theta_i_deg": rng.choice([70.0, 80.0], n),
        "eta_o": rng.choice([8.0, 12.0, 16.0], n), "theta_o_deg": rng.choice([82.0, 90.0], n),
        "mu_ratio": np.r_[np.ones(n // 2), np.full(n - n // 2, 5.8)],
        "R_i": 0.03, "mu_i": 0.35e6,
        "dE_J": rng.uniform(0.01, 0.3, n), "dy_pole_m": rng.uniform(0.01, 0.04, n),
        "y_jump_m": rng.uniform(0.01, 0.3, n),
        "self_crossing": pd.array([i % 5 == 0 for i in range(n)], dtype="boolean"),
        "mesh_sensitive": pd.array([i in (3, 30) for i in range(n)], dtype="boolean"),
    })
    if checked:
        d["asym_first"] = pd.array([i % 3 == 0 for i in range(n)], dtype="boolean")
    return d


@pytest.fixture
def legends(monkeypatch):
    """The legend texts and axes count of the figures drawn (nothing written)."""
    seen = []

    def save(fig, path, dpi):
        seen.append(([t.get_text() for lg in fig.legends for t in lg.get_texts()], len(fig.axes)))
        return path

    monkeypatch.setattr(plots, "_save", save)
    return seen


@pytest.mark.parametrize("draw", [plots.plot_fig4a, plots.plot_fig4c, plots.plot_jump_vs_parameters])
def test_flags_and_best_in_the_legend(legends, tmp_path, draw):
    d = _ranked()
    draw(d, tmp_path / "f.png")
    texts, _ = legends[-1]
    joined = "\n".join(texts)
    n_asym = int(d["asym_first"].sum())
    best = d.loc[d["y_jump_m"].idxmax()]
    assert f"asymmetric mode first ({n_asym})" in joined
    assert f"axisymmetric up to V* ({len(d) - n_asym})" in joined
    assert f"{best['y_jump_m'] * 1e3:.0f} mm" in joined and "best:" in joined
    if draw is not plots.plot_jump_vs_parameters:
        assert f"self-crossing path ({int(d['self_crossing'].sum())})" in joined
        assert "mesh-sensitive snap (2)" in joined


def test_unchecked_tables_say_so(legends, tmp_path):
    plots.plot_fig4a(_ranked(checked=False), tmp_path / "f.png")
    assert "asymmetric modes not checked" in "\n".join(legends[-1][0])


def test_mu_ratios_get_their_own_rows(legends, tmp_path):
    plots.plot_jump_vs_parameters(_ranked(), tmp_path / "f.png")
    assert legends[-1][1] == 2 * 4  # two rows of the four geometric parameters: no ratio hides the other
    d = _ranked()
    d["mu_ratio"] = np.linspace(1, 6, len(d))  # many ratios: one row, coloured
    plots.plot_jump_vs_parameters(d, tmp_path / "g.png")
    assert legends[-1][1] == 5


@pytest.mark.parametrize("draw", [plots.plot_fig4a, plots.plot_fig4c, plots.plot_jump_vs_parameters])
def test_followed_designs_are_drawn_at_their_followed_answer_joined_to_the_axisymmetric_one(legends, tmp_path, draw):
    d = _ranked()
    fol = np.array([i % 6 == 0 for i in range(len(d))])  # a subset of the asymmetric-first rows
    d["followed"] = pd.array(fol, dtype="boolean")
    d["axisym_dE_J"] = np.where(fol, 2.0 * d["dE_J"], d["dE_J"])
    d["axisym_dy_pole_m"] = np.where(fol, 1.5 * d["dy_pole_m"], d["dy_pole_m"])
    draw(d, tmp_path / "f.png")
    joined = "\n".join(legends[-1][0])
    assert f"followed asymmetric snap ({int(fol.sum())})" in joined
    assert f"asymmetric mode first ({int(d['asym_first'].sum())}; {int(fol.sum())} followed)" in joined
    if draw is not plots.plot_jump_vs_parameters:
        assert f"its axisymmetric answer, which does not happen ({int(fol.sum())})" in joined


def test_the_followed_lines_run_from_the_axisymmetric_answer_to_the_followed_one(monkeypatch, tmp_path):
    d = _ranked()
    fol = np.array([i % 6 == 0 for i in range(len(d))])
    d["followed"] = pd.array(fol, dtype="boolean")
    d["axisym_dE_J"], d["axisym_dy_pole_m"] = 2.0 * d["dE_J"], 1.5 * d["dy_pole_m"]
    d.loc[6, "axisym_dE_J"] = np.nan  # no axisymmetric answer: not drawn as followed
    seen = {}

    def save(fig, path, dpi):
        from matplotlib.collections import LineCollection

        seen["segs"] = [c.get_segments() for c in fig.axes[0].collections if isinstance(c, LineCollection)]
        return path

    monkeypatch.setattr(plots, "_save", save)
    rows = d[fol & (np.arange(len(d)) != 6)]
    R, mu = 0.03, 0.35e6
    plots.plot_fig4a(d, tmp_path / "f.png", normalised=True)  # the paper's axes
    (segs,) = seen["segs"]
    assert len(segs) == len(rows)
    for s, (_, r) in zip(segs, rows.iterrows()):
        np.testing.assert_allclose(s[0], [r["axisym_dy_pole_m"] / R, r["axisym_dE_J"] / (mu * R**3)], rtol=1e-12)
        np.testing.assert_allclose(s[1], [r["dy_pole_m"] / R, r["dE_J"] / (mu * R**3)], rtol=1e-12)
    plots.plot_fig4a(d, tmp_path / "f.png")  # the default: mm and mJ
    (segs,) = seen["segs"]
    for s, (_, r) in zip(segs, rows.iterrows()):
        np.testing.assert_allclose(s[0], [r["axisym_dy_pole_m"] * 1e3, r["axisym_dE_J"] * 1e3], rtol=1e-12)
        np.testing.assert_allclose(s[1], [r["dy_pole_m"] * 1e3, r["dE_J"] * 1e3], rtol=1e-12)
