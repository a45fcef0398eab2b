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

__all__ = ["plot_fig4a", "plot_fig4c", "plot_jump_vs_parameters", "make_plots", "plot_pv_curve", "plot_air_curves",
           "PARAMETERS", "PLOT_FILES"]

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


def _ok(df: pd.DataFrame, normalised: bool = False) -> pd.DataFrame:
    """The ``ok`` rows with the plane's coordinates ``x``, ``y``: pole travel [mm] and released
    energy [mJ], or (``normalised``) the paper's ``dy_pole / R_i`` and ``dE / (mu_i R_i^3)``."""
    d = df[df["status"] == "ok"].copy()
    for c in ("dE_J", "dy_pole_m", "R_i", "mu_i"):
        d[c] = d[c].astype("float64")
    if normalised:
        d["x"] = d["dy_pole_m"] / d["R_i"]
        d["y"] = d["dE_J"] / (d["mu_i"] * d["R_i"] ** 3)
    else:
        d["x"] = d["dy_pole_m"] * 1e3
        d["y"] = d["dE_J"] * 1e3
    return d[np.isfinite(d["x"]) & np.isfinite(d["y"])]


#: The plane's axis labels: physical (default) and normalised.
_PLANE_LABELS = {False: ("pole travel $\\Delta y_{pole}$ [mm]", "energy released $\\Delta E$ [mJ]"),
                 True: (r"pole travel $\Delta y_{pole} / R_i$", r"energy released $\Delta E / (\mu_i R_i^3)$")}


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


# ---- the flags of a design, each with its own marker ------------------------------------------
#: marker of a design whose axisymmetric snap holds (circle), of one that goes asymmetric first
#: (triangle) and of one whose asymmetric branch was followed to its snap (diamond: the point is
#: the followed answer, a line joins it to the axisymmetric answer, drawn as an open triangle)
_AXI, _ASYM, _FOL = "o", "^", "D"


_SIZES = {_AXI: 12, _ASYM: 16, _FOL: 20}


def _flags(d: pd.DataFrame) -> dict[str, np.ndarray]:
    """Boolean masks of the flags of the rows of ``d``: ``asym`` (a non-axisymmetric mode loses
    stability before V*), ``self_crossing``, ``mesh_sensitive``; ``checked``: whether any row had
    the harmonic check."""
    def col(name: str) -> np.ndarray:
        if name not in d.columns:
            return np.zeros(len(d), bool)
        return d[name].astype("boolean").fillna(False).to_numpy(bool)

    checked = "asym_first" in d.columns and bool(d["asym_first"].notna().any())
    followed = col("followed")
    if followed.any():  # a followed row needs its axisymmetric answer to draw the line from it
        followed &= np.isfinite(_axisym_xy(d)).all(axis=0)
    return {"asym": col("asym_first"), "followed": followed, "self_crossing": col("self_crossing"),
            "mesh_sensitive": col("mesh_sensitive"), "checked": np.array(checked)}


def _axisym_xy(d: pd.DataFrame, normalised: bool | None = None) -> np.ndarray:
    """The axisymmetric answers of the rows in the plane's coordinates (``dy_pole / R_i, dE /
    (mu_i R_i^3)``, or mm and mJ; NaN where a row has none), as a 2 x n array; ``normalised``
    defaults to the frame's own (``d.attrs["normalised"]``)."""
    if normalised is None:
        normalised = bool(d.attrs.get("normalised", False))
    if "axisym_dE_J" not in d.columns or "axisym_dy_pole_m" not in d.columns:
        return np.full((2, len(d)), np.nan)
    def f(c: str) -> np.ndarray:
        return pd.to_numeric(d[c], errors="coerce").astype("float64").to_numpy(na_value=np.nan)

    R, mu = f("R_i"), f("mu_i")
    if not normalised:
        return np.vstack([f("axisym_dy_pole_m") * 1e3, f("axisym_dE_J") * 1e3])
    return np.vstack([f("axisym_dy_pole_m") / R, f("axisym_dE_J") / (mu * R**3)])


