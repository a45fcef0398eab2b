"""The plots of ``snapjump optimize``: progress (objective per evaluation) and the chosen
design's path through the box; PNG files written atomically."""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from snapjump_cli.optimize.evaluate import objective_values
from snapjump_cli.optimize.spec import PARAMETERS

if TYPE_CHECKING:
    from snapjump_cli.optimize.run import OptimizeResult


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _save_atomic(fig: Any, path: Path) -> Path:
    """Write ``fig`` as a PNG atomically, with the mode the umask gives (as every output)."""
    from snapjump_cli.files import write_atomic

    return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=150, format="png"))


_STAGE_COLOURS = {"start": "#1f77b4", "init": "#17becf", "poll": "#7f7f7f", "pattern": "#ff7f0e", "cross": "#bcbd22",
                  "model": "#e377c2",
                  "de": "#9467bd"}


def _scale(objective: str) -> tuple[float, str]:
    return (1e3, "y_jump [mm]") if objective == "y_jump_m" else (1e3, "dE [mJ]")


def plot_progress(result: OptimizeResult, path: str | Path) -> Path:
    """The objective of every evaluation against its number (infeasible ones at the bottom), the
    running best, the baseline and the confirmed value. Writes a PNG atomically."""
    from matplotlib.ticker import MaxNLocator

    plt = _pyplot()
    objective = result.spec.objective
    sc, label = _scale(objective)
    t = result.table
    t = t[t["stage"] != "confirm"].reset_index(drop=True)
    scored = objective_values(t, objective, result.spec.jump) if len(t) else t.assign(_f=[])
    f = scored["_f"].to_numpy(dtype=float) * sc
    valid = (t["status"] != "invalid_geometry").to_numpy(dtype=bool)
    n = np.arange(len(t))
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    try:
        stages = t["stage"].astype(str).to_numpy()
        for st, colour in _STAGE_COLOURS.items():
            m = (stages == st) & np.isfinite(f)
            if m.any():
                big = st in ("model", "start")
                ax.scatter(n[m], f[m], s=40 if big else 10, marker="*" if st == "model" else "o", color=colour,
                           label=st, alpha=0.9 if big else 0.7, zorder=3 if big else 2)
        bad = valid & ~np.isfinite(f)
        fin = f[np.isfinite(f)]
        floor = (np.nanmin(fin) if fin.size else 0.0)
        if bad.any():
            ax.scatter(n[bad], np.full(bad.sum(), floor), marker="x", s=14, color="#d62728",
                       label="no snap / failed / mesh-sensitive")
        if fin.size:
            run = np.fmax.accumulate(np.where(np.isfinite(f), f, -np.inf))
            run[~np.isfinite(run)] = np.nan
            ax.step(n, run, where="post", color="k", lw=1.2, label="best so far")
        if objective == "y_jump_m" and math.isfinite(result.baseline_y_jump_m):
            ax.axhline(result.baseline_y_jump_m * sc, color="#2ca02c", ls="--", lw=1, label="baseline")
        if objective == "y_jump_m" and math.isfinite(result.y_jump_confirmed_m):
            ax.axhline(result.y_jump_confirmed_m * sc, color="#7b3294", ls=":", lw=1.2, label="confirmed (finer mesh)")
        if fin.size:
            top = np.nanmax(fin)
            ax.set_ylim(max(floor, top - 0.5 * abs(top)) - 0.02 * abs(top), top + 0.05 * abs(top))
        ax.set_xlabel("evaluation number (every design asked, invalid geometries included)")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))  # evaluations are counted: no 1.975
        ax.set_ylabel(label)
        ax.set_title(f"snapjump optimize ({result.spec.method}, seed {result.spec.seed}): "
                     f"{result.n_evaluations} solves")
        ax.legend(loc="lower right", fontsize=7)
        return _save_atomic(fig, Path(path))
    finally:
        plt.close(fig)


def plot_path(result: OptimizeResult, path: str | Path) -> Path:
    """The chosen design's path through parameter space: each free parameter of its successive
    incumbents against the evaluation number, within the box. Writes a PNG atomically."""
    from matplotlib.ticker import MaxNLocator

    plt = _pyplot()
    free = [p for p in PARAMETERS if result.spec.bounds[p][0] < result.spec.bounds[p][1]]
    steps = result.path
    sc, label = _scale(result.spec.objective)
    n = len(free) + 1
    fig, axes = plt.subplots(n, 1, figsize=(6, 1.5 * n + 0.6), sharex=True, constrained_layout=True)
    axes = np.atleast_1d(axes)
    try:
        x = [s["evaluation"] for s in steps]
        for ax, p in zip(axes, free):
            lo, hi = result.spec.bounds[p]
            v = [s[p] for s in steps]
            ax.plot(x, v, "o-", ms=3, color="#1f77b4")
            ax.axhline(lo, color="0.6", ls="--", lw=0.8)
            ax.axhline(hi, color="0.6", ls="--", lw=0.8)
            if result.baseline_design is not None:
                ax.axhline(dict(zip(PARAMETERS, result.baseline_design))[p], color="#2ca02c", ls=":", lw=0.8)
            ax.set_ylabel(f"{p}\n[{lo:g}, {hi:g}]", fontsize=8)
            # zoom on the path (at least a quarter of the box), never beyond the box
            half = max(0.125 * (hi - lo), 0.6 * (max(v) - min(v)) if v else 0.0)
            mid = 0.5 * (max(v) + min(v)) if v else 0.5 * (lo + hi)
            pad = 0.03 * (hi - lo)
            ax.set_ylim(max(lo - pad, mid - half), min(hi + pad, mid + half))
        axes[-1].plot(x, [s["objective"] * sc for s in steps], "o-", ms=3, color="k")
        axes[-1].set_ylabel(label, fontsize=8)
        axes[-1].set_xlabel("evaluation number")
        axes[-1].xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))
        fixed = ", ".join(f"{p} = {result.spec.bounds[p][0]:g}" for p in PARAMETERS if p not in free)
        axes[0].set_title("path of the chosen design (box: dashed, baseline: dotted)" + (f"\nfixed: {fixed}" if fixed else ""),
                          fontsize=9)
        return _save_atomic(fig, Path(path))
    finally:
        plt.close(fig)


def plot_files(output: str | Path) -> tuple[Path, Path]:
    """The plots written next to ``output``: ``<stem>.progress.png`` and ``<stem>.path.png``."""
    output = Path(output)
    stem = output.name.removesuffix(".parquet")
    return output.with_name(stem + ".progress.png"), output.with_name(stem + ".path.png")


def make_plots(result: OptimizeResult, output: str | Path, batch: Any = None) -> list[Path]:
    """Both plots next to ``output``: ``<stem>.progress.png`` and ``<stem>.path.png``; with ``batch``
    (a :class:`snapjump_cli.files.AtomicFiles`) added to it, written with the result, all or none."""
    progress, path = plot_files(output)
    todo = [(plot_progress, progress)] + ([(plot_path, path)] if result.path else [])
    if batch is None:
        return [fn(result, p) for fn, p in todo]
    return [batch.add(p, lambda tmp, fn=fn: fn(result, tmp)) for fn, p in todo]
