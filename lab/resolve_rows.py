"""Re-solve selected rows of a results file with the current code and write a merged copy.

Used to bring the paper grid's descent rows (many solved with the first descent) up to date:

    .venv/bin/python lab/resolve_rows.py results/grid_b9bda24.parquet \
        --where "status == 'ok' and lower_state_method == 'descent'" --mesh 2,2,3 \
        --resolved results/stress/grid_descent_rows_resolved.parquet --merged results/grid_final.parquet

The re-solve is an ordinary (resumable) sweep over the selected designs, given to the sweep as
``points:`` (the same as a YAML ``points:`` list); rows are matched by their key (design + mesh +
solver settings), so ``--mesh`` must be the file's mesh. Prints how much dE and dy_pole moved.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.config import parse_config
from snapjump_cli.sweep.run import run_sweep


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", type=Path)
    ap.add_argument("--where", required=True, help="pandas query selecting the rows to re-solve")
    ap.add_argument("--mesh", required=True, help="ORDER,NT,ASPECT of the file's rows")
    ap.add_argument("--resolved", type=Path, required=True, help="parquet of the re-solved rows (resumable)")
    ap.add_argument("--merged", type=Path, default=None, help="write the results with those rows replaced")
    ap.add_argument("--jobs", type=int, default=-1)
    a = ap.parse_args(argv)
    o, nt, asp = a.mesh.split(",")
    g = pd.read_parquet(a.results)
    sel = g.query(a.where)
    pts = [{"eta_i": float(r.eta_i), "theta_i": float(r.theta_i_deg), "eta_o": float(r.eta_o),
            "theta_o": float(r.theta_o_deg), "mu_ratio": float(r.mu_ratio)} for r in sel.itertuples()]
    print(f"{len(pts)} rows selected", flush=True)
    cfg = parse_config({"points": pts, "mesh": {"order": int(o), "nt": int(nt), "aspect": float(asp)},
                        "n_jobs": a.jobs}, "<resolve_rows>")
    run_sweep(cfg, output=a.resolved, progress=True)
    r = res.read_results(a.resolved)
    rr = r.set_index("key")
    missing = set(rr.index) - set(g.key)
    if missing:
        raise SystemExit(f"{len(missing)} re-solved keys are not in {a.results}: is --mesh the file's mesh?")
    old = g.set_index("key").loc[rr.index]
    print("re-solved:", rr.status.value_counts().to_dict(), "| lower state:", rr.lower_state_method.value_counts().to_dict(),
          "| mesh_sensitive:", int((rr.mesh_sensitive == True).sum()))  # noqa: E712
    ok = (rr.status == "ok") & (old.status == "ok")
    for col, label in (("dE_J", "dE"), ("dy_pole_m", "dy_pole")):
        rel = ((rr[col] - old[col]).abs() / old[col].abs())[ok]
        print(f"{label} change over {int(ok.sum())} rows ok before and after: median {rel.median():.2e}, "
              f"95 % {rel.quantile(0.95):.2e}, max {rel.max():.3g}; > 1 %: {int((rel > 0.01).sum())}, > 5 %: {int((rel > 0.05).sum())}")
    if a.merged is not None:
        m = g.set_index("key")
        for c in m.columns:
            if c in rr.columns:
                m.loc[rr.index, c] = rr[c].values
        m = m.reset_index()[g.columns]
        m.to_parquet(a.merged, index=False)
        print(f"wrote {a.merged}: {len(m)} rows, " + ", ".join(f"{k} {v}" for k, v in m.status.value_counts().items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
