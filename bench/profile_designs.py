"""Per-design cost of a sweep solve: steps, Newton iterations, assemblies, factorisations, time
per iteration and the element pass against its flop count.

    .venv/bin/python -m bench.profile_designs [--repeat 3] [--designs D C grid-0037 grid-1543]

Designs are named designs (``snapjump_cli/geometry/designs.yaml``) or ``grid-NNNN`` (the paper grid's point
NNNN); each is solved once at the grid's mesh (``solve_scene``; ``--sweep``: as the sweep solves
it, with the mesh re-check), warm, the median of ``--repeat`` runs. ``--repo DIR`` profiles another
checkout (e.g. a git worktree of an older commit, with a ``snapjump_kernels -> kernels`` link).
Prints a markdown table. With the compiled corrector the per-assembly and per-factorisation times
are not timed apart; ``--phases`` solves through the Python corrector, whose timers split them.

    .venv/bin/python -m bench.profile_designs --kernels D

times each kernel of one Newton iteration (CPU time per call, 600 calls) at the middle point of
the design's path: the element pass with the stiffness, with the residual only and with the
energy only, the bordered band LDL^T and one refined bordered solve (``--nt 3``: on the mesh of
the re-check), then how exact the band kernels are there (condition number, the bordered solve
against an extended-precision solution, the band solve and product against dense numpy).

    .venv/bin/python -m bench.profile_designs --topologies 400

meshes a seeded sample of paper-grid points (the invalid ones drop out) and counts the distinct
mesh topologies, i.e. the node orders the sweep computes once and then looks up (the order cache
of ``snapjump_cli/mesh/data.py``).
"""
from __future__ import annotations

import argparse
import dataclasses
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


def startup(profile: bool = False) -> int:
    """Start-up costs of ``snapjump curve`` in this fresh process (the thin clamped cap); with
    ``profile``, the first solve's largest costs by cProfile (cumulative)."""
    t0 = time.perf_counter()
    import snapjump_cli.commands.curve  # noqa: F401 - what the command imports first
    t1 = time.perf_counter()
    from snapjump_cli.geometry.caps import CapScene
    from snapjump_cli.settings import MeshSettings, SolverSettings
    from snapjump_cli.fe.solve import solve_scene
    t2 = time.perf_counter()
    cap = CapScene(theta_deg=60.0, eta=30.0, bc="clamped")
    if profile:
        import cProfile
        import pstats

        prof = cProfile.Profile()
        m1 = prof.runcall(solve_scene, cap, MeshSettings(), SolverSettings()).metrics
        pstats.Stats(prof).sort_stats("cumulative").print_stats(25)
    else:
        m1 = solve_scene(cap, MeshSettings(), SolverSettings()).metrics
    t3 = time.perf_counter()
    m2 = solve_scene(cap, MeshSettings(), SolverSettings()).metrics
    t4 = time.perf_counter()
    print(f"load average {os.getloadavg()[0]:.2f}: import of the curve command {t1 - t0:.3f} s, of the solver "
          f"{t2 - t1:.3f} s; first solve {t3 - t2:.3f} s (meshing {m1['mesh_s']:.3f} s), second {t4 - t3:.3f} s "
          f"(meshing {m2['mesh_s']:.3f} s): the first call costs {t3 - t2 - (t4 - t3):.3f} s more")
    return 0


