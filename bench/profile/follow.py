"""Per-design CPU profile of a followed branch (issue 36: where the followed designs' time goes).

    .venv/bin/python -m bench.profile.follow [SCENE ...] [--N N] [--cprofile [K]] [--json PATH]
    .venv/bin/python -m bench.profile.follow --sample bench/harmonics_sample/follow_strata.yaml \\
        --rows 0 1 2 [--cprofile]

``SCENE`` is a named design (``A`` .. ``D``) or one of the caps of :data:`CAPS` (default ``B``),
solved at the default mesh with the harmonic check ``n <= 4``. ``--sample CONFIG --rows I ...``
profiles rows ``I`` of a sweep config's design list instead (e.g. the stratified samples in
``bench/harmonics_sample/``), with that config's mesh and solver settings, as the sweep solves
them (without the sweep's mesh re-check).

For each design, in this process, process CPU time (``time.process_time``; one BLAS thread):

1. the axisymmetric solve and the harmonic check (the first design's includes the one-time costs
   of the process: imports, loading the compiled kernels), and again warm;
2. a short followed trace (3 steps) to compile the multi-harmonic kernels (JIT) outside the timing;
3. the followed answer exactly as a followed sweep computes it (``followed_metrics``: the
   bifurcation located, the branch traced, for ``n_c >= 2`` the secondary check and the branch
   that leaves it, the lower state), with its steps and assemblies and the ratio to the warm
   axisymmetric solve and check, within the solver's ``time_limit_s`` as in a sweep;
4. with ``--cprofile [K]``, the followed answer once more under :mod:`cProfile` (CPU clock): the
   cumulative time of the stages named in :data:`STAGES` that ran, then the ``K`` (default 15)
   functions with the most exclusive time (a numba kernel's time is counted in the Python
   function that calls it). cProfile slows the Python parts; read the shares, not the totals.

Prints one markdown table row per design (and the breakdowns); ``--json`` writes the numbers.
"""
from __future__ import annotations

import argparse
import cProfile
import dataclasses
import importlib
import json
import pstats
import time
from pathlib import Path
from typing import Any

#: caps of the paper's Fig. S16 and a clamped cap that goes asymmetric (``CapScene`` arguments)
CAPS = {
    "S16-12.5-70": dict(theta_deg=70.0, eta=12.5, bc="ring-roller"),
    "S16-10-60": dict(theta_deg=60.0, eta=10.0, bc="ring-roller"),
    "clamped-30-50": dict(theta_deg=30.0, eta=50.0, bc="clamped"),
}

#: the stages whose cumulative time ``--cprofile`` reports, by function name (whichever module
#: holds them)
STAGES = ("locate_bifurcation", "follow_branch", "trace_branch", "follow_secondary", "branch_stability",
          "locate_secondary", "jump_off_branch", "find_lower_state", "descend_at_volume", "linearize",
          "residual", "energy", "lowest_eigen", "extra_eigen")

#: where the library's names live (the first module that has the name wins): the followed branch's
#: entry points moved with the ``fe/`` split by stage; the old paths are kept as fallbacks
_WHERE = {
    "solve_scene": ("snapjump_cli.fe.solve",),
    "time_limit": ("snapjump_cli.fe.limits", "snapjump_cli.fe.continuation.limits"),
    "TimeLimitExceeded": ("snapjump_cli.fe.limits", "snapjump_cli.fe.continuation.limits"),
    "check_harmonics": ("snapjump_cli.fe.stability.harmonics", "snapjump_cli.fe.stability.check",
                        "snapjump_cli.fe.harmonics"),
    "followed_metrics": ("snapjump_cli.fe.branch.followed", "snapjump_cli.fe.branch.follow",
                         "snapjump_cli.fe.branch.trace", "snapjump_cli.fe.branch", "snapjump_cli.fe.follow"),
    "locate_bifurcation": ("snapjump_cli.fe.branch.bifurcation", "snapjump_cli.fe.branch", "snapjump_cli.fe.follow"),
    "follow_branch": ("snapjump_cli.fe.branch.trace", "snapjump_cli.fe.branch.follow", "snapjump_cli.fe.branch",
                      "snapjump_cli.fe.follow"),
    "default_harmonics": ("snapjump_cli.fe.branch.bifurcation", "snapjump_cli.fe.branch.trace",
                          "snapjump_cli.fe.branch.model", "snapjump_cli.fe.branch", "snapjump_cli.fe.follow"),
}


