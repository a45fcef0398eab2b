"""Compare two full sweeps of the same grid row by row, and the time per design of the newer one.

    .venv/bin/python -m bench.grid_compare OLD.parquet NEW.parquet

Prints how many rows changed status, each flag (``self_crossing``, ``lower_state_method``,
``snaps``, ``mesh_sensitive``) on the rows ok in both, the largest relative change of dE,
dy_pole, h_imp, V*, p* and p_max (and how many rows moved by more than 0.5 % and 1e-4), the
harmonic check's answers when both runs have them (``asym_first``, ``asym_n``,
``asym_lower_stable`` exactly; ``asym_V_m3``, ``asym_p_Pa`` by their largest relative change), and
the CPU time per valid design of both runs. Rows are matched by their key, or by the grid index
(same design parameters) when the two runs' keys differ (key version v1 before 23 November 2026) (the ``wall_s`` of each row: mean, p50, p90, max, the
designs over 3 s, the split by the way the lower state was found). This is the full-grid answer
check of the speed work (docs/performance.md, "Full paper-grid runs").
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _changed(a, b):
    """Rows where two columns differ; missing in both counts as equal (a nullable integer column's
    missing values are NaN as strings, and NaN differs from itself)."""
    import pandas as pd

    am, bm = a.isna().to_numpy(), b.isna().to_numpy()
    differ = a.astype(str).to_numpy() != b.astype(str).to_numpy()
    return pd.Series((am != bm) | (~am & ~bm & differ), index=a.index)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old", type=Path)
    ap.add_argument("new", type=Path)
    a = ap.parse_args(argv)
    sys.path.insert(0, str(REPO))
    from snapjump_cli.sweep.results import read_results

    old, new = read_results(a.old), read_results(a.new)
    # the row key changed with the key version (v1 -> v2, the settings' ds0); the grid's index does not
    by = "key" if len(set(old["key"]) & set(new["key"])) else "index"
    old, new = old.set_index(by), new.set_index(by)
    common = old.index.intersection(new.index)
    if by == "index":  # the same grid: each index must name the same design in both
        geo = ["eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio"]
        same = (old.loc[common, geo].astype(float) == new.loc[common, geo].astype(float)).all(axis=1)
        common = common[same.to_numpy()]
    print(f"rows: {len(old)} old, {len(new)} new, {len(common)} in both (matched by {by})")
    old, new = old.loc[common], new.loc[common]
    print(f"status changed: {int((old['status'] != new['status']).sum())}")
    ok = (old["status"] == "ok") & (new["status"] == "ok")
    for f in ("self_crossing", "lower_state_method", "snaps", "mesh_sensitive"):
        changed = _changed(old.loc[ok, f], new.loc[ok, f])
        print(f"{f} changed on {int(changed.sum())} of {int(ok.sum())} rows ok in both"
              + (f": {list(changed[changed].index[:5])}" if changed.any() else ""))
    for f in ("dE_J", "dy_pole_m", "h_imp_m", "V_star_m3", "p_star_Pa", "p_max_Pa"):
        rel = ((new.loc[ok, f] - old.loc[ok, f]).abs() / old.loc[ok, f].abs()).astype(float)
        print(f"{f}: largest relative change {rel.max():.2e}; rows over 0.5 %: {int((rel > 0.005).sum())}, "
              f"over 1e-4: {int((rel > 1e-4).sum())}")
    if "asym_first" in old and "asym_first" in new:
        for f in ("asym_first", "asym_n", "asym_lower_stable"):
            changed = _changed(old.loc[ok, f], new.loc[ok, f])
            print(f"{f} changed on {int(changed.sum())} of {int(ok.sum())} rows ok in both"
                  + (f": {list(changed[changed].index[:5])}" if changed.any() else ""))
        for f in ("asym_V_m3", "asym_p_Pa"):
            a, b = old.loc[ok, f].astype(float), new.loc[ok, f].astype(float)
            both = a.notna() & b.notna()
            rel = ((b[both] - a[both]).abs() / a[both].abs())
            print(f"{f}: set on {int(both.sum())} rows in both, on one only {int((a.notna() != b.notna()).sum())}; "
                  f"largest relative change {rel.max() if len(rel) else 0.0:.2e}")
    for label, df in (("old", old), ("new", new)):
        v = df[df["status"] == "ok"]
        w = v["wall_s"].astype(float)
        line = (f"{label}: wall per valid design (its wall_s) mean {w.mean():.3f} s, p50 {w.median():.3f}, p90 {w.quantile(0.9):.3f}, "
                f"max {w.max():.2f}; {int((w > 3).sum())} over 3 s; sum {w.sum():.0f} s")
        for meth, g in v.groupby(v["lower_state_method"].astype(str)):
            gw = g["wall_s"].astype(float)
            line += f"; {meth} {len(g)}: mean {gw.mean():.3f} s, max {gw.max():.2f}, {gw.sum() / w.sum():.0%}"
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
