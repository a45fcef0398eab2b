"""Figures of a ranked sweep (paper Fig. 4A and 4C, plus jump height per parameter).

matplotlib (Agg backend) is imported inside the functions, so importing this module is cheap and
works without a display.
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["plot_fig4a", "plot_fig4c", "plot_jump_vs_parameters", "make_plots", "PARAMETERS", "PLOT_FILES"]

log = logging.getLogger(__name__)

#: (column, axis label) of the design parameters plotted against the jump height.
PARAMETERS: tuple[tuple[str, str], ...] = (
    ("eta_i", r"$\eta_i$"),
    ("theta_i_deg", r"$\theta_i$ [deg]"),
    ("eta_o", r"$\eta_o$"),
    ("theta_o_deg", r"$\theta_o$ [deg]"),
    ("mu_ratio", r"$\mu_i/\mu_o$"),
)
# The paper's colours: green for mu_i/mu_o = 1, purple for 5.8.
_RATIO_COLOURS = {1.0: "#2ca02c", 5.8: "#7b3294"}
_FALLBACK = ("#1f77b4", "#ff7f0e", "#d62728", "#8c564b", "#e377c2", "#7f7f7f")


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: str | Path, dpi: int) -> Path:
    """Write a figure atomically (:func:`snapjump_cli.files.write_atomic`)."""
    from snapjump_cli.files import write_atomic

    fmt = Path(path).suffix.lstrip(".").lower() or "png"
    return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt))


def _ok(df: pd.DataFrame) -> pd.DataFrame:
    d = df[df["status"] == "ok"].copy()
    for c in ("dE_J", "dy_pole_m", "R_i", "mu_i"):
        d[c] = d[c].astype("float64")
    d["x"] = d["dy_pole_m"] / d["R_i"]
    d["y"] = d["dE_J"] / (d["mu_i"] * d["R_i"] ** 3)
    return d[np.isfinite(d["x"]) & np.isfinite(d["y"])]


def _ratio_colour(r: float, i: int) -> str:
    for k, c in _RATIO_COLOURS.items():
        if abs(float(r) - k) < 1e-9:
            return c
    return _FALLBACK[i % len(_FALLBACK)]


def _log_y_if_wide(ax: Any, y: np.ndarray) -> None:
    pos = y[y > 0]
    if pos.size >= 2 and pos.max() / pos.min() > 100:
        ax.set_yscale("log")


def _empty_note(ax: Any, d: pd.DataFrame) -> None:
    if d.empty:
        ax.text(0.5, 0.5, "no snapping designs", ha="center", va="center", transform=ax.transAxes)


def plot_fig4a(df: pd.DataFrame, path: str | Path) -> Path:
    """Fig. 4A: ``dE / (mu_i R_i^3)`` against ``dy_pole / R_i`` of the ``ok`` rows, coloured by
    ``mu_i / mu_o``. Writes a PNG to ``path`` and returns it."""
    plt = _pyplot()
    d = _ok(df)
    fig, ax = plt.subplots(figsize=(6, 4.5), constrained_layout=True)
    try:
        for i, (r, g) in enumerate(sorted(d.groupby("mu_ratio"), key=lambda t: t[0])):
            ax.scatter(g["x"], g["y"], s=10, alpha=0.7, color=_ratio_colour(r, i), label=rf"$\mu_i/\mu_o$ = {r:g}")
        _log_y_if_wide(ax, d["y"].to_numpy())
        _empty_note(ax, d)
        ax.set_xlabel(r"$\Delta y_{pole} / R_i$")
        ax.set_ylabel(r"$\Delta E / (\mu_i R_i^3)$")
        ax.set_title(f"Energy release vs pole travel ({len(d)} snapping designs)")
        if not d.empty:
            ax.legend(loc="best", fontsize=8)
        path = _save(fig, path, 150)
    finally:
        plt.close(fig)
    return path


def plot_fig4c(ranked: pd.DataFrame, path: str | Path) -> Path:
    """Fig. 4C: ``y_jump / R_i`` over the ``(dy_pole / R_i, dE / (mu_i R_i^3))`` plane of the ``ok``
    rows (needs the columns of :func:`snapjump_cli.rank.rank_results`). Writes a PNG."""
    plt = _pyplot()
    d = _ok(ranked)
    d = d[np.isfinite(d["y_jump_m"].astype("float64"))]
    fig, ax = plt.subplots(figsize=(6.4, 4.5), constrained_layout=True)
    try:
        if not d.empty:
            z = (d["y_jump_m"].astype("float64") / d["R_i"]).to_numpy()
            o = np.argsort(z)  # highest jumps drawn on top
            sc = ax.scatter(d["x"].to_numpy()[o], d["y"].to_numpy()[o], c=z[o], s=12, cmap="viridis")
            fig.colorbar(sc, ax=ax, label=r"$y_{jump} / R_i$")
            best = d.iloc[int(np.argmax(z))]
            note = ax.annotate(
                f"best: ({best['eta_i']:.3g}, {best['theta_i_deg']:.3g}°, {best['eta_o']:.3g}, "
                f"{best['theta_o_deg']:.3g}°, {best['mu_ratio']:.3g})",
                (best["x"], best["y"]), fontsize=7, xytext=(-5, -12), textcoords="offset points", ha="right")
            note.set_in_layout(False)
        _log_y_if_wide(ax, d["y"].to_numpy())
        _empty_note(ax, d)
        ax.set_xlabel(r"$\Delta y_{pole} / R_i$")
        ax.set_ylabel(r"$\Delta E / (\mu_i R_i^3)$")
        ax.set_title("Jump height of the mass-spring model")
        path = _save(fig, path, 150)
    finally:
        plt.close(fig)
    return path


def plot_jump_vs_parameters(ranked: pd.DataFrame, path: str | Path) -> Path:
    """Jump height [mm] against each design parameter (one panel per parameter), coloured by
    ``mu_i / mu_o``; ``ok`` and ``no_snap`` rows. Writes a PNG."""
    plt = _pyplot()
    d = ranked[ranked["status"].isin(["ok", "no_snap"])].copy()
    d["yj"] = d["y_jump_m"].astype("float64") * 1e3
    d = d[np.isfinite(d["yj"])]
    fig, axes = plt.subplots(1, len(PARAMETERS), figsize=(3.2 * len(PARAMETERS), 3.4), sharey=True,
                             constrained_layout=True)
    try:
        groups = sorted(d.groupby("mu_ratio"), key=lambda t: t[0]) if not d.empty else []
        for ax, (col, label) in zip(axes, PARAMETERS):
            for i, (r, g) in enumerate(groups):
                x = g[col].astype("float64").to_numpy()
                span = np.ptp(x) if x.size else 0.0
                jitter = (np.random.default_rng(0).uniform(-0.015, 0.015, x.size) * span) if span > 0 else 0.0
                ax.scatter(x + jitter, g["yj"], s=6, alpha=0.6, color=_ratio_colour(r, i),
                           label=rf"$\mu_i/\mu_o$ = {r:g}")
            ax.set_xlabel(label)
            _empty_note(ax, d)
        axes[0].set_ylabel(r"$y_{jump}$ [mm]")
        if groups:
            axes[-1].legend(loc="best", fontsize=7)
        path = _save(fig, path, 130)
    finally:
        plt.close(fig)
    return path


#: The files :func:`make_plots` writes into its folder.
PLOT_FILES: tuple[str, ...] = ("fig4a.png", "fig4c.png", "jump_vs_parameters.png")


def make_plots(ranked: pd.DataFrame, out_dir: str | Path, batch: Any = None) -> list[Path]:
    """Write ``fig4a.png``, ``fig4c.png`` and ``jump_vs_parameters.png`` into ``out_dir``.

    ``batch``: a :class:`snapjump_cli.files.AtomicFiles` to add them to (written with the other
    outputs of a command, all or none); without it each is written atomically at once.

    Returns
    -------
    list of Path
        The files written.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    plots = ((plot_fig4a, "fig4a.png"), (plot_fig4c, "fig4c.png"), (plot_jump_vs_parameters, "jump_vs_parameters.png"))
    if batch is None:
        files = [fn(ranked, out_dir / name) for fn, name in plots]
    else:
        files = [batch.add(out_dir / name, lambda tmp, fn=fn: fn(ranked, tmp)) for fn, name in plots]
    for f in files:
        log.info("wrote %s", f)
    return files


