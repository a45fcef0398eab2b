"""The followed branches of the named scenes, with the N-convergence (docs/harmonics.md, section 10).

    python -m bench.follow_study [SCENE ...] [--N N ...] [--no-secondary] [--out bench/out/follow_study.json]

For each scene: the axisymmetric solve (default mesh), the harmonic check (n <= 4), and when a
harmonic goes first the followed branch with N = 4 n_c and with N + max(2, n_c) harmonics (or
``--N``); for n_c >= 2 each branch is checked against the harmonics it does not keep and, where it
loses stability to them first, the branch leaving it is traced with every harmonic 0..N
(``secondary``; docs/harmonics.md section 10.7). CPU seconds of each part. Prints one JSON line
per run and per scene and writes the numbers as JSON.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

SCENES = {
    "A": ("design", "A"),
    "B": ("design", "B"),
    "C": ("design", "C"),
    "D": ("design", "D"),
    "S16-12.5-70": ("cap", dict(theta_deg=70.0, eta=12.5, bc="ring-roller")),
    "S16-10-60": ("cap", dict(theta_deg=60.0, eta=10.0, bc="ring-roller")),
    "clamped-30-50": ("cap", dict(theta_deg=30.0, eta=50.0, bc="clamped")),
}


def solve_checked_scene(name: str) -> tuple:
    """The scene ``name`` of :data:`SCENES` solved at the default mesh and checked against
    ``n <= 4``: ``(result, check, CPU seconds of the solve)``."""
    from snapjump_cli.fe.stability.harmonics import check_harmonics
    from snapjump_cli.fe.solve import solve_scene
    from snapjump_cli.geometry.caps import CapScene
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.settings import MeshSettings, SolverSettings

    kind, arg = SCENES[name]
    scene = get_design(arg) if kind == "design" else CapScene(**arg)
    t0 = time.process_time()
    res = solve_scene(scene, MeshSettings(), SolverSettings())
    t_axi = time.process_time() - t0
    return res, check_harmonics(res, 4), t_axi


def run(name: str, Ns: list[int] | None = None, secondary: bool = True) -> dict:
    from snapjump_cli.fe.branch.bifurcation import default_harmonics, locate_bifurcation
    from snapjump_cli.fe.branch.trace import follow_branch
    from snapjump_cli.fe.branch.secondary import follow_secondary

    res, chk, t_axi = solve_checked_scene(name)
    m = res.metrics
    out = {"scene": name, "cpu_axisym_s": t_axi, "axisym_dE_J": m["dE_J"], "axisym_dy_pole_m": m["dy_pole_m"],
           "axisym_V_star_m3": m["V_star_m3"], "axisym_h_imp_m": m.get("h_imp_m"), "asym_n": chk.asym_n,
           "asym_V_m3": chk.asym_V_m3, "runs": []}
    if not chk.asym_first:
        return out
    n = int(chk.asym_n)
    t0 = time.process_time()
    bif = locate_bifurcation(res, n)
    out["cpu_locate_s"] = time.process_time() - t0
    N1 = 4 * n
    for N in (Ns or (N1, N1 + max(2, n))):
        t0 = time.process_time()
        fr = follow_branch(res, bif, default_harmonics(n, N))
        fm = fr.metrics
        row = {k: fm.get(k) for k in ("follow_kind", "dE_J", "dy_pole_m", "h_imp_m", "V_star_m3", "p_star_Pa",
                                      "follow_lower_method", "follow_dE_rel_diff", "follow_note",
                                      "follow_micro_folds", "follow_V_bif_m3")}
        row.update(N=N, first_kind=fr.first_kind, cpu_s=time.process_time() - t0, steps=len(fr.path.points) - 1,
                   assemblies=fr.model.n_assemblies, ndof=fr.model.n)
        if secondary and n >= 2:  # the branch against the harmonics it does not keep
            t0 = time.process_time()
            fs, chk, sec = follow_secondary(res, fr)
            row["secondary"] = None if sec is None else {
                "n": sec.n, "V_m3": sec.V_m3, "p_Pa": sec.p_Pa, "V_rel_axisym": sec.V_m3 / m["V_star_m3"],
                "kind": fs.kind, "cpu_s": time.process_time() - t0, "steps": len(fs.path.points) - 1,
                "ndof": fs.model.n, **{k: fs.metrics.get(k) for k in ("dE_J", "dE_path_J", "follow_dE_rel_diff",
                                                                      "dy_pole_m", "h_imp_m", "V_star_m3",
                                                                      "p_star_Pa", "follow_lower_method",
                                                                      "follow_note")}}
            row["secondary_check"] = {"first_V_m3": chk.V_m3[chk.first] if chk.first is not None else None,
                                      "states": len(chk.index), "N": chk.N}
        out["runs"].append(row)
        print(json.dumps({"scene": name, **row}, default=float), file=sys.stderr, flush=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--out", type=Path, default=Path("bench/out/follow_study.json"))
    ap.add_argument("--N", type=int, nargs="+", default=None,
                    help="the harmonics kept, each run (default: 4 n_c and 4 n_c + max(2, n_c))")
    ap.add_argument("--no-secondary", action="store_true",
                    help="do not check a branch of n_c >= 2 against the other harmonics")
    a = ap.parse_args(argv)
    rows = []
    for name in a.scenes:
        r = run(name, a.N, not a.no_secondary)
        rows.append(r)
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(json.dumps(rows, indent=1, default=float))
        print(r["scene"], json.dumps(r, default=float), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