def _shapes(fl: dict[str, np.ndarray]) -> tuple[tuple[str, np.ndarray], ...]:
    """(marker, mask) of the rows drawn with each shape."""
    fol = fl["followed"]
    return ((_AXI, ~fl["asym"] & ~fol), (_ASYM, fl["asym"] & ~fol), (_FOL, fol))


def _mark_followed(ax: Any, d: pd.DataFrame, fl: dict[str, np.ndarray]) -> list:
    """Join each followed design's answer (diamond) to its axisymmetric answer (open triangle) with
    a thin line; legend handles."""
    fol = fl["followed"]
    if not fol.any():
        return []
    from matplotlib.collections import LineCollection

    x0, y0 = _axisym_xy(d)[:, fol]
    x1, y1 = d["x"].to_numpy()[fol], d["y"].to_numpy()[fol]
    ax.add_collection(LineCollection(np.stack([np.c_[x0, y0], np.c_[x1, y1]], axis=1), colors="0.35", lw=0.6,
                                     alpha=0.7, zorder=3))
    h = ax.scatter(x0, y0, marker=_ASYM, s=22, facecolors="none", edgecolors="0.35", lw=0.7, zorder=3,
                   label=f"its axisymmetric answer, which does not happen ({int(fol.sum())})")
    return [h]


def _mark_flags(ax: Any, x: np.ndarray, y: np.ndarray, flags: dict[str, np.ndarray]) -> list:
    """Overlay the self-crossing (x) and mesh-sensitive (open orange square) designs; legend handles."""
    handles = []
    sc, ms = flags["self_crossing"], flags["mesh_sensitive"]
    if sc.any():
        handles.append(ax.scatter(x[sc], y[sc], marker="x", s=8, lw=0.5, color="0.25", zorder=4,
                                  label=f"self-crossing path ({int(sc.sum())})"))
    if ms.any():
        handles.append(ax.scatter(x[ms], y[ms], marker="s", s=40, facecolors="none", edgecolors="#ff7f0e", lw=1.0,
                                  zorder=5, label=f"mesh-sensitive snap ({int(ms.sum())})"))
    return handles


def _shape_handles(flags: dict[str, np.ndarray], colour: str = "0.45") -> list:
    """Legend entries of the two marker shapes (whether the harmonic check ran)."""
    from matplotlib.lines import Line2D

    asym, fol = flags["asym"], flags.get("followed", np.zeros_like(flags["asym"]))
    if not bool(flags["checked"]):
        return [Line2D([], [], ls="", marker=_AXI, color=colour, label="asymmetric modes not checked")]
    out = [Line2D([], [], ls="", marker=_AXI, color=colour, label=f"axisymmetric up to V* ({int((~asym).sum())})"),
           Line2D([], [], ls="", marker=_ASYM, color=colour,
                  label=f"asymmetric mode first ({int(asym.sum())}" + (f"; {int(fol.sum())} followed)" if fol.any() else ")"))]
    if fol.any():
        out.append(Line2D([], [], ls="", marker=_FOL, color=colour, mec="k", mew=0.6,
                          label=f"followed asymmetric snap ({int(fol.sum())})"))
    return out


def _best(d: pd.DataFrame) -> pd.Series | None:
    """The row of the highest jump (``None`` without jump heights)."""
    if "y_jump_m" not in d.columns or d.empty:
        return None
    yj = d["y_jump_m"].astype("float64")
    if not np.isfinite(yj).any():
        return None
    return d.loc[yj.idxmax()]


def _mark_best(ax: Any, best: pd.Series | None, x: str, y: str) -> list:
    """An open star on the best design (the points under it stay visible); its label goes to the
    legend below the axes, so it covers no point."""
    if best is None:
        return []
    return [ax.scatter([best[x]], [best[y]], marker="*", s=300, facecolors="none", edgecolors="#d62728", lw=1.4,
                       zorder=6, label=_mark_best_label(best))]


