"""Where a followed design's CPU goes, per phase, for designs of a points file.

    .venv/bin/python -m bench.profile.follow_phases POINTS.csv [--rows A:B] [--mode actuator|full]
                                                     [--out FILE.jsonl] [--time-limit S]

Each design (the columns ``eta_i, theta_i, eta_o, theta_o, mu_ratio`` of the sweep's points
files, e.g. ``bench/harmonics_sample/follow_strata.csv``) is solved on the sweep's mesh (order 2,
nt 2, aspect 3) with the harmonic check, then again with its branch followed
(``solver: {harmonics: 4, follow: true, follow_mode: MODE}``) under :mod:`cProfile`, in this
process (the kernels compiled or loaded by a first solve, not timed). One JSON line per design:
the process CPU of the axisymmetric solve and check and of the followed solve, their ratio, the
answer (kind, ``dE_J``, ``dy_pole_m``, ``V_star_m3``, lower-state method, note), every branch
traced (points, points up to the upper state: the states the actuator passes through, harmonics,
dofs, how the lower state was found) and the cumulative time and call count of each phase
(bifurcation, branch traces, lower-state searches, the secondary check, assembly, factorisation).
The profiler's times are wall-clock under its overhead: compare phases within a line, and the
unprofiled CPU totals between lines.
"""
from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import sys
import time

PHASES = {
    "locate_bifurcation": "bifurcation", "trace_branch": "branch traces", "trace": "continuation",
    "find_lower_state": "lower state", "snap_at_fixed_volume": "lower: fixed-volume path",
    "descend_at_volume": "lower: descent", "follow_secondary": "secondary", "branch_stability": "secondary: check",
    "first_extra": "secondary: first", "locate_secondary": "secondary: locate", "jump_off_branch": "secondary: jump",
    "full_model": "secondary: full model", "linearize": "assembly", "factor": "factorisation",
}


def _phases(stats: pstats.Stats) -> dict:
    out: dict = {}
    for (fn, _, name), (_, nc, _, ct, _) in stats.stats.items():
        if name in PHASES and "snapjump" in fn:
            key = PHASES[name]
            if name in ("linearize", "factor"):
                key += " (multi-harmonic)" if "branch" in fn else " (axisymmetric)"
            out[key] = round(out.get(key, 0.0) + ct, 3)
            out[key + " #"] = out.get(key + " #", 0) + nc
    return out


def _branches(fr) -> list[dict]:
    chain = []
    while fr is not None:
        st = fr.states
        chain.append({"kind": fr.kind, "points": len(fr.path.points),
                      "up_to_upper": st.k_before if st is not None else None, "N": int(fr.model.hn[-1]),
                      "dofs": int(fr.model.n), "lower": fr.lower_method, "note": (fr.lower_note or "")[:160]})
        fr = fr.parent
    return chain


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.profile.follow_phases", description=__doc__.split("\n\n")[0])
    ap.add_argument("points", help="a points CSV (eta_i, theta_i, eta_o, theta_o, mu_ratio)")
    ap.add_argument("--rows", default="0:1000000", help="rows A:B of the file (default all)")
    ap.add_argument("--mode", choices=("actuator", "full"), default="actuator", help="solver.follow_mode")
    ap.add_argument("--out", default=None, help="append the JSON lines to this file (default: stdout)")
    ap.add_argument("--time-limit", type=float, default=900.0, help="CPU seconds per followed solve")
    args = ap.parse_args(argv)

    import pandas as pd

    from snapjump_cli.fe.solve import solve_checked
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.settings import MeshSettings, SolverSettings

    df = pd.read_csv(args.points)
    a, _, b = args.rows.partition(":")
    mesh = MeshSettings(order=2, nt=2, aspect=3.0)
    warm = True
    for i in range(int(a or 0), min(int(b or len(df)), len(df))):
        r = df.iloc[i]
        d = Design(eta_i=float(r.eta_i), theta_i_deg=float(r.theta_i), eta_o=float(r.eta_o),
                   theta_o_deg=float(r.theta_o), mu_ratio=float(r.mu_ratio))
        if warm:  # compile or load every kernel before anything is timed
            solve_checked(d, mesh, SolverSettings(harmonics=4, follow=True, time_limit_s=30.0))
            warm = False
        t0 = time.process_time()
        solve_checked(d, mesh, SolverSettings(harmonics=4))
        t_axi = time.process_time() - t0
        prof = cProfile.Profile()
        t0 = time.process_time()
        prof.enable()
        try:
            res, err = solve_checked(d, mesh, SolverSettings(harmonics=4, follow=True, follow_mode=args.mode,
                                                             time_limit_s=args.time_limit)), ""
        except Exception as exc:  # noqa: BLE001 - a study records every outcome
            res, err = None, str(exc)
        prof.disable()
        t_f = time.process_time() - t0
        m = res.metrics if res is not None else {}
        rec = {"row": i, "design": [float(r.eta_i), float(r.theta_i), float(r.eta_o), float(r.theta_o),
                                    float(r.mu_ratio)], "mode": args.mode, "cpu_axisym_s": round(t_axi, 3),
               "cpu_followed_s": round(t_f, 2), "ratio": round(t_f / t_axi, 1), "error": err,
               **{k: m.get(k) for k in ("asym_n", "followed", "follow_kind", "follow_sec_n", "dE_J", "dy_pole_m",
                                        "V_star_m3", "p_star_Pa", "lower_state_method", "follow_note")},
               "branches": _branches(getattr(res, "follow", None)), "phases": _phases(pstats.Stats(prof))}
        line = json.dumps(rec, default=str)
        if args.out:
            with open(args.out, "a") as f:
                f.write(line + "\n")
        else:
            sys.stdout.write(line + "\n")
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
