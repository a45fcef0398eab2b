"""The figures of docs/harmonics.md section 9 from a sweep run with the harmonic check.

    .venv/bin/python scripts/harmonics_counts.py results/paper_grid_h4.parquet [--top 20]
        [--crossing results/paper_grid.parquet]

Prints: the designs by status; among the valid ones, how many lose stability to a harmonic before
V* and by which n (overall and by stiffness ratio); where (``asym_V_m3 / V_star_m3`` and
``asym_p_Pa / p_max_Pa``); the lower state's stability; the confusion table against the
self-crossing flag; dE of the two groups; and the ranking's top ``--top`` with and without
``--exclude-asymmetric`` (jump model defaults), with the best design that stays axisymmetric.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))


def _key(df: pd.DataFrame) -> pd.Series:
    return df[["eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio"]].round(4).astype(str).agg(",".join, axis=1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("--top", type=int, default=20)
    ap.add_argument("--crossing", type=Path, metavar="RESULTS",
                    help="take self_crossing from this result file of the same designs (e.g. a run of the "
                         "current code when the checked run mixes code versions)")
    a = ap.parse_args(argv)
    from snapjump_cli.jump.rank import rank_results, top_table
    from snapjump_cli.sweep.results import read_results

    df = read_results(a.results)
    if a.crossing is not None:
        other = read_results(a.crossing)
        sc_map = dict(zip(_key(other), other["self_crossing"]))
        keys = _key(df)
        missing = int((~keys.isin(sc_map.keys())).sum())
        if missing:
            print(f"warning: {missing} designs not in {a.crossing}")
        new = keys.map(sc_map).astype("boolean").fillna(df["self_crossing"].astype("boolean"))
        ok = (df["status"] == "ok").to_numpy()
        changed = int((new.fillna(False).to_numpy(bool) != df["self_crossing"].astype("boolean").fillna(False)
                       .to_numpy(bool))[ok].sum())
        df["self_crossing"] = new
        print(f"self_crossing taken from {a.crossing} ({changed} ok rows differ from the checked run's own)")
    print(f"{len(df)} rows: " + ", ".join(f"{k} {v}" for k, v in df["status"].value_counts().items()))
    ok = df[df["status"] == "ok"].copy()
    if ok["asym_first"].isna().any():
        print(f"warning: {int(ok['asym_first'].isna().sum())} ok rows without the harmonic check")
    asym = ok["asym_first"].astype("boolean").fillna(False).to_numpy(bool)
    sc = ok["self_crossing"].astype("boolean").fillna(False).to_numpy(bool)
    n = len(ok)
    print(f"\nvalid (ok): {n}; a harmonic unstable before V*: {asym.sum()} ({asym.mean():.1%}), stable up to V*: {(~asym).sum()}")
    print("first harmonic:", ok.loc[asym, "asym_n"].value_counts().sort_index().to_dict())
    for mr, g in ok.groupby("mu_ratio"):
        ga = g["asym_first"].astype("boolean").fillna(False)
        print(f"  mu ratio {mr:g}: {int(ga.sum())} of {len(g)} asymmetric first; by n "
              f"{g.loc[ga.to_numpy(bool), 'asym_n'].value_counts().sort_index().to_dict()}")
    fa = ok.loc[asym]
    rv = (fa["asym_V_m3"] / fa["V_star_m3"]).to_numpy(float)
    rp = (fa["asym_p_Pa"] / fa["p_max_Pa"]).to_numpy(float)
    if len(fa):
        print(f"where: V/V* {np.nanmin(rv):.2f}-{np.nanmax(rv):.2f} (median {np.nanmedian(rv):.2f}); "
              f"p/p_max {np.nanmin(rp):.2f}-{np.nanmax(rp):.2f} (median {np.nanmedian(rp):.2f})")
    ls = ok["asym_lower_stable"].astype("boolean")
    print(f"lower state stable against the harmonics: {int(ls.fillna(False).sum())}, unstable: "
          f"{int((~ls.fillna(True)).sum())}, not checked: {int(ls.isna().sum())}")
    print("\n| | stable up to V* | a harmonic unstable before V* | all |\n|---|---|---|---|")
    for lab, m in (("not self-crossing", ~sc), ("self-crossing", sc)):
        print(f"| {lab} | {int((m & ~asym).sum())} | {int((m & asym).sum())} | {int(m.sum())} |")
    print(f"| all | {int((~asym).sum())} | {int(asym.sum())} | {n} |")
    agree = int((sc & asym).sum() + (~sc & ~asym).sum())
    print(f"agreement of the two: {agree}/{n} = {agree / max(n, 1):.0%}")
    dE = ok["dE_J"].to_numpy(float) * 1e3
    print(f"median dE: asymmetric first {np.median(dE[asym]):.0f} mJ, stable {np.median(dE[~asym]):.0f} mJ")
    r_all = rank_results(df)
    r_ax = rank_results(df, exclude_asymmetric=True)
    print(f"\ntop {a.top} (all designs):\n" + top_table(r_all, a.top))
    print(f"\ntop {a.top} (--exclude-asymmetric):\n" + top_table(r_ax, a.top))
    k_all, k_ax = set(_key(r_all.head(a.top))), set(_key(r_ax.head(a.top)))
    print(f"\n{len(k_all & k_ax)} of the top {a.top} are the same; "
          f"asymmetric-first designs in the unfiltered top {a.top}: "
          f"{int(r_all.head(a.top)['asym_first'].astype('boolean').fillna(False).sum())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
