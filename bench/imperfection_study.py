"""Imperfection sensitivity of the named designs (docs/harmonics.md, section 12).

    python -m bench.imperfection_study [SCENE ...] [--deltas 1e-3 1e-2 0.1] [--n 1] [--N N]
                                       [--out bench/out/imperfection_study.json]

For each scene (default B and D, default mesh): the perfect axisymmetric solve, the harmonic check
(n <= 4), the margins of every harmonic along the path (n <= 4), the imperfection shape of
harmonic ``n`` (the critical mode, or the least stable one), the perfect answer (the followed
branch for a design that goes asymmetric first, else the axisymmetric snap), and the imperfect
actuator traced from rest for each ``delta`` (amplitude / inner-cap thickness). Prints one JSON
line per run and a markdown table; CPU seconds of each part.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

KEYS = ("dE_J", "dE_path_J", "dy_pole_m", "V_star_m3", "p_star_Pa", "h_imp_m", "lower_state_method",
        "follow_amplitude_m")


def run(name: str, deltas: list[float], n: int, N: int | None, post: int | None = None) -> dict:
    from snapjump_cli.fe.branch.bifurcation import default_harmonics, locate_bifurcation
    from snapjump_cli.fe.branch.trace import follow_branch
    from snapjump_cli.fe.stability.harmonics import check_harmonics
    from snapjump_cli.fe.branch.imperfection import imperfection_shape, inner_thickness, trace_imperfect
    from snapjump_cli.fe.stability.margins import path_margins
    from snapjump_cli.fe.solve import solve_scene
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.settings import MeshSettings, SolverSettings

    scene = get_design(name)
    t0 = time.process_time()
    res = solve_scene(scene, MeshSettings(), SolverSettings())
    m = res.metrics
    out = {"scene": name, "cpu_axisym_s": time.process_time() - t0, "V_star_axisym_m3": m["V_star_m3"],
           "p_max_Pa": m.get("p_max_Pa"), "axisym": {k: m.get(k) for k in KEYS}}
    chk = check_harmonics(res, 4)
    out["check"] = {k: getattr(chk, k) for k in ("asym_first", "asym_n", "asym_V_m3", "asym_p_Pa")}
    # margins of n = 0..4 along the path (mu_i / R_i^2), as fractions of V*
    table = path_margins(res, 4).table
    Vs = table[:, 0] / m["V_star_m3"]
    out["margins"] = {"V_rel": Vs.tolist(), **{f"n{k}": table[:, 1 + k].tolist() for k in range(table.shape[1] - 1)}}
    t0 = time.process_time()
    shape = imperfection_shape(res, n)
    sV = res.tracer.sc[0] * res.model.L ** 3
    out["shape"] = {"n": n, "source": shape.source, "V_rel": shape.V * sV / m["V_star_m3"], "eig": shape.eig,
                    "cpu_s": time.process_time() - t0}
    runs = []
    t0 = time.process_time()
    if chk.asym_first and int(chk.asym_n) == n:
        fr = follow_branch(res, locate_bifurcation(res, n), default_harmonics(n, N))
        perfect = {k: fr.metrics.get(k) for k in KEYS}
        perfect.update(kind="followed " + (fr.kind or "?"), steps=len(fr.path.points) - 1)
    else:
        perfect = dict(out["axisym"], kind="axisymmetric")
    perfect.update(delta=0.0, cpu_s=time.process_time() - t0)
    runs.append(perfect)
    print(json.dumps({"scene": name, **perfect}, default=float), file=sys.stderr, flush=True)
    t_i = inner_thickness(scene)
    for d in deltas:
        r = trace_imperfect(res, shape, d, t_i, N=N, post_snap_steps=post)
        row = {k: r.metrics.get(k) for k in KEYS}
        row.update(delta=d, kind="imperfect", steps=r.metrics["imp_steps"], cpu_s=r.metrics["imp_cpu_s"],
                   assemblies=r.model.n_assemblies, note=r.metrics["imp_note"],
                   micro_folds=r.metrics["imp_micro_folds"])
        runs.append(row)
        print(json.dumps({"scene": name, **row}, default=float), file=sys.stderr, flush=True)
    out["runs"] = runs
    return out


def table(rows: list[dict]) -> str:
    """The markdown table of the study (V* and dE relative to the perfect axisymmetric snap)."""
    lines = ["| scene | delta | path | V* / axisym V* | p* (kPa) | dE (mJ) | dy_pole (mm) | CPU (s) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        Va = r["V_star_axisym_m3"]
        for x in r["runs"]:
            V = x.get("V_star_m3")
            dE = x.get("dE_J")
            lines.append("| {} | {:g} | {} | {} | {} | {} | {} | {:.0f} |".format(
                r["scene"], x["delta"], x["kind"], f"{V / Va:.4f}" if V else "-",
                f"{x['p_star_Pa'] / 1e3:.3f}" if x.get("p_star_Pa") else "-", f"{dE * 1e3:.3f}" if dE else "-",
                f"{x['dy_pole_m'] * 1e3:.2f}" if x.get("dy_pole_m") is not None else "-", x["cpu_s"]))
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=["B", "D"])
    ap.add_argument("--deltas", nargs="+", type=float, default=[1e-3, 1e-2, 1e-1])
    ap.add_argument("--n", type=int, default=1, help="harmonic of the imperfection (default 1)")
    ap.add_argument("--N", type=int, default=None, help="highest harmonic kept (default 4 n)")
    ap.add_argument("--post-snap-steps", type=int, default=None,
                    help="steps after the snap to find the lower state on the path (default: the solver's)")
    ap.add_argument("--out", type=Path, default=Path("bench/out/imperfection_study.json"))
    a = ap.parse_args(argv)
    rows = []
    for name in a.scenes:
        rows.append(run(name, a.deltas, a.n, a.N, a.post_snap_steps))
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(json.dumps(rows, indent=1, default=float))
    print(table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
