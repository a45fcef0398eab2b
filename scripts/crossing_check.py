"""The self-crossing of one design's path by both tests, at the default or finer steps.

    .venv/bin/python scripts/crossing_check.py 5.6,80,16.666666666666668,90,5.8 --ds-max 0.1 --max-steps 5000
    .venv/bin/python scripts/crossing_check.py A --curve --ds0 0.01 --ds-max 0.02

Solves the design as the sweep does (the grid's mesh and the mesh re-check; ``--curve``: as
``snapjump curve`` does at the default mesh, without the re-check) and prints the reported
``self_crossing``, the polyline (chord) test and the cubic Hermite test on the reported path
(docs/physics.md: the flag uses the Hermite test).
The evidence for the self-crossing rows of bench/regression/accepted.json.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("design", help="a named design or eta_i,theta_i,eta_o,theta_o,mu_ratio")
    ap.add_argument("--curve", action="store_true", help="solve as snapjump curve does (default mesh, no re-check)")
    ap.add_argument("--ds0", type=float)
    ap.add_argument("--ds-max", type=float)
    ap.add_argument("--max-steps", type=int)
    a = ap.parse_args(argv)
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.fe.metrics import path_derivatives, path_self_crosses
    from snapjump_cli.settings import MeshSettings, SolverSettings
    from snapjump_cli.fe.solve import solve_checked, solve_scene

    if "," in a.design:
        keys = ("eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio")
        design = Design(**dict(zip(keys, map(float, a.design.split(",")))))
    else:
        design = get_design(a.design)
    over = {k: v for k, v in (("ds0", a.ds0), ("ds_max", a.ds_max), ("max_steps", a.max_steps)) if v is not None}
    if a.curve:
        r = solve_scene(design, MeshSettings(), dataclasses.replace(SolverSettings(), **over))
    else:
        cfg = load_config(REPO / "configs" / "paper_grid.yaml")
        r = solve_checked(design, cfg.mesh, dataclasses.replace(cfg.solver, **over))
    pts = r.path.points
    sV, sp = float(r.tracer.sc[0]), float(r.tracer.sc[1])
    V = np.array([pt.zeta[0] * sV for pt in pts])
    p = np.array([pt.p for pt in pts])
    chord = path_self_crosses(V, p)
    hermite = path_self_crosses(V, p, *path_derivatives(pts, sV, sp))
    print(f"{a.design} ({'curve' if a.curve else 'sweep'}, {over or 'default steps'}): {len(pts)} points, "
          f"stop: {r.path.stop_reason}; reported self_crossing {r.metrics['self_crossing']}, chord test {chord}, "
          f"Hermite test {hermite}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
