"""The largest pressure on a design's path, from the points and from the Hermite curve, at the
default and at finer steps.

    .venv/bin/python lab/pmax_check.py 5,80,10,90,5.8 5,70,13.333333333333334,76,5.8
    .venv/bin/python lab/pmax_check.py D --ds-max 0.02 --max-turn 2

Solves each design as the sweep does (the grid's mesh and the mesh re-check) at the default steps
and at finer ones, and prints the largest pressure on the loading path (up to the upper state)
taken over the path points and over the path's cubic Hermite curve (what ``p_max_Pa`` reports
since 23 November 2026, docs/physics.md section 5). The points
miss a smooth maximum by the curvature times the square of the step; the curve, by its fourth power.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("designs", nargs="+", help="named designs or eta_i,theta_i,eta_o,theta_o,mu_ratio")
    ap.add_argument("--ds-max", type=float, default=0.02, help="largest step of the fine trace")
    ap.add_argument("--max-turn", type=float, default=2.0, help="largest turn per step of the fine trace [deg]")
    ap.add_argument("--max-steps", type=int, default=20000)
    a = ap.parse_args(argv)
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.fe.axisym.metrics import loading_peak
    from snapjump_cli.fe.solve import solve_checked

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    fine = dataclasses.replace(cfg.solver, ds0=min(cfg.solver.ds0, a.ds_max), ds_max=a.ds_max, max_turn_deg=a.max_turn, max_steps=a.max_steps)
    print("| design | steps | p_max points [Pa] | p_max curve [Pa] | fine steps | fine points [Pa] | fine curve [Pa] |"
          " points vs fine curve | curve vs fine curve |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in a.designs:
        if "," in name:
            keys = ("eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio")
            design = Design(**dict(zip(keys, map(float, name.split(",")))))
        else:
            design = get_design(name)
        out = []
        for solver in (cfg.solver, fine):
            r = solve_checked(design, cfg.mesh, solver)
            pts = r.path.points
            sV, sp, S = float(r.tracer.sc[0]), float(r.tracer.sc[1]), r.model.S
            st = r.states
            upto = pts if st.upper is None else pts[: st.k_before + 1] + [st.upper]
            points_max = max(pt.p for pt in upto)
            curve = loading_peak(pts, st, sV, sp)
            out.append((len(pts) - 1, points_max * S, curve * S))
            assert abs(r.metrics["p_max_Pa"] - curve * S) <= 1e-12 * abs(curve * S)
        (n0, pts0, cur0), (n1, pts1, cur1) = out
        print(f"| {name} | {n0} | {pts0:.2f} | {cur0:.2f} | {n1} | {pts1:.2f} | {cur1:.2f} | "
              f"{(pts0 - cur1) / cur1:+.2e} | {(cur0 - cur1) / cur1:+.2e} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
