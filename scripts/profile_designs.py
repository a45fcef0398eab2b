"""Per-design cost of a sweep solve: steps, Newton iterations, assemblies, factorisations, time
per iteration and the element pass against its flop count (issue 10's before/after table).

    .venv/bin/python scripts/profile_designs.py [--repeat 3] [--designs D C grid-0037 grid-1543]

Designs are named designs (``snapjump_cli/data/designs.yaml``) or ``grid-NNNN`` (the paper grid's point
NNNN); each is solved once at the grid's mesh (``solve_scene``; ``--sweep``: as the sweep solves
it, with the mesh re-check), warm, the median of ``--repeat`` runs. ``--repo DIR`` profiles another
checkout (e.g. a git worktree of an older commit, with a ``snapjump_kernels -> kernels`` link).
Prints a markdown table. With the compiled corrector the per-assembly and per-factorisation times
need ``SNAPJUMP_PROFILE_PHASES=1`` (the Python corrector, whose timers split the phases).
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def element_flops(nen: int, nq: int, npr: int) -> float:
    """Floating-point operations of one element's energy, force and stiffness (an estimate from
    the loops of ``kernels/assembly.py``, multiply and add counted separately)."""
    nd = 2 * nen
    lower = nd * (nd + 1) // 2
    per_q = (
        2 * 5 * nen  # deformation gradient
        + 600  # Gent energy, gradient and Hessian in the five components
        + 2 * 5 * nd  # B^T stress
        + 2 * npr * 5 * nd  # G rows
        + 2 * 25  # D
        + 2 * 5 * nd * 5 // 2  # D B (u_r dofs use 3 rows of B, u_z dofs 2)
        + 2 * (5 * lower) // 2  # B^T (D B), lower triangle
    )
    vol = 2 * npr * npr * nd + 2 * npr * lower  # kappa G^T M^-1 G
    return nq * per_q + vol + 2 * lower  # + scatter


def startup() -> int:
    """Start-up costs of ``snapjump curve`` in this fresh process (the thin clamped cap)."""
    t0 = time.perf_counter()
    import snapjump_cli.commands.curve  # noqa: F401 - what the command imports first
    t1 = time.perf_counter()
    from snapjump_cli.geometry import CapScene
    from snapjump_cli.settings import MeshSettings, SolverSettings
    from snapjump_cli.solve import solve_scene
    t2 = time.perf_counter()
    cap = CapScene(theta_deg=60.0, eta=30.0, bc="clamped")
    m1 = solve_scene(cap, MeshSettings(), SolverSettings()).metrics
    t3 = time.perf_counter()
    m2 = solve_scene(cap, MeshSettings(), SolverSettings()).metrics
    t4 = time.perf_counter()
    print(f"load average {os.getloadavg()[0]:.2f}: import of the curve command {t1 - t0:.3f} s, of the solver "
          f"{t2 - t1:.3f} s; first solve {t3 - t2:.3f} s (meshing {m1['mesh_s']:.3f} s), second {t4 - t3:.3f} s "
          f"(meshing {m2['mesh_s']:.3f} s): the first call costs {t3 - t2 - (t4 - t3):.3f} s more")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--designs", nargs="*", default=["D", "C", "grid-0037", "grid-1543"])
    ap.add_argument("--sweep", action="store_true", help="solve_design (with the mesh re-check)")
    ap.add_argument("--repo", default=str(REPO))
    ap.add_argument("--startup", action="store_true",
                    help="only the start-up costs of a fresh process: imports, first and second solve of a cap")
    a = ap.parse_args(argv)
    repo = Path(a.repo).resolve()
    sys.path.insert(0, str(repo))
    if a.startup:
        return startup()
    from snapjump_cli.config import load_config
    from snapjump_cli.designs import get_design
    from snapjump_cli.geometry import Design
    from snapjump_cli.solve import solve_design, solve_scene, warm_up

    cfg = load_config(repo / "configs" / "paper_grid.yaml")
    points = list(cfg.designs())
    warm_up()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; mesh {cfg.mesh}")
    print("| design | lower state | dofs | steps | Newton | assemblies | factorisations | wall [s] | "
          "ms / assembly | ms / factorisation | element pass GFlop/s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in a.designs:
        d = Design(**points[int(name[5:])].design_kwargs()) if name.startswith("grid-") else get_design(name)
        runs = []
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            if a.sweep:
                m = solve_design(d, cfg.mesh, cfg.solver)
            else:
                r = solve_scene(d, cfg.mesh, cfg.solver)
                m = r.metrics
                m["n_assemblies"] = r.model.n_assemblies  # (older code: every element pass, energy ones too)
            m["_wall"] = time.perf_counter() - t0
            runs.append(m)
        m = sorted(runs, key=lambda r: r["_wall"])[len(runs) // 2]
        n_asm = m.get("n_assemblies")
        n_fac = m.get("n_factorizations")
        n_el = m["n_elements"]
        flops = element_flops(9, 9, 3) if cfg.mesh.order == 2 else element_flops(4, 4, 1)
        ms_asm = 1e3 * m["t_assembly_s"] / n_asm if n_asm else float("nan")
        gf = flops * n_el / (m["t_assembly_s"] / n_asm) / 1e9 if n_asm else float("nan")
        print(f"| {name} | {m['lower_state_method']} ({m.get('mesh_check') or 'no re-check'}) | {m['n_dofs']} | "
              f"{m['n_steps']} | {m['n_newton']} | {n_asm if n_asm else '-'} | {n_fac} | "
              f"{statistics.median(r['_wall'] for r in runs):.3f} | {ms_asm:.3f} | "
              f"{1e3 * m['t_factor_s'] / n_fac:.3f} | {gf:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
