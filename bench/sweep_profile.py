"""Where a sweep worker's CPU goes, phase by phase, for the two kinds of paper-grid design.

    .venv/bin/python -m bench.sweep_profile [--path 60] [--descent 24] [--seed 1] [--grid results/paper_grid.parquet]

A seeded sample of the designs of a finished grid run (``--grid``; the designs whose lower state
was found on the path and those found by descent, i.e. re-solved at ``nt = 3``) is solved again
as the sweep solves it (``solve_design`` with the grid's mesh and solver settings, the harmonic
check included), one process, one BLAS thread, process CPU time (``time.process_time``). The
phases are timed by wrapping the functions the solve calls (exclusive times):

* ``mesh``: gmsh (``mesh_scene``), per solve;
* ``trace to V*``: the continuation from rest to the upper state (the volume limit located);
* ``trace after V*``: the post-snap continuation, until the path is back at ``V*`` (path designs)
  or until it stops otherwise (the cavity volume at zero, the step budget: descent designs);
* ``lower state``: :func:`snapjump_cli.fe.axisym.lower_state.find_lower_state` (the stability of the
  path's lower state, or the fixed-volume path);
* ``metrics``: :func:`snapjump_cli.fe.axisym.metrics.snap_metrics`;
* ``check``: :func:`snapjump_cli.fe.stability.harmonics.check_harmonics`;
* ``other``: the rest (model set-up, Python glue).

and, per kind, the compiled corrector's time (the solves' ``t_newton_s``) against the traces'.
The first solve of a design is ``nt2``, the mesh re-check's ``nt3``. ``--out`` writes every
design's answers (``dE_J``, ``dy_pole_m``, the flags, ``n_steps``, ...) and CPU per phase as JSON,
so that two versions can be compared on the same sample (run this file with the other checkout's
interpreter: ``cd OTHER && .venv/bin/python /path/to/bench/sweep_profile.py ...``).

    .venv/bin/python -m bench.sweep_profile --dispatch [--path 30] [--repeat 4]

times the path designs of the sample in one process, alternately with the ahead-of-time kernels'
argument checks as separate per-argument closures (as before 2026-11-28) and as one generated
check per signature (:func:`snapjump_kernels.aot.signature_check`): the CPU per design of each.
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread, as a sweep worker
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from bench.cases import json_value  # noqa: E402
from bench.check_profile import PhaseTimer  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
GRID = REPO / "configs" / "paper_grid.yaml"
ANSWERS = ("status", "dE_J", "dy_pole_m", "h_imp_m", "p_star_Pa", "V_star_m3", "snaps", "self_crossing",
           "mesh_sensitive", "lower_state_method", "asym_first", "asym_n", "asym_V_m3", "asym_lower_stable",
           "n_steps", "n_newton", "mesh_check")
PHASES = ("mesh", "trace to V*", "trace after V*", "lower state", "metrics", "check", "other")


class Clock(PhaseTimer):
    """Exclusive process-CPU time per (solve, phase) (:class:`bench.check_profile.PhaseTimer`'s
    wrapping, keyed by the solve as well)."""

    def __init__(self) -> None:
        self.cpu: dict[tuple[str, str], float] = {}
        self._stack: list[float] = []
        self.solve = "nt2"

    def add(self, phase: str, dt: float) -> None:
        key = (self.solve, phase)
        self.cpu[key] = self.cpu.get(key, 0.0) + dt


def install(clock: Clock) -> None:
    """Wrap the callees of the sweep's solve."""
    from snapjump_cli.fe.axisym import snap
    from snapjump_cli.fe import solve
    from snapjump_cli.mesh import build

    build.mesh_scene = clock.wrap("mesh", build.mesh_scene)
    solve.find_lower_state = clock.wrap("lower state", solve.find_lower_state)
    solve.snap_metrics = clock.wrap("metrics", solve.snap_metrics)
    orig_scene = solve.solve_scene
    count = {"n": 0}

    def scene(*args, **kwargs):
        clock.solve = "nt2" if count["n"] == 0 else "nt3"
        count["n"] += 1
        return orig_scene(*args, **kwargs)

    solve.solve_scene = scene
    clock.reset_count = lambda: count.update(n=0)
    orig_trace = solve._trace

    def traced(*args, **kwargs):
        # the split at the upper state: the tracker's call that finds it marks the time
        mark = {"t": None}
        orig_call = snap.SnapTracker.__call__

        def call(self, path):
            had = self.states.upper is not None
            r = orig_call(self, path)
            if not had and self.states.upper is not None and mark["t"] is None:
                mark["t"] = time.process_time()
            return r

        snap.SnapTracker.__call__ = call
        clock._stack.append(0.0)
        t0 = time.process_time()
        try:
            return orig_trace(*args, **kwargs)
        finally:
            snap.SnapTracker.__call__ = orig_call
            t1 = time.process_time()
            inner = clock._stack.pop()
            tm = mark["t"] if mark["t"] is not None else t1
            clock.add("trace to V*", tm - t0)
            clock.add("trace after V*", t1 - tm - inner)
            if clock._stack:
                clock._stack[-1] += t1 - t0

    solve._trace = traced
    from snapjump_cli.fe.stability import harmonics

    harmonics_check = harmonics.check_harmonics
    harmonics.check_harmonics = clock.wrap("check", harmonics_check)