def _legend_below(fig: Any, handles: list, ncols: int = 2) -> None:
    fig.legend(handles=handles, loc="outside lower center", ncols=ncols, fontsize=7.5, frameon=False)


def plot_fig4a(df: pd.DataFrame, path: str | Path, normalised: bool = False) -> Path:
    """Fig. 4A: the released energy [mJ] against the pole travel [mm] (``normalised``: the paper's
    ``dE / (mu_i R_i^3)`` against ``dy_pole / R_i``) of the ``ok`` rows, coloured by
    ``mu_i / mu_o``; triangles for the designs that go asymmetric before V* (the harmonic check),
    crosses for self-crossing paths, open squares for mesh-sensitive snaps and a star for the
    highest jump (when the table is ranked). Writes a PNG to ``path`` and returns it."""
    plt = _pyplot()
    d = _ok(df, normalised)
    d.attrs["normalised"] = normalised
    fl = _flags(d)
    fig, ax = plt.subplots(figsize=(6.4, 5.4), layout="constrained")
    try:
        handles = []
        for i, (r, g) in enumerate(sorted(d.groupby("mu_ratio"), key=lambda t: t[0])):
            colour = _ratio_colour(r, i)
            sel = d["mu_ratio"].to_numpy() == r
            for shape, mask in _shapes({k: v[sel] if v.ndim else v for k, v in fl.items()}):
                if mask.any():
                    ax.scatter(g["x"].to_numpy()[mask], g["y"].to_numpy()[mask], s=_SIZES[shape], marker=shape,
                               alpha=0.75 if shape != _FOL else 1.0, color=colour,
                               lw=0 if shape != _FOL else 0.6, edgecolors="k" if shape == _FOL else "face",
                               zorder=4 if shape == _FOL else 2)
            handles.append(ax.scatter([], [], s=30, color=colour, label=rf"$\mu_i/\mu_o$ = {r:g} ({len(g)})"))
        handles += _shape_handles(fl) + _mark_followed(ax, d, fl)
        handles += _mark_flags(ax, d["x"].to_numpy(), d["y"].to_numpy(), fl)
        handles += _mark_best(ax, _best(d), "x", "y")
        _log_y_if_wide(ax, d["y"].to_numpy())
        _empty_note(ax, d)
        ax.set_xlabel(_PLANE_LABELS[normalised][0])
        ax.set_ylabel(_PLANE_LABELS[normalised][1])
        ax.set_title(f"Energy release vs pole travel ({len(d)} snapping designs)", fontsize=10)
        if not d.empty:
            _legend_below(fig, handles)
        path = _save(fig, path, 150)
    finally:
        plt.close(fig)
    return path