def api() -> dict[str, Any]:
    """The library functions this profile calls, looked up in :data:`_WHERE`; raises
    ``ImportError`` naming the one not found (the test suite checks that all resolve)."""
    out = {}
    for name, modules in _WHERE.items():
        for mod in modules:
            try:
                m = importlib.import_module(mod)
            except ImportError:
                continue
            if hasattr(m, name):
                out[name] = getattr(m, name)
                break
        else:
            raise ImportError(f"{name} not found in any of {', '.join(modules)}")
    return out


def scenes(names: list[str], sample: Path | None, rows: list[int]) -> list[tuple[str, Any, Any, Any]]:
    """``(label, scene, mesh, solver)`` for each design to profile."""
    from snapjump_cli.geometry.caps import CapScene, Design
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.settings import MeshSettings, SolverSettings

    if sample is not None:
        from snapjump_cli.sweep.config import load_config

        cfg = load_config(sample)
        points = list(cfg.designs())
        solver = cfg.solver if cfg.solver.harmonics > 0 else dataclasses.replace(cfg.solver, harmonics=4)
        return [(f"{sample.stem}#{i}", Design(**points[i].design_kwargs()), cfg.mesh, solver) for i in rows]
    out = []
    for name in names:
        scene = CapScene(**CAPS[name]) if name in CAPS else get_design(name)
        out.append((name, scene, MeshSettings(), SolverSettings(harmonics=4)))
    return out


def _value(check: Any, key: str) -> Any:
    """A value of the harmonic check's answer (a dict, or a typed result with attributes)."""
    return check.get(key) if isinstance(check, dict) else getattr(check, key, None)


def _followed(fns: dict[str, Any], res, chk, N: int) -> tuple[dict, Any]:
    """``followed_metrics``' answer as ``(values, branch)``, whether it returns that pair or a
    typed answer with ``values`` and ``branch``."""
    ans = fns["followed_metrics"](res, chk, N=N or None)
    if isinstance(ans, tuple):
        return ans
    return ans.values, ans.branch