def pick(grid: Path, n_path: int, n_descent: int, seed: int):
    import pandas as pd

    d = pd.read_parquet(grid)
    ok = d[d.status == "ok"]
    path = ok[ok.lower_state_method == "path"].sample(n=min(n_path, (ok.lower_state_method == "path").sum()),
                                                      random_state=seed)
    desc = ok[ok.lower_state_method == "descent"].sample(
        n=min(n_descent, (ok.lower_state_method == "descent").sum()), random_state=seed)
    return [("path", r) for _, r in path.iterrows()] + [("descent", r) for _, r in desc.iterrows()]


def dispatch_ab(grid: Path, n_path: int, seed: int, repeat: int) -> int:
    """CPU per path design with the per-argument checks of the ahead-of-time kernels against the
    generated whole-signature checks, alternated in one process."""
    import sys

    import snapjump_kernels.aot as aot
    import snapjump_kernels.calls as calls
    from snapjump_cli.fe.stability import harmonics  # noqa: F401 - their kernel names are patched
    from snapjump_cli.fe.axisym import lower_state
    from snapjump_cli.fe.axisym import model
    from snapjump_cli.fe import solve
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.sweep.config import load_config

    exports, ext = aot._table()
    if ext is None:
        print("no ahead-of-time build in use here (make install; SNAPJUMP_NO_AOT unset)")
        return 1
    cfg = load_config(GRID)
    rows = [r for kind, r in pick(grid, n_path, 0, seed)]
    designs = [Design(eta_i=float(r.eta_i), theta_i_deg=float(r.theta_i_deg), eta_o=float(r.eta_o),
                      theta_o_deg=float(r.theta_o_deg), mu_ratio=float(r.mu_ratio), R_i=cfg.R_i, mu_i=cfg.mu_i,
                      J_m=cfg.J_m, t_ring_frac=cfg.t_ring_frac, w_ring_frac=cfg.w_ring_frac) for r in rows]
    new, old = {}, {}
    for mod, names in calls.KERNELS.items():
        for name in names:
            new[name] = getattr(calls, name)
            variants = exports.get(mod, {}).get(name)
            old[name] = aot.dispatch([(getattr(ext, v["export"]), [aot.arg_check(x) for x in v["args"]])
                                      for v in variants], new[name].jit) if variants else new[name]

    def install(table):
        for m in list(sys.modules.values()):
            if getattr(m, "__name__", "").startswith("snapjump_cli"):
                for name, f in table.items():
                    if callable(vars(m).get(name)):
                        setattr(m, name, f)

    solve.warm_up()
    solve.solve_design(designs[0], cfg.mesh, cfg.solver)
    tot = {"per-argument checks": 0.0, "generated check": 0.0}
    for rep in range(repeat):
        for label in (list(tot) if rep % 2 == 0 else list(tot)[::-1]):
            install(old if label.startswith("per") else new)
            t0 = time.process_time()
            for d in designs:
                solve.solve_design(d, cfg.mesh, cfg.solver)
            tot[label] += time.process_time() - t0
    install(new)
    n = repeat * len(designs)
    print(f"load average {os.getloadavg()[0]:.2f}; {len(designs)} path designs x {repeat}, alternated")
    for label, v in tot.items():
        print(f"{label}: {v / n:.4f} CPU-s per design")
    print(f"ratio {tot['generated check'] / tot['per-argument checks']:.3f}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.sweep_profile", description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", type=Path, default=REPO / "results" / "paper_grid.parquet")
    ap.add_argument("--path", type=int, default=60, help="designs with the lower state on the path")
    ap.add_argument("--descent", type=int, default=24, help="designs with the lower state by descent")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="write the answers and CPU per design (JSON)")
    ap.add_argument("--dispatch", action="store_true", help="A/B of the aot argument checks on the path designs")
    ap.add_argument("--repeat", type=int, default=4, help="with --dispatch: alternations")
    a = ap.parse_args(argv)
    if a.dispatch:
        return dispatch_ab(a.grid, a.path, a.seed, a.repeat)

    from snapjump_cli.fe import solve
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.sweep.config import load_config

    cfg = load_config(GRID)
    items = pick(a.grid, a.path, a.descent, a.seed)
    solve.warm_up()
    clock = Clock()
    install(clock)

    def design(r):
        return Design(eta_i=float(r.eta_i), theta_i_deg=float(r.theta_i_deg), eta_o=float(r.eta_o),
                      theta_o_deg=float(r.theta_o_deg), mu_ratio=float(r.mu_ratio), R_i=cfg.R_i, mu_i=cfg.mu_i,
                      J_m=cfg.J_m, t_ring_frac=cfg.t_ring_frac, w_ring_frac=cfg.w_ring_frac)

    solve.solve_design(design(items[0][1]), cfg.mesh, cfg.solver)  # compile / load outside the timings
    rows = []
    totals: dict[str, dict] = {}
    for kind, r in items:
        clock.cpu = {}
        clock.reset_count()
        t0 = time.process_time()
        try:
            m = solve.solve_design(design(r), cfg.mesh, cfg.solver)
            m["status"] = "ok" if m.get("snaps") else "no_snap"
        except solve.SolveFailed as exc:
            m = {"status": "failed", "error": str(exc)[:200]}
        dt = time.process_time() - t0
        clock.add("other", dt - sum(clock.cpu.values()))
        kind_now = "descent" if m.get("mesh_check") else kind
        t = totals.setdefault(kind_now, {"n": 0, "cpu": 0.0, "phases": {}, "corrector": 0.0})
        t["n"] += 1
        t["cpu"] += dt
        t["corrector"] += float(m.get("t_newton_s") or 0.0)  # the compiled corrector's calls (in the traces)
        for k, v in clock.cpu.items():
            t["phases"][k] = t["phases"].get(k, 0.0) + v
        rows.append({"key": str(r.key), "kind": kind, "cpu_s": dt,
                     "phases": {f"{s}/{p}": v for (s, p), v in clock.cpu.items()},
                     **{k: json_value(m.get(k)) for k in ANSWERS}})
    print(f"load average {os.getloadavg()[0]:.2f}; grid {a.grid}; seed {a.seed}")
    for kind, t in totals.items():
        n = t["n"]
        print(f"\n{kind}: {n} designs, {t['cpu'] / n:.4f} CPU-s per design")
        print("| solve | phase | CPU-s per design |\n|---|---|---|")
        for (s, p), v in sorted(t["phases"].items(), key=lambda kv: (kv[0][0], PHASES.index(kv[0][1]))):
            print(f"| {s} | {p} | {v / n:.4f} |")
        traces = sum(v for (s, p), v in t["phases"].items() if p.startswith("trace"))
        print(f"compiled corrector (the solves' t_newton_s, wall): {t['corrector'] / n:.4f} s per design, "
              f"{100 * t['corrector'] / max(traces, 1e-300):.0f} % of the traces' CPU (its few calls outside them, "
              "the snap roots and the check's bisection, included)")
    if a.out is not None:
        a.out.write_text(json.dumps({"totals": {k: {**v, "phases": {f"{s}/{p}": x for (s, p), x in v["phases"].items()}}
                                                for k, v in totals.items()}, "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