def plot_fig4c(ranked: pd.DataFrame, path: str | Path, normalised: bool = False) -> Path:
    """Fig. 4C: the jump height [mm] over the plane of :func:`plot_fig4a` (``normalised``:
    ``y_jump / R_i`` over the ``(dy_pole / R_i, dE / (mu_i R_i^3))`` plane) of the ``ok``
    rows (needs the columns of :func:`snapjump_cli.jump.rank.rank_results`), with the flags' markers of
    :func:`plot_fig4a` and the best design starred. Writes a PNG."""
    plt = _pyplot()
    d = _ok(ranked, normalised)
    d = d[np.isfinite(d["y_jump_m"].astype("float64"))]
    d.attrs["normalised"] = normalised
    fl = _flags(d)
    fig, ax = plt.subplots(figsize=(6.6, 5.4), layout="constrained")
    try:
        handles = []
        if not d.empty:
            z = (d["y_jump_m"].astype("float64") / d["R_i"]).to_numpy() if normalised else \
                (d["y_jump_m"].astype("float64") * 1e3).to_numpy()
            x, y = d["x"].to_numpy(), d["y"].to_numpy()
            norm = plt.Normalize(float(z.min()), float(z.max()))
            for shape, mask in _shapes(fl):
                o = np.flatnonzero(mask)[np.argsort(z[mask])]  # highest jumps drawn on top
                if o.size:
                    ax.scatter(x[o], y[o], c=z[o], s=_SIZES[shape] + 2, marker=shape, cmap="viridis",
                               norm=norm, lw=0 if shape != _FOL else 0.6, edgecolors="face" if shape != _FOL else "k",
                               zorder=4 if shape == _FOL else 2)
            fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap="viridis"), ax=ax,
                         label=r"jump height $y_{jump} / R_i$" if normalised else r"jump height $y_{jump}$ [mm]")
            handles += _shape_handles(fl) + _mark_followed(ax, d, fl)
            handles += _mark_flags(ax, x, y, fl) + _mark_best(ax, _best(d), "x", "y")
        _log_y_if_wide(ax, d["y"].to_numpy())
        _empty_note(ax, d)
        ax.set_xlabel(_PLANE_LABELS[normalised][0])
        ax.set_ylabel(_PLANE_LABELS[normalised][1])
        ax.set_title("Jump height of the mass-spring model", fontsize=10)
        if handles:
            _legend_below(fig, handles)
        path = _save(fig, path, 150)
    finally:
        plt.close(fig)
    return path


def plot_jump_vs_parameters(ranked: pd.DataFrame, path: str | Path) -> Path:
    """Jump height [mm] against each design parameter, ``ok`` and ``no_snap`` rows: one row of
    panels per ``mu_i / mu_o`` (up to four values, so neither hides the other; more are coloured
    in one row), triangles for the designs that go asymmetric first, a star for the best design.
    Points are spread a little sideways within a grid value. Writes a PNG."""
    plt = _pyplot()
    d = ranked[ranked["status"].isin(["ok", "no_snap"])].copy()
    d["yj"] = d["y_jump_m"].astype("float64") * 1e3
    d = d[np.isfinite(d["yj"])]
    ratios = sorted(d["mu_ratio"].astype("float64").unique()) if not d.empty else []
    by_row = 1 <= len(ratios) <= 4
    params = [p for p in PARAMETERS if not (by_row and p[0] == "mu_ratio")]
    nrows = len(ratios) if by_row else 1
    fig, axes = plt.subplots(nrows, len(params), figsize=(2.35 * len(params) + 0.4, 2.3 * nrows + 0.9),
                             sharey=True, sharex="col", squeeze=False, layout="constrained")
    best = _best(d)
    fl_all = _flags(d)
    try:
        rng = np.random.default_rng(0)
        rows = [(r, d["mu_ratio"].astype("float64").to_numpy() == r) for r in ratios] if by_row else [(None, None)]
        handles = []
        for i, (r, sel) in enumerate(rows):
            g = d if sel is None else d[sel]
            fl = _flags(g)
            for ax, (col, label) in zip(axes[i], params):
                x = g[col].astype("float64").to_numpy()
                span = np.ptp(d[col].astype("float64").to_numpy()) if len(d) else 0.0
                x = x + (rng.uniform(-0.015, 0.015, x.size) * span if span > 0 else 0.0)
                colours = ([_ratio_colour(r, i)] * len(g)) if by_row else [
                    _ratio_colour(v, ratios.index(v)) for v in g["mu_ratio"].astype("float64")]
                colours = np.array(colours, dtype=object)
                for shape, mask in _shapes(fl):
                    if mask.any():
                        ax.scatter(x[mask], g["yj"].to_numpy()[mask], s=_SIZES[shape] * 0.45, marker=shape,
                                   alpha=0.55 if shape != _FOL else 1.0, c=list(colours[mask]),
                                   lw=0 if shape != _FOL else 0.4, edgecolors="face" if shape != _FOL else "k")
                if best is not None and (sel is None or abs(float(best["mu_ratio"]) - r) < 1e-12):
                    h = ax.scatter([float(best[col])], [float(best["yj"])], marker="*", s=170, facecolors="none",
                                   edgecolors="#d62728", lw=1.1, zorder=6)
                    if not handles:
                        handles.append(h)
                ax.tick_params(labelsize=8)
                if i == nrows - 1:
                    ax.set_xlabel(label)
                _empty_note(ax, g)
            axes[i, 0].set_ylabel(r"$y_{jump}$ [mm]" + (f"\n$\\mu_i/\\mu_o$ = {r:g}" if by_row else ""))
        if handles:
            handles[0].set_label(_mark_best_label(best))
        handles = handles + _shape_handles(fl_all)
        if not d.empty:
            _legend_below(fig, handles, ncols=3)
        path = _save(fig, path, 130)
    finally:
        plt.close(fig)
    return path


