"""Where a followed grid's time went, by class and by how each row's mesh was checked.

    .venv/bin/python -m bench.followed_grid_time results/paper_grid_followed.parquet

For the followed rows of a followed sweep (``followed`` true) grouped by the harmonic followed,
``mu_i/mu_o`` and the mesh check (``re-solved``: the snap was re-solved one mesh finer and the
branch followed there, as followed solves did before they skipped that re-solve; ``not
re-checked``: a suspicious snap of a design that goes asymmetric first; ``-``: not suspicious),
prints count, median, mean, p90 and max of the rows' ``wall_s`` and each group's share of the
followed rows' time. Then the same per class without the ``re-solved`` rows (what the current
settings cost), the design wall summed at those class means over all the grid's rows (the
other rows at their own ``wall_s``) and, per followed harmonic, the share of valid designs and
mean wall (the class means weighted by the followed rows of each ``mu_i/mu_o``) that
``snapjump_cli.sweep.run.REF_FOLLOW`` takes (docs/performance.md).
"""
from __future__ import annotations

import argparse
import sys

import numpy as np
import pandas as pd


def mesh_kind(mesh_check: pd.Series) -> pd.Series:
    """``re-solved``, ``not re-checked`` or ``-`` from the rows' ``mesh_check``."""
    mc = mesh_check.fillna("")
    return pd.Series(np.where(mc.str.contains("not re-checked"), "not re-checked",
                              np.where(mc.str.contains("re-solved"), "re-solved", "-")), index=mc.index)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", help="a followed sweep's parquet file")
    a = ap.parse_args(argv)
    d = pd.read_parquet(a.results)
    d["mesh"] = mesh_kind(d["mesh_check"])
    f = d[d["followed"] == True]  # noqa: E712 (a nullable boolean column)
    if f.empty:
        print(f"{a.results}: no followed rows", file=sys.stderr)
        return 2
    keys = ["follow_n", "mu_ratio"]
    stats = ["count", "median", "mean", lambda s: s.quantile(0.9), "max"]
    by = f.groupby(keys + ["mesh"])["wall_s"].agg(stats)
    by.columns = ["count", "median", "mean", "p90", "max"]
    by["share"] = f.groupby(keys + ["mesh"])["wall_s"].sum() / f["wall_s"].sum()
    print(f"{len(d)} rows, {int((d['status'] == 'ok').sum())} ok, {len(f)} followed; "
          f"design wall {d['wall_s'].sum():,.0f} s ({f['wall_s'].sum():,.0f} s in the followed rows)")
    print(by.round(3).to_string())
    cur = f[f["mesh"] != "re-solved"]
    now = cur.groupby(keys)["wall_s"].agg(stats)
    now.columns = ["count", "median", "mean", "p90", "max"]
    print("\nwithout the re-solved rows:")
    print(now.round(2).to_string())
    counts = f.groupby(keys).size()
    total = float((now["mean"] * counts).sum()) + float(d.loc[d["followed"] != True, "wall_s"].sum())  # noqa: E712
    print(f"\ndesign wall at those class means: {total:,.0f} s, {total / 2 / 3600:.2f} h on 2 workers")
    n_ok = int((d["status"] == "ok").sum())
    for n, g in f.groupby("follow_n"):  # the class means weighted by the followed rows of each mu_i/mu_o
        mean = float((now["mean"] * counts).loc[n].sum()) / len(g)
        print(f"REF_FOLLOW[{n}]: share {len(g)} / {n_ok}, mean wall {mean:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
