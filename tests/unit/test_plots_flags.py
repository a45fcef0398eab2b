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