def _mark_best_label(best: pd.Series) -> str:
    return (f"best: $\\eta_i$ {best['eta_i']:.3g}, $\\theta_i$ {best['theta_i_deg']:.3g}°, "
            f"$\\eta_o$ {best['eta_o']:.3g}, $\\theta_o$ {best['theta_o_deg']:.3g}°, "
            f"$\\mu_i/\\mu_o$ {best['mu_ratio']:.3g}: {float(best['y_jump_m']) * 1e3:.0f} mm")


#: The files :func:`make_plots` writes into its folder.
PLOT_FILES: tuple[str, ...] = ("fig4a.png", "fig4c.png", "jump_vs_parameters.png")


def make_plots(ranked: pd.DataFrame, out_dir: str | Path, batch: Any = None, normalised: bool = False) -> list[Path]:
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
    from functools import partial

    plots = ((partial(plot_fig4a, normalised=normalised), "fig4a.png"),
             (partial(plot_fig4c, normalised=normalised), "fig4c.png"), (plot_jump_vs_parameters, "jump_vs_parameters.png"))
    if batch is None:
        files = [fn(ranked, out_dir / name) for fn, name in plots]
    else:
        files = [batch.add(out_dir / name, lambda tmp, fn=fn: fn(ranked, tmp)) for fn, name in plots]
    for f in files:
        log.info("wrote %s", f)
    return files


def _pv_axes(curve: dict, normalised: bool):
    """``(fx, fy, xlabel, ylabel)``: the p-V plot's axes, physical (kPa against ml) or normalised as
    the paper's Fig. 2A (``p / mu_i`` against ``dV / R_i^3``)."""
    L, mu, V0 = curve["L_m"], curve["mu_Pa"], curve["V0_m3"]
    if normalised:
        return ((lambda V: (np.asarray(V, float) - V0) / L**3), (lambda p: np.asarray(p, float) / mu),
                r"$\Delta V / R_i^3$", r"$p / \mu_i$")
    return ((lambda V: np.asarray(V, float) * 1e6), (lambda p: np.asarray(p, float) / 1e3),
            "cavity volume V [ml]", "pressure p [kPa]")


