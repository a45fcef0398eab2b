"""Cost of the air option against water, measured back to back (docs/air.md, "Cost").

Solves each design with water and with air (V0_sys = 45 mL, isothermal) alternately, ``--repeats``
times, in one warm process, and prints the CPU time per design and the ratio air/water::

    python lab/air_cost.py [--repeats 3] [--V0 45] [--grid 12]

The designs: C, D and ``--grid`` designs drawn with a fixed seed from the paper grid's valid points
at mu_i/mu_o = 5.8 (the grid's mesh: Q9, nt 2, aspect 3).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from snapjump_cli.sweep.config import load_config
from snapjump_cli.geometry.designs import get_design
from snapjump_cli.fe.axisym.fluid import FluidSettings
from snapjump_cli.geometry.caps import Design, InvalidDesign
from snapjump_cli.settings import MeshSettings
from snapjump_cli.fe.solve import SolveFailed, solve_checked, warm_up


def _designs(n_grid: int) -> list[tuple[str, Design]]:
    out = [("C", get_design("C")), ("D", get_design("D"))]
    cfg = load_config("configs/paper_grid.yaml")
    pts = [p for p in cfg.designs() if p.mu_ratio == 5.8]
    rng = np.random.default_rng(26)
    for i in rng.permutation(len(pts)):
        if len(out) >= 2 + n_grid:
            break
        try:
            out.append((f"grid-{pts[i].index}", Design(**pts[i].design_kwargs())))
        except InvalidDesign:
            continue
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--V0", type=float, default=45.0, help="V0_sys [mL]")
    ap.add_argument("--grid", type=int, default=12)
    a = ap.parse_args()
    warm_up()
    mesh = MeshSettings(order=2, nt=2, aspect=3.0)
    air = FluidSettings(kind="air", V0_ml=a.V0)
    tot = {"water": 0.0, "air": 0.0}
    print(f"{'design':12s} {'water s':>9s} {'air s':>9s} {'ratio':>6s}")
    for name, d in _designs(a.grid):
        t = {"water": 0.0, "air": 0.0}
        for _ in range(a.repeats):
            for kind, fluid in (("water", None), ("air", air)):
                t0 = time.process_time()
                try:
                    solve_checked(d, mesh, fluid=fluid)
                except SolveFailed as e:
                    print(f"{name}: {kind} failed: {e}")
                t[kind] += time.process_time() - t0
        for k in t:
            tot[k] += t[k]
        print(f"{name:12s} {t['water'] / a.repeats:9.3f} {t['air'] / a.repeats:9.3f} {t['air'] / t['water']:6.2f}")
    print(f"{'all':12s} {tot['water'] / a.repeats:9.3f} {tot['air'] / a.repeats:9.3f} {tot['air'] / tot['water']:6.2f}")


if __name__ == "__main__":
    main()
