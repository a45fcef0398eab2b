"""Re-solve paper-grid rows at much finer steps and compare both an older run and this code with
them: which one the step-converged answer is nearer to.

    .venv/bin/python lab/step_check.py OLD.parquet 1404 3854 ...

For each grid index (the row of ``configs/paper_grid.yaml``) the design is solved as the sweep
solves it (the grid's mesh and the mesh re-check) at the default steps and at 20x shorter largest
steps with a 2-degree turn limit (``--ds0``, ``--ds-max``, ``--max-turn``), and the script prints
the largest relative difference over V*, p*, dE, dy_pole and h_imp of the old row and of this
code from the fine solve, and the ``self_crossing`` flag of all three. Used for the full-grid
comparison with the code before the speed work (docs/performance.md, "Full paper-grid runs").
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

KEYS = ("V_star_m3", "p_star_Pa", "dE_J", "dy_pole_m", "h_imp_m")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", type=Path, help="an earlier sweep of the paper grid (parquet)")
    ap.add_argument("index", type=int, nargs="+", help="grid indices to re-solve")
    ap.add_argument("--ds0", type=float, default=0.01)
    ap.add_argument("--ds-max", type=float, default=0.05)
    ap.add_argument("--max-turn", type=float, default=2.0)
    a = ap.parse_args(argv)
    sys.path.insert(0, str(REPO))
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.sweep.results import read_results
    from snapjump_cli.fe.solve import solve_checked

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    points = list(cfg.designs())
    old = read_results(a.old).set_index("index")
    fine = dataclasses.replace(cfg.solver, ds0=a.ds0, ds_max=a.ds_max, max_turn_deg=a.max_turn, max_steps=20000)
    print(f"fine steps: ds0 {a.ds0:g}, ds_max {a.ds_max:g}, turn limit {a.max_turn:g} deg")
    print("| index | design | largest old vs fine | largest now vs fine | self_crossing old / now / fine |")
    print("|---|---|---|---|---|")
    for i in a.index:
        kw = points[i].design_kwargs()
        d = Design(**kw)
        now = solve_checked(d, cfg.mesh, cfg.solver).metrics
        ref = solve_checked(d, cfg.mesh, fine).metrics

        def worst(get):
            errs = {k: abs(float(get(k)) - ref[k]) / abs(ref[k]) for k in KEYS}
            k = max(errs, key=errs.get)
            return f"{errs[k]:.1e} ({k})"

        design = ", ".join(f"{kw[k]:.3g}" for k in ("eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio"))
        print(f"| {i} | ({design}) | {worst(lambda k: old.loc[i, k])} | {worst(lambda k: now[k])} | "
              f"{old.loc[i, 'self_crossing']} / {now['self_crossing']} / {ref['self_crossing']} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