def plot_pv_curve(curve: dict, metrics: dict, path: str | Path, title: str = "", branch: dict | None = None,
                  normalised: bool = False, imperfect: dict | None = None) -> Path:
    """The pressure-volume path of one scene (pressure [kPa] against volume [ml]; ``normalised``:
    the paper's Fig. 2A axes ``p / mu_i`` against ``dV / R_i^3``), with the released energy dE
    shaded (the area between the path and the vertical line ``V = V*``), the volume limit point
    (black) and the isochoric point on the lower branch (white) marked.

    ``branch`` (:func:`snapjump_cli.fe.branch.metrics.branch_curve`): the followed non-axisymmetric branch.
    When the followed snap is the answer (``metrics["followed"]``) it is the main curve: the path
    up to the bifurcation and the branch from there, its snap shaded and labelled with the reported
    dE; the axisymmetric path beyond the bifurcation and its snap are drawn thin and pale, as what
    does not happen. ``imperfect`` (:func:`snapjump_cli.viz.outputs.imperfect_curve`): the imperfect
    actuator's path from rest (``--imperfection``), dashed, its snap shaded and labelled with
    ``imp_dE_J``. The legend is below the axes, so it covers no curve. The format follows the
    suffix (``.png``, ``.svg``, ``.pdf``)."""
    plt = _pyplot()
    fx, fy, xlabel, ylabel = _pv_axes(curve, normalised)
    x, y = fx(curve["V_m3"]), fy(curve["p_Pa"])
    fig, ax = plt.subplots(figsize=(6.4, 5.2), layout="constrained")
    followed = branch is not None and bool(metrics.get("followed"))
    main, pale = "tab:blue", "0.6"
    snap_axi = metrics.get("snaps") and "snap_V_m3" in curve
    if not followed:
        label = "equilibrium path" if branch is None else "axisymmetric path"
        ax.plot(x, y, "-", color=main, lw=1.5, label=label)
        if snap_axi:
            sx, sy = fx(curve["snap_V_m3"]), fy(curve["snap_p_Pa"])
            dE = metrics.get("axisym_dE_J") if branch is not None and metrics.get("axisym_dE_J") is not None \
                else metrics["dE_J"]
            ax.fill(np.r_[sx, sx[:1]], np.r_[sy, sy[:1]], color=main, alpha=0.25,
                    label=f"dE = {dE * 1e3:.4g} mJ ({metrics['lower_state_method']})")
            ax.plot(sx[0], sy[0], "o", mfc="k", mec="k", ms=7, label="volume limit V*")
            ax.plot(sx[-1], sy[-1], "o", mfc="w", mec="k", ms=7, label="isochoric point")
        if branch is not None:  # followed but not the answer: drawn for comparison
            bx, by = fx(branch["V_m3"]), fy(branch["p_Pa"])
            ax.plot(bx, by, "-", color="tab:orange", lw=1.1, label=f"followed branch ({_branch_what(branch)})")
            _branch_marks(ax, branch, fx, fy)
    else:
        bx, by = fx(branch["V_m3"]), fy(branch["p_Pa"])
        V_bif = np.asarray(branch["V_m3"])[0]
        before = np.asarray(curve["V_m3"]) <= V_bif
        s_bif = int(np.argmin(before)) if not before.all() else len(before)  # the first point past it
        ax.plot(x[s_bif - 1:], y[s_bif - 1:], "-", color=pale, lw=1.0,
                label="axisymmetric path past the bifurcation (does not happen)")
        if snap_axi and metrics.get("axisym_dE_J") is not None:
            sx, sy = fx(curve["snap_V_m3"]), fy(curve["snap_p_Pa"])
            ax.fill(np.r_[sx, sx[:1]], np.r_[sy, sy[:1]], facecolor="none", edgecolor=pale, hatch="///", lw=0.6,
                    label=f"axisymmetric dE = {metrics['axisym_dE_J'] * 1e3:.4g} mJ (does not happen)")
        ax.plot(np.r_[x[:s_bif], bx[:1]], np.r_[y[:s_bif], by[:1]], "-", color=main, lw=1.8,
                label="axisymmetric loading, to the bifurcation")
        ax.plot(bx, by, "-", color="tab:orange", lw=1.8, label=f"followed branch ({_branch_what(branch)})")
        _branch_marks(ax, branch, fx, fy)
        if "snap_V_m3" in branch:
            sx, sy = fx(branch["snap_V_m3"]), fy(branch["snap_p_Pa"])
            if branch.get("axisym_landing"):  # the area under the axisymmetric path to the landing state
                ax_, ay_ = _axisym_snap_area(curve, branch)
                sx, sy = fx(ax_), fy(ay_)
            ax.fill(np.r_[sx, sx[:1]], np.r_[sy, sy[:1]], color="tab:orange", alpha=0.35,
                    label=f"dE = {metrics['dE_J'] * 1e3:.4g} mJ (the followed snap, reported)")
            ax.plot([sx[0], sx[-1]], [sy[0], sy[-1]], "--", color="tab:red", lw=1.3, label="snap at fixed volume")
            ax.plot(sx[0], sy[0], "o", mfc="k", mec="k", ms=7, label="volume limit V*")
            ax.plot(sx[-1], sy[-1], "o", mfc="w", mec="k", ms=7, label="lower state")
    if imperfect is not None:
        ix, iy = fx(imperfect["V_m3"]), fy(imperfect["p_Pa"])
        ax.plot(ix, iy, "--", color="tab:purple", lw=1.3,
                label=f"imperfect actuator (n = {imperfect['n']}, amplitude {imperfect['delta']:g} t_i)")
        if "snap_V_m3" in imperfect and metrics.get("imp_dE_J") is not None:
            sx, sy = fx(imperfect["snap_V_m3"]), fy(imperfect["snap_p_Pa"])
            ax.fill(np.r_[sx, sx[:1]], np.r_[sy, sy[:1]], color="tab:purple", alpha=0.25,
                    label=f"imperfect dE = {metrics['imp_dE_J'] * 1e3:.4g} mJ")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    fig.legend(loc="outside lower center", ncols=2, fontsize=7.5, frameon=False)
    try:
        return _save(fig, path, 120)
    finally:
        plt.close(fig)