def profile_one(label: str, scene, mesh, solver, fns: dict[str, Any], N: int, top: int | None) -> dict[str, Any]:
    """Profile one design (steps 1-4 of the module's docstring); returns the numbers."""
    t0 = time.process_time()
    res = fns["solve_scene"](scene, mesh, solver)
    chk = fns["check_harmonics"](res, solver.harmonics)
    t_first = time.process_time() - t0
    t0 = time.process_time()
    res = fns["solve_scene"](scene, mesh, solver)
    chk = fns["check_harmonics"](res, solver.harmonics)
    t_axi = time.process_time() - t0
    row: dict[str, Any] = {"design": label, "cpu_axisym_check_first_s": t_first, "cpu_axisym_check_s": t_axi,
                           "asym_first": bool(_value(chk, "asym_first")), "asym_n": _value(chk, "asym_n")}
    if not row["asym_first"]:
        return row
    n = int(row["asym_n"])
    bif = fns["locate_bifurcation"](res, n)
    if bif is not None:  # compile the multi-harmonic kernels (JIT) outside the timing
        fns["follow_branch"](res, bif, fns["default_harmonics"](n, N or None), max_steps=3)
    t0 = time.process_time()
    try:
        with fns["time_limit"](solver.time_limit_s):
            out, fr = _followed(fns, res, chk, N)
    except fns["TimeLimitExceeded"] as exc:
        out, fr = {"follow_note": f"at the time limit: {exc}"}, None
        top = None
    row["cpu_followed_s"] = time.process_time() - t0
    row["ratio"] = row["cpu_followed_s"] / t_axi
    path, model = getattr(fr, "path", None), getattr(fr, "model", None)
    row["steps"] = len(path.points) - 1 if path is not None else None
    row["assemblies"] = getattr(model, "n_assemblies", None)
    row["harmonics"] = [int(h) for h in model.hn] if model is not None else None
    row.update({k: out.get(k) for k in ("followed", "follow_kind", "dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa",
                                        "follow_note")})
    if top is not None:
        prof = cProfile.Profile(time.process_time)
        prof.runcall(_followed, fns, res, chk, N)
        st = pstats.Stats(prof)
        total = max(sum(v[2] for v in st.stats.values()), 1e-12)
        cum: dict[str, float] = {}
        for (_, _, fname), (_, _, tt, ct, _) in st.stats.items():
            if fname in STAGES:
                cum[fname] = max(cum.get(fname, 0.0), ct)
        excl = sorted(((v[2], f"{Path(k[0]).parent.name}/{Path(k[0]).name}:{k[2]}") for k, v in st.stats.items()),
                      reverse=True)[:top]
        row["cprofile"] = {"total_s": total, "stages_cum_s": cum, "top_exclusive_s": [[n_, t] for t, n_ in excl]}
    return row


def _fmt(v: Any, nd: int = 3) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.{nd}g}"
    return str(v)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.profile.follow", description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", default=["B"], help="named designs A..D or caps of CAPS (default B)")
    ap.add_argument("--sample", type=Path, default=None, help="a sweep config whose design list to take rows from")
    ap.add_argument("--rows", type=int, nargs="+", default=[0], help="rows of --sample (0-based)")
    ap.add_argument("--N", type=int, default=0, help="highest harmonic kept (default 4 n_c, as the sweep)")
    ap.add_argument("--cprofile", type=int, nargs="?", const=15, default=None, metavar="K",
                    help="also break the followed solve down under cProfile (the K functions with most exclusive time)")
    ap.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    a = ap.parse_args(argv)
    fns = api()
    rows = []
    print("| design | n_c | axisym + check CPU-s (first / warm) | followed CPU-s | ratio | steps | assemblies "
          "| kind | dE_J | note |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label, scene, mesh, solver in scenes(a.scenes, a.sample, a.rows):
        r = profile_one(label, scene, mesh, solver, fns, a.N, a.cprofile)
        rows.append(r)
        print(f"| {label} | {_fmt(r.get('asym_n'))} | {r['cpu_axisym_check_first_s']:.3f} / "
              f"{r['cpu_axisym_check_s']:.3f} | {_fmt(r.get('cpu_followed_s'))} | {_fmt(r.get('ratio'))} "
              f"| {_fmt(r.get('steps'))} | {_fmt(r.get('assemblies'))} | {_fmt(r.get('follow_kind'))} "
              f"| {_fmt(r.get('dE_J'), 4)} | {r.get('follow_note') or ('stays axisymmetric' if not r['asym_first'] else '')} |",
              flush=True)
    for r in rows:
        cp = r.get("cprofile")
        if not cp:
            continue
        print(f"\n### {r['design']} under cProfile: {cp['total_s']:.2f} CPU-s\n\n| stage (cumulative) | CPU-s | share |")
        print("|---|---|---|")
        for k in STAGES:
            if k in cp["stages_cum_s"]:
                v = cp["stages_cum_s"][k]
                print(f"| {k} | {v:.2f} | {100 * v / cp['total_s']:.0f} % |")
        print("\n| function (exclusive) | CPU-s | share |\n|---|---|---|")
        for name, v in cp["top_exclusive_s"]:
            print(f"| {name} | {v:.2f} | {100 * v / cp['total_s']:.0f} % |")
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(rows, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