def plot_pv_curve(curve: dict, metrics: dict, path: str | Path, title: str = "") -> Path:
    """The pressure-volume path of one scene, normalised as the paper's Fig. 2A
    (``p / mu_i`` against ``dV / R_i^3``), with the released energy dE shaded (the area between
    the path and the vertical line ``V = V*``), the volume limit point (black) and the isochoric
    point on the lower branch (white) marked."""
    plt = _pyplot()
    L, mu, V0 = curve["L_m"], curve["mu_Pa"], curve["V0_m3"]
    x = (np.asarray(curve["V_m3"]) - V0) / L**3
    y = np.asarray(curve["p_Pa"]) / mu
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.plot(x, y, "-", color="tab:blue", lw=1.4, label="equilibrium path")
    if metrics.get("snaps") and "snap_V_m3" in curve:
        sx = (np.asarray(curve["snap_V_m3"]) - V0) / L**3
        sy = np.asarray(curve["snap_p_Pa"]) / mu
        ax.fill(np.r_[sx, sx[:1]], np.r_[sy, sy[:1]], color="tab:blue", alpha=0.25,
                label=f"dE = {metrics['dE_J'] * 1e3:.4g} mJ ({metrics['lower_state_method']})")
        ax.plot(sx[0], sy[0], "o", mfc="k", mec="k", ms=7, label="volume limit V*")
        ax.plot(sx[-1], sy[-1], "o", mfc="w", mec="k", ms=7, label="isochoric point")
    ax.set_xlabel(r"$\Delta V / R_i^3$")
    ax.set_ylabel(r"$p / \mu_i$")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    try:
        return _save(fig, path, 120)
    finally:
        plt.close(fig)