def _axisym_snap_area(curve: dict, branch: dict) -> tuple[np.ndarray, np.ndarray]:
    """The boundary of a followed snap that lands on the axisymmetric path's state (SI): the
    bifurcation, the axisymmetric path from there through its fold to its crossing of the
    bifurcation's volume nearest the lower state's pressure, the lower state."""
    V, P = np.asarray(curve["V_m3"]), np.asarray(curve["p_Pa"])
    V_b, p_up, p_lo = branch["snap_V_m3"][0], branch["snap_p_Pa"][0], branch["snap_p_Pa"][-1]
    cross = np.nonzero((V[:-1] - V_b) * (V[1:] - V_b) <= 0.0)[0]
    if len(cross) < 2:
        return np.array([V_b, V_b]), np.array([p_up, p_lo])
    w = (V_b - V[cross]) / np.where(V[cross + 1] != V[cross], V[cross + 1] - V[cross], 1.0)
    p_x = P[cross] + w * (P[cross + 1] - P[cross])
    i1 = cross[1:][int(np.argmin(np.abs(p_x[1:] - p_lo)))]
    i0 = cross[0]
    return np.r_[V_b, V[i0 + 1:i1 + 1], V_b], np.r_[p_up, P[i0 + 1:i1 + 1], p_lo]


def _branch_marks(ax, branch: dict, fx, fy) -> None:
    """The bifurcation, a secondary bifurcation and the landing of a fold's jump on a followed branch."""
    bx, by = fx(branch["V_m3"]), fy(branch["p_Pa"])
    ax.plot(bx[:1], by[:1], "D", mfc="tab:orange", mec="k", ms=6, label="bifurcation")
    if branch.get("V_sec_m3") is not None:  # where the followed branch left the first one
        k = int(np.argmin(np.abs(np.asarray(branch["V_m3"]) - branch["V_sec_m3"])))
        ax.plot(bx[k], by[k], "v", mfc="tab:red", mec="k", ms=7, label=f"secondary bifurcation (n = {branch['n_sec']})")
    if branch.get("landing_V_m3") is not None:  # a jump past the branch's fold onto an unstable state
        ax.plot(fx(branch["landing_V_m3"]), fy(branch["landing_p_Pa"]), "x", color="tab:red", ms=8, mew=2,
                label=f"the fold's jump lands here: unstable in n = {branch['n_sec']}")


def _branch_what(branch: dict) -> str:
    if branch.get("n_sec") is not None and branch.get("landing_V_m3") is not None:  # a jump off it
        return f"n = {branch['n']} ({branch.get('parent_kind') or '?'}) to its fold, then a jump, N = {branch['N']}"
    if branch.get("n_sec") is not None:  # the first branch, then the one leaving it
        return (f"n = {branch['n']} ({branch.get('parent_kind') or '?'}), then n = {branch['n_sec']} "
                f"({branch['kind'] or 'no snap'}), N = {branch['N']}")
    return f"n = {branch['n']}, {branch['kind'] or 'no snap'}, N = {branch['N']}"


