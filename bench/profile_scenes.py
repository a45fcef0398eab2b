"""Warm solve times of the paper's scenes at the default mesh (the compiled Newton corrector), and
the split between element assembly, band LDL^T factorisation (incl. bordered solves' set-up) and
everything else (Python, meshing, metrics), measured through the Python corrector
(``solve_scene(..., fused=False)``), whose timers see the phases (the compiled corrector does the
same work in one call, so its phases cannot be timed apart).

    .venv/bin/python -m bench.profile_scenes [--repeat 5]
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
    print("| scene | dofs | steps | Newton | wall median [s] | Python corrector: wall [s] | assembly | factorisation | other |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, sc in SCENES.items():
        runs = [solve_scene(sc, MeshSettings(), SolverSettings()).metrics for _ in range(a.repeat)]
        split = [solve_scene(sc, MeshSettings(), SolverSettings(), fused=False).metrics for _ in range(a.repeat)]
        m = runs[0]
        p = sorted(split, key=lambda r: r["wall_s"])[len(split) // 2]
        w = p["wall_s"]
        print(f"| {name} | {m['n_dofs']} | {m['n_steps']} | {m['n_newton']} | {statistics.median(r['wall_s'] for r in runs):.3g} | "
              f"{w:.3g} | {p['t_assembly_s'] / w:.0%} | {p['t_factor_s'] / w:.0%} | "
              f"{1 - (p['t_assembly_s'] + p['t_factor_s']) / w:.0%} |", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
