"""Fig. 4A/4C of the paper grid with the followed answers of the designs whose branch was followed.

    .venv/bin/python -m bench.followed_fig4 results/paper_grid.parquet \\
        results/follow_strata.parquet.parts@n=1 results/follow_strata_n2.parquet.parts [--plots DIR]

The grid (a sweep with the harmonic check, ``solver: {harmonics: 4}``) gives every design's
axisymmetric answer and whether it goes asymmetric first; each further file (a sweep with
``solver: {harmonics: 4, follow: true}``, or the ``.parts`` folder of one still running) gives the
followed answer of some of those designs. A grid row is replaced by the followed row of the same
design (the five design parameters match) when that row is ``ok`` and ``followed``; the others keep
their axisymmetric answer. The table is ranked by the jump model as ``snapjump rank`` ranks it and
the report gives, for the followed designs, followed / axisymmetric of dE, dy_pole, V* and the jump
(median and range, overall and by the critical harmonic), how many lift off (the inner pole rises
above where it started) with the followed answers and with their axisymmetric ones, and whether
the top 20 changes. ``--plots DIR`` draws ``fig4a.png``, ``fig4c.png`` and ``jump_vs_parameters.png`` of
the merged table (a followed design: a diamond at its followed answer, joined by a line to its
axisymmetric answer).

Until the whole grid is followed (``make run-followed``) the figures show the grid with the
followed sample merged in: the designs not followed are drawn at their axisymmetric answer,
triangles where it does not happen.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd

PARAMS = ["eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio"]


def read_followed(spec: str) -> pd.DataFrame:
    """A followed table given as ``PATH`` or ``PATH@n=K`` (only its rows whose critical harmonic
    ``follow_n`` is ``K``: e.g. the ``n = 1`` rows of a sample whose ``n = 2`` rows a later run
    replaces)."""
    path, _, cond = spec.partition("@")
    key, _, value = cond.partition("=")
    if cond and (key != "n" or not value.isdigit()):
        raise SystemExit(f"{spec}: the filter must be @n=K (an integer K), got @{cond}")
    df = read_any(Path(path))
    return df[df["follow_n"].astype("float64") == float(value)] if cond else df


def read_any(path: Path) -> pd.DataFrame:
    """A result table, or the part files of an unfinished sweep (a ``.parts`` folder) concatenated."""
    from snapjump_cli.sweep.results import read_results

    if path.is_dir():
        parts = sorted(path.glob("part-*.parquet"))
        if not parts:
            raise SystemExit(f"{path}: no part-*.parquet files")
        return pd.concat([read_results(p) for p in parts], ignore_index=True)
    return read_results(path)


def keys(df: pd.DataFrame) -> pd.Series:
    """The five design parameters of each row as one string (rows of two runs of one grid match)."""
    return df[PARAMS].astype("float64").round(4).astype(str).agg(",".join, axis=1)


def merge(grid: pd.DataFrame, followed: list[pd.DataFrame]) -> tuple[pd.DataFrame, int, int]:
    """The grid with each design that has an ``ok`` followed row replaced by it; returns the table,
    the number of rows replaced and the number of followed-sweep rows not in the grid."""
    out = grid.copy().reset_index(drop=True)
    for c in ("followed", "follow_n", "follow_kind", "follow_note") + tuple(
            "axisym_" + k for k in ("dE_J", "dy_pole_m", "h_imp_m", "V_star_m3", "p_star_Pa")):
        if c not in out.columns:
            out[c] = pd.NA
    k = keys(out)
    pos = dict(zip(k, range(len(out))))
    from snapjump_cli.fe.branch.trace import MICRO_FOLD_DE

    replaced, missing = 0, 0
    for f in followed:
        f = f[(f["status"] == "ok") & f["followed"].astype("boolean").fillna(False)]
        # rows written before follow.followed_metrics refused a near-zero followed snap: refuse it here too
        f = f[~(f["dE_J"].astype("float64") < MICRO_FOLD_DE * f["axisym_dE_J"].astype("float64"))]
        for key, (_, row) in zip(keys(f), f.iterrows()):
            i = pos.get(key)
            if i is None:
                missing += 1
                continue
            for c in out.columns:
                if c in row.index:
                    out.at[i, c] = row[c]
            replaced += 1
    return out, replaced, missing


def _ratio_line(name: str, r: np.ndarray) -> str:
    r = r[np.isfinite(r)]
    if not r.size:
        return f"| {name} | - | - |"
    return f"| {name} | {np.median(r):.2f} | {r.min():.2f} - {r.max():.2f} |"


def report(ranked: pd.DataFrame, top: int = 20, axisym: pd.DataFrame | None = None) -> list[str]:
    """Followed / axisymmetric ratios of the followed rows of a ranked merged table, and the top.
    ``axisym``: the grid ranked with its axisymmetric answers; each "lift off" line then also
    counts the same designs' lift-offs with those answers (``jumped``: the inner pole rises above
    where it started)."""
    fol = ranked[ranked["followed"].astype("boolean").fillna(False).to_numpy(bool)]
    axi_jumped = None
    if axisym is not None and "jumped" in axisym.columns:
        axi_jumped = set(keys(axisym[axisym["jumped"].astype("boolean").fillna(False).to_numpy(bool)]))
    f = lambda c: fol[c].astype("float64").to_numpy()  # noqa: E731
    out = [f"followed designs: {len(fol)}"]
    groups = ([("all", fol)] + [(f"n = {int(n)}", g) for n, g in fol.groupby(fol["follow_n"].astype("float64"))]
              + [(f"mu_i/mu_o = {mu:g}", g) for mu, g in fol.groupby(fol["mu_ratio"].astype("float64"))])
    for lab, g in groups:
        gg = lambda c: g[c].astype("float64").to_numpy()  # noqa: E731
        out.append(f"\n{lab} ({len(g)} designs), followed / axisymmetric:\n\n| | median | range |\n|---|---|---|")
        out.append(_ratio_line("dE", gg("dE_J") / gg("axisym_dE_J")))
        out.append(_ratio_line("dy_pole", gg("dy_pole_m") / gg("axisym_dy_pole_m")))
        out.append(_ratio_line("V*", gg("V_star_m3") / gg("axisym_V_star_m3")))
        out.append(_ratio_line("jump", gg("y_jump_m") / gg("y_jump_axisym_m")))
        if "jumped" in g.columns:
            line = f"lift off: {int(g['jumped'].astype('boolean').fillna(False).sum())} of {len(g)}"
            if axi_jumped is not None:
                line += f" (with their axisymmetric answers: {sum(k in axi_jumped for k in keys(g))})"
            out.append(line)
    if len(fol):
        yj = f("y_jump_m")
        out.append(f"\nhighest followed jump: {np.nanmax(yj) * 1e3:.0f} mm "
                   f"(its axisymmetric answer: {f('y_jump_axisym_m')[np.nanargmax(yj)] * 1e3:.0f} mm)")
    ok = ranked[ranked["status"] == "ok"]
    top_now = set(keys(ok.head(top)))
    by_axi = ok.assign(_y=ok["y_jump_axisym_m"].astype("float64")).sort_values("_y", ascending=False)
    top_axi = set(keys(by_axi.head(top)))
    out.append(f"top {top}: {len(top_now & top_axi)} of {top} the same as with the axisymmetric answers; "
               f"followed designs in it: {int(ok.head(top)['followed'].astype('boolean').fillna(False).sum())}")
    return out


def sample_report(grid: pd.DataFrame, followed: list[pd.DataFrame]) -> list[str]:
    """The followed samples themselves, by critical harmonic and ``mu_i/mu_o``: designs, followed
    (through a secondary bifurcation), at the time limit, followed / axisymmetric medians (ranges)
    and the median wall time of a followed design; then the whole grid's followed run at the
    samples' mean wall time per design of each harmonic (the grid's axisymmetric ``wall_s`` added)."""
    rows = pd.concat(followed, ignore_index=True)
    rows = rows[rows["status"] == "ok"]
    out = ["\nthe followed samples (wall times as they ran, on the machine they ran on):",
           "| n | mu_i/mu_o | designs | followed (secondary) | time limit | dE | dy_pole | V* | wall, followed "
           "| following / the grid's solve: median (p90) |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    # the following's wall time over the same design's axisymmetric solve and check in the grid
    grid_wall = pd.Series(grid["wall_s"].astype("float64").to_numpy(), index=keys(grid).to_numpy())
    axi = keys(rows).map(grid_wall).astype("float64").to_numpy()
    rows = rows.assign(_cost=(rows["wall_s"].astype("float64").to_numpy() - axi) / axi)

    def med(r: np.ndarray) -> str:
        r = r[np.isfinite(r)]
        return f"{np.median(r):.2f} ({r.min():.2f}-{r.max():.2f})" if r.size else "-"

    def cost(c: pd.Series) -> str:
        c = c.to_numpy(float)
        c = c[np.isfinite(c)]
        return f"{np.median(c):.0f}x ({np.quantile(c, 0.9):.0f}x)" if c.size else "-"

    for (n, mu), g in rows.groupby([rows["follow_n"].astype("float64"), rows["mu_ratio"].astype("float64")]):
        fol = g[g["followed"].astype("boolean").fillna(False).to_numpy(bool)]
        v = lambda c: fol[c].astype("float64").to_numpy()  # noqa: E731
        sec = int(fol["follow_sec_n"].notna().sum()) if "follow_sec_n" in fol else 0
        limit = int(g["follow_note"].fillna("").str.contains("time limit").sum())
        wall = f"{fol['wall_s'].astype('float64').median():.0f} s" if len(fol) else "-"
        out.append(f"| {int(n)} | {mu:g} | {len(g)} | {len(fol)} ({sec}) | {limit} | {med(v('dE_J') / v('axisym_dE_J'))} "
                   f"| {med(v('dy_pole_m') / v('axisym_dy_pole_m'))} | {med(v('V_star_m3') / v('axisym_V_star_m3'))} "
                   f"| {wall} | {cost(g['_cost'])} |")
    asym = rows[rows["follow_n"].notna().to_numpy(bool)]
    out.append(f"| all | | {len(asym)} | | | | | | | {cost(asym['_cost'])} |")
    ok = grid[grid["status"] == "ok"]
    first = ok[ok["asym_first"].astype("boolean").fillna(False).to_numpy(bool)]
    counts = first["asym_n"].astype("float64").value_counts()
    mean_wall = rows.groupby(rows["follow_n"].astype("float64"))["wall_s"].mean()
    total = float(ok["wall_s"].astype("float64").sum())
    parts = []
    for n, c in counts.items():
        if n in mean_wall.index:
            total += c * float(mean_wall[n])
            parts.append(f"{int(c)} x {mean_wall[n]:.0f} s (n = {int(n)})")
        else:
            parts.append(f"{int(c)} designs of n = {int(n)} not sampled (not counted)")
    out.append(f"the grid's followed run at the samples' cost: {'; '.join(parts)}, plus the axisymmetric "
               f"solves: {total:,.0f} s, {total / 2 / 3600:.0f} h on 2 cores")
    return out


def followed_or_not(followed: list[pd.DataFrame]) -> list[str]:
    """Of the followed sweeps' ``ok`` rows that go asymmetric first: how many follow another
    harmonic than the check's (another bifurcates first) and how many of those are followed; and
    each design not followed, by its index, with the last part of its note (why)."""
    rows = pd.concat(followed, ignore_index=True)
    rows = rows[(rows["status"] == "ok") & rows["asym_first"].astype("boolean").fillna(False).to_numpy(bool)]
    fol = rows["followed"].astype("boolean").fillna(False).to_numpy(bool)
    other = (rows["follow_n"].astype("float64") != rows["asym_n"].astype("float64")).to_numpy(bool) \
        & rows["follow_n"].notna().to_numpy(bool)
    out = [f"\nasymmetric first: {len(rows)}, followed {int(fol.sum())}; another harmonic than the check's "
           f"followed (it bifurcates first): {int(other.sum())}, {int((other & fol).sum())} of them followed"]
    for _, r in rows[~fol].iterrows():
        out.append(f"not followed: index {r.get('index')}: {str(r.get('follow_note') or '').split('; ')[-1]}")
    return out


def main(argv: Iterable[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.followed_fig4", description=__doc__.split("\n\n")[0])
    ap.add_argument("grid", type=Path, help="the grid's result table (with the harmonic check)")
    ap.add_argument("followed", nargs="+",
                    help="result tables (or .parts folders) with followed rows; PATH@n=K keeps only the rows "
                         "whose critical harmonic is K")
    ap.add_argument("--plots", type=Path, default=None, metavar="DIR", help="write the figures into DIR")
    ap.add_argument("--top", type=int, default=20)
    a = ap.parse_args(None if argv is None else list(argv))
    from snapjump_cli.jump.rank import rank_results

    grid = read_any(a.grid)
    tables = [read_followed(p) for p in a.followed]
    merged, n, missing = merge(grid, tables)
    print(f"{len(grid)} grid rows; {n} replaced by their followed answer"
          + (f"; {missing} followed rows are not designs of the grid (ignored)" if missing else ""))
    ranked = rank_results(merged)
    print("\n".join(report(ranked, a.top, axisym=rank_results(grid))))
    print("\n".join(sample_report(grid, tables)))
    print("\n".join(followed_or_not(tables)))
    if a.plots is not None:
        from snapjump_cli.viz.figures import make_plots

        for p in make_plots(ranked, a.plots):
            print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