def plot_air_curves(curve: dict, metrics: dict, path: str | Path, title: str = "") -> Path:
    """The snap under air beside the snap under water (paper Fig. S9), pressure [kPa] in both panels.

    Left, against the volume the syringe has dispensed (for water, the cavity's volume change): the
    air path (the equilibrium path with the gas's volume change added) and the water path, each
    with its snap (a drop at constant dispensed volume) and its energy shaded. Right, against the
    actuator's volume change: the one equilibrium path of both fluids, the water snap (at constant
    volume) and the air snap (at constant dispensed volume: the actuator grows as the gas expands,
    eq 9).
    """
    from snapjump_cli.fe.axisym.fluid import GasLaw

    plt = _pyplot()
    V0 = curve["V0_m3"]
    ml = 1e6
    p = np.asarray(curve["p_Pa"]) / 1e3
    dV = (np.asarray(curve["V_m3"]) - V0) * ml
    Vd = np.asarray(curve["V_disp_m3"]) * ml
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11.0, 4.4))
    air_label = (f"air, V0_sys = {metrics['air_V0_m3'] * ml:.4g} ml, gamma = {metrics['air_gamma']:g}")
    a1.plot(dV, p, "-", color="tab:blue", lw=1.3, label="water")
    a1.plot(Vd, p, "-", color="tab:red", lw=1.3, label=air_label)
    a2.plot(dV, p, "-", color="k", lw=1.3, label="equilibrium path (both fluids)")
    if "snap_V_m3" in curve and metrics.get("water_dE_J"):
        sx, sy = (np.asarray(curve["snap_V_m3"]) - V0) * ml, np.asarray(curve["snap_p_Pa"]) / 1e3
        a1.fill(np.r_[sx, sx[:1]], np.r_[sy, sy[:1]], color="tab:blue", alpha=0.2,
                label=f"water dE = {metrics['water_dE_J'] * 1e3:.4g} mJ")
        for ax in (a1, a2):
            ax.plot([sx[0], sx[-1]], [sy[0], sy[-1]], ":", color="tab:blue", lw=1.5)
        a2.plot([], [], ":", color="tab:blue", label="water snap (constant volume)")
    if "air_snap_Vd_m3" in curve and metrics.get("snaps"):
        sx, sy = np.asarray(curve["air_snap_Vd_m3"]) * ml, np.asarray(curve["air_snap_p_Pa"]) / 1e3
        a1.fill(np.r_[sx, sx[:1]], np.r_[sy, sy[:1]], color="tab:red", alpha=0.2,
                label=f"air dE = {metrics['dE_J'] * 1e3:.4g} mJ")
        a1.plot([sx[0], sx[-1]], [sy[0], sy[-1]], "--", color="tab:red", lw=1.5)
        gas = GasLaw(metrics["air_V0_m3"], metrics["air_p0_Pa"], metrics["air_gamma"])
        pp = np.linspace(metrics["p_before_Pa"], metrics["p_after_Pa"], 50)
        V_up = np.asarray(curve["air_snap_V_m3"])[0] - V0
        a2.plot((V_up + gas.expelled(pp[0]) - gas.expelled(pp)) * ml, pp / 1e3, "--", color="tab:red", lw=1.5,
                label=f"air snap (constant dispensed volume): +{metrics['dV_snap_m3'] * ml:.3g} ml")
    a1.set_xlabel("dispensed volume [ml] (water: cavity volume change)")
    a2.set_xlabel("actuator volume change [ml]")
    for ax in (a1, a2):
        ax.set_ylabel("pressure (gauge) [kPa]")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    try:
        return _save(fig, path, 120)
    finally:
        plt.close(fig)
