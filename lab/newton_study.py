"""Reproduce the iteration-count study of the speed work (docs/performance.md, issue 10 notes).

    .venv/bin/python lab/newton_study.py variants --n 20            # counts per continuation variant
    .venv/bin/python lab/newton_study.py history --design D         # Newton residuals per step
    .venv/bin/python lab/newton_study.py perturb --design D         # Newton from perturbed states
    .venv/bin/python lab/newton_study.py recheck results/paper_grid.parquet   # nt 2 vs nt 3 re-check
    .venv/bin/python lab/newton_study.py recheck results/paper_grid.parquet --flags -j 2   # ... and flags
    .venv/bin/python lab/newton_study.py predictor --design D       # predictor errors per step
    .venv/bin/python lab/newton_study.py turning --design D         # where the path turns
    .venv/bin/python lab/newton_study.py pressure --design D        # element pressure at predictions
    .venv/bin/python lab/newton_study.py accepted --design D        # residual of the accepted states
    .venv/bin/python lab/newton_study.py contraction D grid-1543    # Newton contraction, steps kept and failed

``variants`` solves the first N valid, snapping designs of the seeded benchmark sample (the grid
rows of bench/regression/baseline.json) as the sweep does and prints the assemblies, steps and
Newton iterations (deterministic, so comparable on a loaded machine) and the largest change of dE,
dy_pole, h_imp and of the flags against the baseline, for the current settings, tol_path 1e-5,
1e-4, 1e-3 and n_opt 3 and 6. ``history`` prints the relative residual of every Newton iteration of
every corrector call (the Python corrector). ``perturb`` runs a pressure-controlled Newton from
states between two path points. ``recheck`` reads a result file and prints how far the nt = 3
re-check moved dE and dy_pole on the rows whose lower state is off the path; with ``--flags`` it
also solves those designs again at the grid's mesh (nt = 2, no re-check) and compares their
``self_crossing`` flag and lower-state method with the reported (nt = 3) ones: whether the re-check
needs its own trace. ``predictor`` measures, on the traced path, how far the tangent, the cubic
Hermite (the one used) and a quintic Hermite through three points predict each next point
(relative to the step, in the arc-length metric). ``turning`` prints the median turn per step after
the snap in each plane of the measures: what limits the steps. ``pressure`` prints,
for the path steps, how far the condensed element pressure ``kappa M^-1 g(u)`` of the predicted
state is from that of the accepted state (relative, whole field): the reason for the mixed
linearisation (docs/numerics.md). ``accepted`` prints the relative residual of the path states
that the error test accepted (median, 90th percentile, largest). ``contraction`` prints how much
each Newton correction of a path step shrinks against the one before, for the steps that converged
and those that failed (with the give-up rule ``theta_max`` switched off): the basis of that rule.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # bench/ (the baseline and the sample's scenes)


def _variants(a: argparse.Namespace) -> None:
    from bench.regression import BASELINE, scenes
    from snapjump_cli.fe import continuation as C
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.fe.solve import solve_design

    base = {r["id"]: r for r in json.loads(Path(BASELINE).read_text())["rows"]}
    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    sample = [s for s in scenes(240, 10) if s["kind"] == "grid" and base[s["id"]]["status"] == "ok"][: a.n]
    orig_init = C.ContinuationSettings.__init__
    for label, tol_path, n_opt in (("current", None, None), ("tol_path 1e-5", 1e-5, None),
                                   ("tol_path 1e-4", 1e-4, None), ("tol_path 1e-3", 1e-3, None),
                                   ("n_opt 3", None, 3), ("n_opt 6", None, 6)):
        solver = dataclasses.replace(cfg.solver, tol_path=tol_path) if tol_path else cfg.solver
        C.ContinuationSettings.__init__ = (
            (lambda self, *x, _n=n_opt, **k: orig_init(self, *x, **{**k, "n_opt": _n})) if n_opt else orig_init)
        tot = Counter()
        worst, flags = 0.0, []
        for s in sample:
            m = solve_design(Design(**s["params"]), cfg.mesh, solver)
            tot.update({k: m.get(k) or 0 for k in ("n_assemblies", "n_steps", "n_newton")})
            b = base[s["id"]]
            flags += [(s["id"], k) for k in ("snaps", "self_crossing", "mesh_sensitive") if bool(m[k]) != bool(b[k])]
            worst = max([worst] + [abs(m[k] - b[k]) / abs(b[k]) for k in ("dE_J", "dy_pole_m", "h_imp_m") if b.get(k)])
        C.ContinuationSettings.__init__ = orig_init
        print(json.dumps({"variant": label, **tot, "worst_rel_change": f"{worst:.2e}", "flag_changes": flags}),
              flush=True)


#: The grid's five design parameters, in the order of a comma-separated ``--design``.
_PARAMS = ("eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio")


def _design_of(params) -> "Design":
    from snapjump_cli.geometry.caps import Design

    return Design(**dict(zip(_PARAMS, map(float, params))))


def _design(name: str):
    """A named design, ``grid-NNNN`` (the paper grid's point NNNN) or ``eta_i,theta_i,eta_o,theta_o,mu_ratio``."""
    from snapjump_cli.geometry.designs import get_design

    if name.startswith("grid-"):
        from snapjump_cli.sweep.config import load_config
        from snapjump_cli.geometry.caps import Design

        points = list(load_config(REPO / "configs" / "paper_grid.yaml").designs())
        return Design(**points[int(name[5:])].design_kwargs())
    return _design_of(name.split(",")) if "," in name else get_design(name)


def _history(a: argparse.Namespace) -> None:
    from snapjump_cli.fe import continuation as C
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.fe.solve import solve_scene

    hist: list[list] = []
    orig_scale, orig_correct = C.Tracer.residual_scale, C.Tracer.correct

    def residual_scale(self, lin, dz_du, p):
        ref = orig_scale(self, lin, dz_du, p)
        hist[-1].append(float(np.linalg.norm(lin.R)) / ref)
        return ref

    def correct(self, *x, **k):
        hist.append([])
        r = orig_correct(self, *x, **k)
        hist[-1].append("ok" if r is not None else "FAIL")
        return r

    C.Tracer.residual_scale, C.Tracer.correct = residual_scale, correct
    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    m = solve_scene(_design(a.design), cfg.mesh, cfg.solver, fused=False).metrics
    print(f"{a.design}: steps {m['n_steps']}, Newton {m['n_newton']}, rejected {m['n_rejected']}")
    print("solves per corrector call:", dict(sorted(Counter(len(h) - 1 for h in hist).items())))
    for h in hist[a.skip: a.skip + a.show]:
        print(" ".join(f"{x:.1e}" if isinstance(x, float) else x for x in h))


def _perturb(a: argparse.Namespace) -> None:
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.fe.solve import solve_scene

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    r = solve_scene(_design(a.design), cfg.mesh, cfg.solver)
    model, pts = r.model, r.path.points
    for k in (10, 40, 80):
        for eps in (1.0, 0.3, 0.1, 0.01):  # the state eps of the way to the next path point, at p_k
            u, p, seq = pts[k].u + eps * (pts[k + 1].u - pts[k].u), pts[k].p, []
            for _ in range(7):
                lin = model.linearize(u, p)
                if lin is None:
                    seq.append(float("nan"))
                    break
                seq.append(float(np.linalg.norm(lin.R) / (np.linalg.norm(lin.g) * abs(p))))
                x = lin.factor(np.zeros(model.n), 1.0).solve(np.concatenate([-lin.R, [0.0]]))
                u = u + x[:-1]
            print(k, eps, " ".join(f"{s:.1e}" for s in seq))


def _recheck(a: argparse.Namespace) -> None:
    import pandas as pd

    from snapjump_cli.sweep.results import read_results

    if a.results.is_dir():  # the part files of an unfinished sweep
        df = pd.concat([read_results(f) for f in sorted(a.results.glob("part-*.parquet"))]).drop_duplicates("key")
    else:
        df = read_results(a.results)
    d = df[(df["status"] == "ok") & (df["lower_state_method"] == "descent")]
    for col, coarse in (("dE_J", "dE_J_coarse"), ("dy_pole_m", "dy_pole_m_coarse")):
        rel = ((d[col] - d[coarse]).abs() / d[col]).dropna()
        print(f"{col}: {len(rel)} rows re-checked at nt = 3; change median {rel.median():.2%}, "
              f"90 % {rel.quantile(0.9):.2%}, max {rel.max():.2%}")
    if a.flags:
        from joblib import Parallel, delayed

        params = [tuple(float(r[k]) for k in _PARAMS) for _, r in d.iterrows()]
        got = Parallel(n_jobs=a.jobs)(delayed(_coarse_flags)(x) for x in params)
        sc_nt3 = [bool(v) for v in d["self_crossing"]]
        same = sum(g[0] == s3 for g, s3 in zip(got, sc_nt3))
        methods = Counter(g[1] for g in got)
        print(f"the {len(got)} rows solved again at nt = 2 (no re-check): lower state {dict(methods)}; "
              f"self_crossing equal to the reported (nt = 3) one on {same}")
        for g, s3, x in zip(got, sc_nt3, params):
            if g[0] != s3:
                print(f"  {x}: nt 2 {g[0]}, nt 3 {s3}")


def _coarse_flags(params: tuple) -> tuple:
    """``(self_crossing, lower_state_method)`` of a grid design solved at the grid's mesh alone."""
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.fe.solve import SolveFailed, solve_scene

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    try:
        m = solve_scene(_design_of(params), cfg.mesh, cfg.solver).metrics
    except SolveFailed as exc:
        return None, f"failed: {exc}"[:60]
    return bool(m["self_crossing"]), m["lower_state_method"]


def _grid_solve(name: str):
    """The scene result of ``name`` solved at the paper grid's mesh (no re-check)."""
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.fe.solve import solve_scene

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    return solve_scene(_design(name), cfg.mesh, cfg.solver)


def _hermite(nodes, vals, ders, x):
    """Hermite interpolation of values and first derivatives at ``nodes``, evaluated at ``x``."""
    z = np.repeat(nodes, 2)
    prev = [vals[i // 2] for i in range(len(z))]
    coef = [prev[0]]
    for j in range(1, len(z)):
        prev = [ders[i // 2] if z[i + j] == z[i] else (prev[i + 1] - prev[i]) / (z[i + j] - z[i])
                for i in range(len(z) - j)]
        coef.append(prev[0])
    out = coef[-1]
    for j in range(len(z) - 2, -1, -1):
        out = coef[j] + (x - z[j]) * out
    return out


def _predictor(a: argparse.Namespace) -> None:
    r = _grid_solve(a.design)
    tr, pts = r.tracer, r.path.points
    al = tr.alpha

    def x(pt):
        return np.concatenate([pt.u, [pt.p]])

    def dx(pt):
        return np.concatenate([pt.du_ds, [pt.dp_ds]])

    err = {"tangent": [], "cubic Hermite (used)": [], "quintic Hermite": []}
    for k in range(3, len(pts) - 1):
        p0, p1, p2, p3 = pts[k - 2], pts[k - 1], pts[k], pts[k + 1]
        ds = p3.s - p2.s
        preds = {"tangent": x(p2) + ds * dx(p2),
                 "cubic Hermite (used)": _hermite(np.array([p1.s, p2.s]), [x(p1), x(p2)], [dx(p1), dx(p2)], p3.s),
                 "quintic Hermite": _hermite(np.array([p0.s, p1.s, p2.s]), [x(p0), x(p1), x(p2)],
                                             [dx(p0), dx(p1), dx(p2)], p3.s)}
        for name, pr in preds.items():
            z, _, _ = tr.zeta(pr[:-1], pr[-1])
            dz, du = z - p3.zeta, al * (pr[:-1] - p3.u)
            err[name].append(float(np.sqrt(dz @ dz + du @ du)) / ds)
    for name, e in err.items():
        print(f"{a.design}, {name}: predictor error / step, 10 / 50 / 90 %: "
              + " / ".join(f"{v:.2g}" for v in np.percentile(e, [10, 50, 90])))


def _turning(a: argparse.Namespace) -> None:
    r = _grid_solve(a.design)
    pts, kb = r.path.points, r.states.k_before
    T = np.array([pt.tangent for pt in pts[kb:]])

    def turn(idx):
        a_, b_ = T[:-1][:, idx], T[1:][:, idx]
        c = np.sum(a_ * b_, axis=1) / (np.linalg.norm(a_, axis=1) * np.linalg.norm(b_, axis=1))
        return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))

    print(f"{a.design}: {len(T) - 1} steps after the volume limit; median (90 %) turn per step in degrees:")
    for label, idx in (("(V, p)", [0, 1]), ("(V, w)", [0, 2]), ("(p, w)", [1, 2]), ("(V, p, w)", [0, 1, 2])):
        t = turn(idx)
        print(f"  {label}: {np.median(t):.2f} ({np.percentile(t, 90):.2f})")


def _riks_calls(design: str, record):
    """Solve ``design`` through the Python corrector; ``record(tracer, u_pred, p_pred, result)`` is
    called after every Riks corrector call that converged with the error test."""
    from snapjump_cli.fe import continuation as C
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.fe.solve import solve_scene

    orig = C.Tracer.correct

    def correct(self, u, p, z0, t, ds, target=None, tol=None, aux=None, error_test=False):
        res = orig(self, u, p, z0, t, ds, target, tol, aux, error_test)
        if res is not None and target is None and error_test:
            record(self, u, p, res[0])
        return res

    C.Tracer.correct = correct
    try:
        cfg = load_config(REPO / "configs" / "paper_grid.yaml")
        return solve_scene(_design(design), cfg.mesh, cfg.solver, fused=False).metrics
    finally:
        C.Tracer.correct = orig


def _pressure(a: argparse.Namespace) -> None:
    errs = []

    def record(tr, u, p, acc):
        pred = tr.pb.linearize(u, p).aux
        final = tr.pb.linearize(acc.u, acc.p).aux
        errs.append(float(np.linalg.norm(pred - final) / np.linalg.norm(final)))

    m = _riks_calls(a.design, record)
    e = np.array(errs)
    print(f"{a.design}: {len(e)} path steps; condensed element pressure of the predicted state against the "
          f"accepted one (relative): min {e.min():.2g}, median {np.median(e):.2g}, max {e.max():.3g} "
          f"({m['n_steps']} steps, {m['n_newton']} Newton iterations)")


def _accepted(a: argparse.Namespace) -> None:
    out = []

    def record(tr, u, p, acc):
        lin = tr.pb.linearize(acc.u, acc.p)
        ref = np.linalg.norm(lin.g) * max(abs(acc.p), 1e-3 * tr.sc[1])
        out.append(float(np.linalg.norm(lin.R) / ref))

    _riks_calls(a.design, record)
    r = np.array(out)
    print(f"{a.design}: {len(r)} path states accepted by the error test; residual / pressure load: median "
          f"{np.median(r):.2g}, 90th percentile {np.quantile(r, 0.9):.2g}, largest {r.max():.2g}")


def _contraction(a: argparse.Namespace) -> None:
    """Contraction of the Newton corrections (each one over the one before) on the path steps, for
    the steps that converged and those that failed, with the give-up rule switched off: why Newton
    stops at a contraction above ``theta_max`` (ContinuationSettings).

    Needs the tracer's ``on_increment`` hook, which the library no longer has (issue 35): this
    study is retired; ``git show 51d9ff8:lab/newton_study.py`` runs it on that commit."""
    raise SystemExit("lab/newton_study.py contraction: the tracer's on_increment hook was removed (issue 35); "
                     "run it on commit 51d9ff8")
    from snapjump_cli.fe import continuation as C
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.fe.solve import solve_scene

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    orig_correct, orig_from = C.Tracer.correct, C.ContinuationSettings.from_solver.__func__
    for name in a.designs:
        calls: list[tuple[bool, list[float]]] = []

        def correct(self, u, p, z0, t, ds, target=None, tol=None, aux=None, error_test=False):
            incs: list[float] = []
            self.on_increment = lambda it, inc: incs.append(inc)
            res = orig_correct(self, u, p, z0, t, ds, target, tol, aux, error_test)
            self.on_increment = None
            if target is None and error_test:
                calls.append((res is not None, incs))
            return res

        C.Tracer.correct = correct
        C.ContinuationSettings.from_solver = classmethod(
            lambda cls, *x, **k: orig_from(cls, *x, **{**k, "theta_max": float("inf")}))
        try:
            m = solve_scene(_design(name), cfg.mesh, cfg.solver, fused=False).metrics
        finally:
            C.Tracer.correct = orig_correct
            C.ContinuationSettings.from_solver = classmethod(orig_from)
        print(f"{name}: {m['n_steps']} steps; path corrector calls {len(calls)}, "
              f"{sum(not ok for ok, _ in calls)} failed")
        for label, want in (("converged", True), ("failed", False)):
            th = [i[k + 1] / i[k] for ok, i in calls if ok == want for k in range(len(i) - 1)]
            if th:
                print(f"  {label}: contraction median {np.median(th):.1e}, 90th percentile "
                      f"{np.quantile(th, 0.9):.1e}, largest {max(th):.2g}; element passes "
                      f"{sum(len(i) + (0 if ok else 1) for ok, i in calls if ok == want)}")
        ok_incs = [i for ok, i in calls if ok]
        for thr in (0.25, 0.5, 0.75):
            n = sum(1 for i in ok_incs if any(i[k + 1] > thr * i[k] for k in range(len(i) - 1)))
            print(f"  converged steps with a contraction above {thr}: {n} of {len(ok_incs)}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    v = sub.add_parser("variants")
    v.add_argument("--n", type=int, default=20)
    h = sub.add_parser("history")
    h.add_argument("--design", default="D", help="a named design or eta_i,theta_i,eta_o,theta_o,mu_ratio")
    h.add_argument("--skip", type=int, default=5)
    h.add_argument("--show", type=int, default=35)
    p = sub.add_parser("perturb")
    p.add_argument("--design", default="D")
    r = sub.add_parser("recheck")
    r.add_argument("results", type=Path, help="a result file, or the .parts folder of an unfinished sweep")
    r.add_argument("--flags", action="store_true", help="also solve the off-path rows at nt = 2 and compare flags")
    r.add_argument("-j", "--jobs", type=int, default=2)
    for name in ("pressure", "accepted", "predictor", "turning"):
        sub.add_parser(name).add_argument("--design", default="D")
    c = sub.add_parser("contraction")
    c.add_argument("designs", nargs="*", default=["D", "C", "grid-0037", "grid-1543", "grid-2239"],
                   help="named designs, grid-NNNN or eta_i,theta_i,eta_o,theta_o,mu_ratio")
    a = ap.parse_args(argv)
    {"variants": _variants, "history": _history, "perturb": _perturb, "recheck": _recheck, "pressure": _pressure,
     "accepted": _accepted, "predictor": _predictor, "turning": _turning, "contraction": _contraction}[a.what](a)
    return 0


if __name__ == "__main__":
    sys.exit(main())