def kernels(name: str, calls: int = 600, nt: int | None = None) -> int:
    """CPU time per call of the kernels of one Newton iteration at a path state of ``name`` (at the
    grid's mesh, or with ``nt`` elements through the thickness)."""
    import numpy as np

    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.fe.solve import solve_scene
    from snapjump_kernels.assembly import evaluate
    from snapjump_kernels.banded import bordered_factor, bordered_solve

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    mesh = cfg.mesh if nt is None else dataclasses.replace(cfg.mesh, nt=nt)
    r = solve_scene(get_design(name), mesh, cfg.solver)
    m = r.model
    pt = r.path.points[len(r.path.points) // 2]

    def element_pass(want):
        R, g, data = np.zeros(m.n), np.zeros(m.n), np.zeros(m.ndata)
        evaluate(pt.u, m.dofmap, m.X, m.conn, m.mat, m.mu, m.jm, m.kappa, m.dNdX, m.N_ref, m.Rq, m.Wq, m.Np,
                 m.Minv, m.edofs, m.epos, m.edges, m.edge_dofs, m.edge_pos, pt.p, want, R, g, data, *m._no_aux())
        return g, data

    def per_call(f):
        f()
        t0 = time.process_time()
        for _ in range(calls):
            f()
        return 1e3 * (time.process_time() - t0) / calls

    g, data = element_pass(2)
    K = data.reshape(m.n, m.kl + 1)
    c = np.random.default_rng(0).random(m.n)
    fac = bordered_factor(K, m.band_ext, -g, c, 0.1)
    rhs = np.random.default_rng(1).random(m.n + 1)
    print(f"{name}: {m.n} dofs, {m.conn.shape[0]} elements, half-bandwidth {m.kl}, mean envelope "
          f"{float(np.mean(m.band_ext)):.1f}; load average {os.getloadavg()[0]:.2f}; ms (CPU) per call:")
    for label, f in (("element pass, stiffness", lambda: element_pass(2)),
                     ("element pass, residual", lambda: element_pass(1)),
                     ("element pass, energy", lambda: element_pass(0)),
                     ("bordered band LDL^T", lambda: bordered_factor(K, m.band_ext, -g, c, 0.1)),
                     ("refined bordered solve",
                      lambda: bordered_solve(fac[2], K, m.band_ext, -g, c, 0.1, fac[3], fac[4], rhs, True))):
        ms = per_call(f)
        print(f"  {label}: {ms:.3f}")
        if label == "element pass, stiffness" and m.conn.shape[1] in (4, 9):
            fl = element_flops(9, 9, 3) if m.conn.shape[1] == 9 else element_flops(4, 4, 1)
            print(f"    ~{fl / 1e3:.1f} kflop per element (estimate), {fl * m.conn.shape[0] / 1e6:.2f} Mflop "
                  f"per pass: {fl * m.conn.shape[0] / (ms * 1e-3) / 1e9:.2f} GFlop/s")
    _solve_accuracy(K, m.band_ext, g, c, rhs, fac)
    return 0


def _solve_accuracy(K, ext, g, c, rhs, fac) -> None:
    """How exact the band kernels are on this matrix: the bordered matrix's condition number, the
    errors of the bordered solve (without and with its refinement step) against a solution
    refined with residuals in extended precision, and the band solve and product against dense
    numpy."""
    import numpy as np

    from snapjump_kernels.banded import band_ldlt_solve, bordered_solve, sym_band_matvec

    n = len(ext)
    A = np.zeros((n, n))
    for j in range(n):
        A[j:j + ext[j] + 1, j] = K[j, :ext[j] + 1]
        A[j, j:j + ext[j] + 1] = K[j, :ext[j] + 1]
    B = np.zeros((n + 1, n + 1))
    B[:n, :n], B[:n, n], B[n, :n], B[n, n] = A, -g, c, 0.1

    def solve(r, refine):
        return bordered_solve(fac[2], K, ext, -g, c, 0.1, fac[3], fac[4], np.ascontiguousarray(r), refine)

    x = solve(rhs, False).astype(np.longdouble)
    for _ in range(8):  # iterative refinement with the residual in extended precision
        x = x + solve((rhs.astype(np.longdouble) - B.astype(np.longdouble) @ x).astype(float), False)
    exact = x.astype(float)

    def err(y, ref):
        return float(np.abs(y - ref).max() / np.abs(ref).max())

    b = rhs[:n]
    print(f"  accuracy: cond of the bordered matrix {np.linalg.cond(B):.1e}; bordered solve vs the "
          f"extended-precision solution {err(solve(rhs, False), exact):.1e} (refined: {err(solve(rhs, True), exact):.1e}); "
          f"band solve vs dense numpy {err(band_ldlt_solve(fac[2], b, ext), np.linalg.solve(A, b)):.1e}, "
          f"band product {err(sym_band_matvec(K, b, ext), A @ b):.1e}")


def topologies(n: int, seed: int = 0) -> int:
    """Mesh ``n`` seeded paper-grid points; print how many were valid and their distinct topologies."""
    import numpy as np

    from snapjump_cli.mesh import data as meshdata
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.caps import Design, InvalidDesign
    from snapjump_cli.mesh.build import mesh_scene

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    points = list(cfg.designs())
    meshdata._ORDER_CACHE.clear()
    n_valid = 0
    for i in np.random.default_rng(seed).choice(len(points), n, replace=False):
        try:
            d = Design(**points[int(i)].design_kwargs())
        except InvalidDesign:
            continue
        mesh_scene(d, cfg.mesh)
        n_valid += 1
    n_orders = sum(1 for key in meshdata._ORDER_CACHE if key[0] == "node_order")
    print(f"{n} points (seed {seed}), {n_valid} valid designs meshed at {cfg.mesh}: "
          f"{n_orders} distinct mesh topologies ({len(meshdata._ORDER_CACHE)} cached orders)")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--designs", nargs="*", default=["D", "C", "grid-0037", "grid-1543"])
    ap.add_argument("--sweep", action="store_true", help="solve_design (with the mesh re-check)")
    ap.add_argument("--phases", action="store_true",
                    help="through the Python corrector (fused=False), whose timers split the phases")
    ap.add_argument("--repo", default=str(REPO))
    ap.add_argument("--kernels", metavar="DESIGN", help="only time the kernels of one iteration at a path state")
    ap.add_argument("--nt", type=int, help="with --kernels: elements through the thickness (default: the grid's)")
    ap.add_argument("--profile", action="store_true", help="with --startup: cProfile of the first solve")
    ap.add_argument("--startup", action="store_true",
                    help="only the start-up costs of a fresh process: imports, first and second solve of a cap")
    ap.add_argument("--topologies", type=int, metavar="N",
                    help="only count the distinct mesh topologies of N seeded grid points")
    a = ap.parse_args(argv)
    repo = Path(a.repo).resolve()
    sys.path.insert(0, str(repo))
    if a.topologies:
        return topologies(a.topologies)
    if a.startup:
        return startup(a.profile)
    if a.kernels:
        return kernels(a.kernels, nt=a.nt)
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.fe.solve import solve_design, solve_scene, warm_up

    cfg = load_config(repo / "configs" / "paper_grid.yaml")
    points = list(cfg.designs())
    warm_up()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; mesh {cfg.mesh}")
    print("| design | lower state | dofs | steps | Newton | assemblies | factorisations | wall [s] | "
          "ms per assembly, all in | compiled corrector share |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in a.designs:
        d = Design(**points[int(name[5:])].design_kwargs()) if name.startswith("grid-") else get_design(name)
        runs = []
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            kw = {"fused": False} if a.phases else {}
            if a.sweep:
                m = solve_design(d, cfg.mesh, cfg.solver, **kw)
            else:
                r = solve_scene(d, cfg.mesh, cfg.solver, **kw)
                m = r.metrics
                m["n_assemblies"] = r.model.n_assemblies  # (older code: every element pass, energy ones too)
            m["_wall"] = time.perf_counter() - t0
            runs.append(m)
        m = sorted(runs, key=lambda r: r["_wall"])[len(runs) // 2]
        n_asm = m.get("n_assemblies")
        n_fac = m.get("n_factorizations")
        wall = statistics.median(r["_wall"] for r in runs)
        # the assemblies run inside the compiled corrector, whose timer covers assembly,
        # factorisation and solves together: the cost per assembly is given all in (the design's
        # wall over its assemblies); the element pass alone against its flop count: --kernels
        ms_asm = 1e3 * wall / n_asm if n_asm else float("nan")
        share = (m.get("t_newton_s") or 0.0) / m["_wall"]
        print(f"| {name} | {m['lower_state_method']} ({m.get('mesh_check') or 'no re-check'}) | {m['n_dofs']} | "
              f"{m['n_steps']} | {m['n_newton']} | {n_asm if n_asm else '-'} | {n_fac} | "
              f"{wall:.3f} | {ms_asm:.3f} | {share:.0%} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
