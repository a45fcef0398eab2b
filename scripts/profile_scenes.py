"""Warm solve times of the paper's scenes at the default mesh, with the split between element
assembly, band LDL^T factorisation (incl. bordered solves' set-up) and everything else (Python,
meshing, metrics).

    .venv/bin/python scripts/profile_scenes.py [--repeat 5]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys

from snapjump_cli.geometry.designs import fig1_caps, get_design
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.fe.solve import solve_scene, warm_up

SCENES = {
    **fig1_caps(("cap30-clamped", "cap8.5-roller-point")),
    **{k: get_design(k) for k in "ABCD"},
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args(argv)
    warm_up()
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print("| scene | dofs | steps | Newton | wall median [s] | assembly | factorisation | other |")
    print("|---|---|---|---|---|---|---|---|")
    for name, sc in SCENES.items():
        runs = [solve_scene(sc, MeshSettings(), SolverSettings()).metrics for _ in range(a.repeat)]
        m = sorted(runs, key=lambda r: r["wall_s"])[len(runs) // 2]
        w = m["wall_s"]
        print(f"| {name} | {m['n_dofs']} | {m['n_steps']} | {m['n_newton']} | {statistics.median(r['wall_s'] for r in runs):.3g} | "
              f"{m['t_assembly_s'] / w:.0%} | {m['t_factor_s'] / w:.0%} | {1 - (m['t_assembly_s'] + m['t_factor_s']) / w:.0%} |", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
