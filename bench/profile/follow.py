"""Per-design CPU profile of a followed branch (issue 36: where the followed designs' time goes).

    .venv/bin/python -m bench.profile.follow [SCENE ...] [--N N] [--mode actuator|full] [--cprofile [K]]
                                             [--landing] [--compare] [--compare-axisym-first]
                                             [--condensed] [--json PATH]
    .venv/bin/python -m bench.profile.follow --sample bench/harmonics_sample/follow_strata.yaml \\
        --rows 0 1 2 [--cprofile]

``SCENE`` is a named design (``A`` .. ``D``) or one of the caps of :data:`CAPS` (default ``B``),
solved at the default mesh with the harmonic check ``n <= 4``. ``--sample CONFIG --rows I ...``
profiles rows ``I`` of a sweep config's design list instead (e.g. the stratified samples in
``bench/harmonics_sample/``), with that config's mesh and solver settings, as the sweep solves
them (without the sweep's mesh re-check).

For each design, in this process, process CPU time (``time.process_time``; one BLAS thread):

1. the axisymmetric solve and the harmonic check (the first design's includes the one-time costs
   of the process: imports, loading the compiled kernels), and again warm, ``--repeat`` times (the
   least is the ratio's denominator: on a shared machine one 0.1 s solve varies by +-40 %);
2. a short followed trace (3 steps) to compile the multi-harmonic kernels (JIT) outside the timing;
3. the followed answer exactly as a followed sweep computes it (``followed_metrics``: the
   bifurcation located, the branch traced, for ``n_c >= 2`` the secondary check and the branch
   that leaves it, the lower state; ``--mode``: ``solver.follow_mode``), with its steps and
   assemblies, every branch traced (its points and how many of them come before its upper state:
   the states the actuator passes through; how its lower state was found) and the ratio to the
   warm axisymmetric solve and check, within the solver's ``time_limit_s`` as in a sweep
   (``--json`` also holds the answer's model's factorisations, those of them a descent gave up at a
   negative pivot, and the assemblies of the branch the answer left); with ``--repeat-followed K``
   the followed answer is computed up to ``K`` times (again only while a solve takes at most
   :data:`REPEAT_FOLLOWED_BELOW_S`) and its least CPU is the ratio's numerator, as the denominator
   is the least of ``--repeat`` (every repeat must give the same answer values, else it stops);
4. with ``--cprofile [K]``, the followed answer once more under :mod:`cProfile` (CPU clock): the
   cumulative time of the stages named in :data:`STAGES` that ran, then the ``K`` (default 15)
   functions with the most exclusive time (a numba kernel's time is counted in the Python
   function that calls it). cProfile slows the Python parts; read the shares, not the totals.

5. with ``--landing``, the experiment of stopping the branch at its upper state and searching the
   state the actuator lands on at fixed volume from there (the fixed-volume path, then the energy
   descent: ``find_lower_state``), against the answer of step 3: CPU, how it was found, and the
   energy of the two lower states.

6. with ``--compare``, the other follow mode on the same solve: its CPU, how many answer values
   differ from this mode's (timings excluded) and the distance between the two lower states
   (relative to the norm of this mode's): where the modes land on the same state, and how much
   the actuator mode saves against the reference.

Prints one markdown table row per design (and the breakdowns); ``--json`` writes the numbers.
"""
from __future__ import annotations

import argparse
import cProfile
import dataclasses
import json
import logging
import pstats
import time
from pathlib import Path
from typing import Any

from bench.profile.answers import ANSWER_KEYS  # the answers whose differences answer_diff reports one by one
from snapjump_cli.fe.axisym.lower_state import find_lower_state
from snapjump_cli.fe.branch.bifurcation import default_harmonics, locate_bifurcation
from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.branch.trace import follow_branch
from snapjump_cli.fe.limits import TimeLimitExceeded, time_limit
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics

#: caps of the paper's Fig. S16 and a clamped cap that goes asymmetric (``CapScene`` arguments)
CAPS = {
    "S16-12.5-70": dict(theta_deg=70.0, eta=12.5, bc="ring-roller"),
    "S16-10-60": dict(theta_deg=60.0, eta=10.0, bc="ring-roller"),
    "clamped-30-50": dict(theta_deg=30.0, eta=50.0, bc="clamped"),
}

#: the stages whose cumulative time ``--cprofile`` reports, by function name
STAGES = ("locate_bifurcation", "first_bifurcation", "follow_branch", "trace_branch", "follow_secondary", "branch_stability",
          "locate_secondary", "jump_off_branch", "find_lower_state", "snap_at_fixed_volume", "descend_at_volume",
          "linearize", "residual", "energy", "lowest_eigen", "extra_eigen", "block_band", "outside_modes")


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


def branches(fr) -> list[dict[str, Any]]:
    """Every branch traced for an answer, the one whose snap it is first: its points, how many come
    before its upper state (the states the actuator passes through), dofs, how its lower state was
    found."""
    out = []
    while fr is not None:
        st = fr.states
        out.append({"kind": fr.kind, "points": len(fr.path.points),
                    "before_upper": st.k_before if st is not None else None, "dofs": int(fr.model.n),
                    "harmonics": [int(h) for h in fr.model.hn], "lower": fr.lower_method,
                    "lower_note": fr.lower_note})
        fr = fr.parent
    return out


def landing(res, n: int, N: int, fr) -> dict[str, Any]:
    """The ``--landing`` experiment: the branch stopped at its upper state and the lower state
    searched at fixed volume from there, against the answer's branch ``fr``."""
    t0 = time.process_time()
    head = follow_branch(res, locate_bifurcation(res, n), default_harmonics(n, N or None), stop_at_upper=True)
    low = find_lower_state(head.tracer, head.states, head.path.points, "upper state located")
    out = {"cpu_s": time.process_time() - t0, "points": len(head.path.points), "solver": low.solver,
           "message": low.message}
    if low.state is not None and fr is not None and fr.states.lower is not None:
        mh = fr.model
        out["lower_energy_rel_diff"] = abs(mh.energy(low.state.u) - mh.energy(fr.states.lower.u)) / abs(
            mh.energy(fr.states.upper.u) - mh.energy(fr.states.lower.u))
    return out


def compare_modes(res, chk, N: int, mode: str, out: dict, fr) -> dict[str, Any]:
    """The ``--compare`` figures: the other follow mode's answer on the same solve against this
    mode's ``out`` (its values) and ``fr`` (its branch)."""
    other = "full" if mode == "actuator" else "actuator"
    t0 = time.process_time()
    ans = followed_metrics(res, chk, N=N or None, mode=other)
    cpu = time.process_time() - t0
    return answer_diff(other, cpu, out, fr, ans)


def compare_axisym_first(res, chk, N: int, mode: str, out: dict, fr) -> dict[str, Any]:
    """The ``--compare-axisym-first`` figures: the same mode without the axisymmetric inverted state
    taken first where the axisymmetric path has no crossing to polish (``trace.axisym_lower_landing``
    giving nothing: the sphere path, the branch traced, the search at fixed volume) and where the
    sphere path gives up on an ``n_c >= 2`` landing (``trace.AXISYM_BEFORE_DESCENT = False``: the
    descent) or a branch of ``n_c >= 2`` is subcritical (``followed.AXISYM_FIRST_ALL = False``: the
    branch traced and searched), against ``out``/``fr``."""
    from snapjump_cli.fe.branch import followed, trace

    t0 = time.process_time()
    keep = trace.axisym_lower_landing, trace.AXISYM_BEFORE_DESCENT, followed.AXISYM_FIRST_ALL
    trace.axisym_lower_landing, trace.AXISYM_BEFORE_DESCENT, followed.AXISYM_FIRST_ALL = (
        (lambda *a, **k: None), False, False)
    try:
        ans = followed_metrics(res, chk, N=N or None, mode=mode)
    finally:
        trace.axisym_lower_landing, trace.AXISYM_BEFORE_DESCENT, followed.AXISYM_FIRST_ALL = keep
    return answer_diff(f"{mode} without the axisymmetric state first", time.process_time() - t0, out, fr, ans)


def answer_diff(other: str, cpu: float, out: dict, fr, ans) -> dict[str, Any]:
    """The answer values of ``ans`` (a ``followed_metrics`` answer, computed in ``cpu`` CPU-s) that
    differ from ``out`` and the distance between the two lower states (relative to ``fr``'s)."""
    import numpy as np

    keys = [k for k in set(out) | set(ans.values) if k not in ("follow_wall_s", "follow_note")]
    same = [k for k in keys if out.get(k) == ans.values.get(k) or (
        isinstance(out.get(k), float) and isinstance(ans.values.get(k), float)
        and np.isnan(out[k]) and np.isnan(ans.values[k]))]
    differ = sorted(set(keys) - set(same))
    # each float value's relative difference (to the larger of the two)
    rel = {k: abs(out[k] - ans.values[k]) / max(abs(out[k]), abs(ans.values[k]), 1e-300) for k in keys
           if isinstance(out.get(k), float) and isinstance(ans.values.get(k), float)}
    row = {"mode": other, "cpu_s": cpu, "values": len(keys), "differ": differ,
           "largest_rel_diff": max((rel[k] for k in differ if k in rel), default=0.0),
           "answers_rel_diff": {k: rel[k] for k in ANSWER_KEYS if k in rel}}  # the answers the jump model takes
    lo, lo2 = (fr.states.lower if fr is not None else None), (ans.branch.states.lower if ans.branch is not None else None)
    if lo is not None and lo2 is not None and lo.u.shape == lo2.u.shape:
        row["landing_distance"] = float(np.linalg.norm(lo2.u - lo.u) / np.linalg.norm(lo.u))
    return row


#: ``--repeat-followed``: a followed answer is computed again only while one solve takes at most
#: this CPU (the descents, ~100 s each, once).
REPEAT_FOLLOWED_BELOW_S = 30.0


def profile_one(label: str, scene, mesh, solver, N: int, mode: str, top: int | None, with_landing: bool,
                compare: bool = False, compare_axisym: bool = False, repeat: int = 3,
                repeat_followed: int = 1) -> dict:
    """Profile one design (steps 1-5 of the module's docstring); returns the numbers."""
    t0 = time.process_time()
    res = solve_scene(scene, mesh, solver)
    chk = check_harmonics(res, solver.harmonics)
    t_first = time.process_time() - t0
    t_axi = float("inf")
    for _ in range(max(1, int(repeat))):  # warm: the least of a few (the machine's noise is +-40 % on a 0.1 s solve)
        t0 = time.process_time()
        res = solve_scene(scene, mesh, solver)
        chk = check_harmonics(res, solver.harmonics)
        t_axi = min(t_axi, time.process_time() - t0)
    row: dict[str, Any] = {"design": label, "cpu_axisym_check_first_s": t_first, "cpu_axisym_check_s": t_axi,
                           "asym_first": bool(chk.asym_first), "asym_n": chk.asym_n, "mode": mode}
    if not row["asym_first"]:
        return row
    n = int(row["asym_n"])
    bif = locate_bifurcation(res, n)
    if bif is not None:  # compile the multi-harmonic kernels (JIT) outside the timing
        follow_branch(res, bif, default_harmonics(n, N or None), max_steps=3, stop_at_upper=True)
    t0 = time.process_time()
    try:
        with time_limit(solver.time_limit_s):
            ans = followed_metrics(res, chk, N=N or None, mode=mode)
        out, fr = ans.values, ans.branch
    except TimeLimitExceeded as exc:
        out, fr = {"follow_note": f"at the time limit: {exc}"}, None
        top = None
    runs = [time.process_time() - t0]
    while fr is not None and len(runs) < repeat_followed and runs[-1] <= REPEAT_FOLLOWED_BELOW_S:
        t0 = time.process_time()
        again = followed_metrics(res, chk, N=N or None, mode=mode)
        runs.append(time.process_time() - t0)
        if answer_diff("repeat", 0.0, out, fr, again)["differ"]:
            raise SystemExit(f"{label}: a repeated followed solve gave other answer values")
    row["cpu_followed_s"] = min(runs)
    row["cpu_followed_runs_s"] = runs
    row["ratio"] = row["cpu_followed_s"] / t_axi
    row["steps"] = len(fr.path.points) - 1 if fr is not None else None
    row["assemblies"] = getattr(fr.model, "n_assemblies", None) if fr is not None else None
    # (the diagonal blocks outside a branch formed for its stability checks, MultiHarmonicModel.block_band)
    row["block_assemblies"] = getattr(fr.model, "n_block_assemblies", None) if fr is not None else None
    # (its factorisations, those given up at a negative pivot by a descent's test, and the
    # assemblies of the branch it left, if any: the branch model's own count is among them)
    row["factorizations"] = getattr(fr.model, "n_factorizations", None) if fr is not None else None
    row["given_up"] = getattr(fr.model, "n_given_up", None) if fr is not None else None
    parent = getattr(fr, "parent", None) if fr is not None else None
    row["parent_assemblies"] = getattr(parent.model, "n_assemblies", None) if parent is not None else None
    row["branches"] = branches(fr)
    row.update({k: out.get(k) for k in ("followed", "follow_kind", "follow_sec_n", "dE_J", "dy_pole_m", "V_star_m3",
                                        "p_star_Pa", "follow_note")})
    if top is not None:
        prof = cProfile.Profile(time.process_time)
        prof.runcall(followed_metrics, res, chk, N=N or None, mode=mode)
        st = pstats.Stats(prof)
        total = max(sum(v[2] for v in st.stats.values()), 1e-12)
        cum: dict[str, float] = {}
        for (_, _, fname), (_, _, tt, ct, _) in st.stats.items():
            if fname in STAGES:
                cum[fname] = max(cum.get(fname, 0.0), ct)
        excl = sorted(((v[2], f"{Path(k[0]).parent.name}/{Path(k[0]).name}:{k[2]}") for k, v in st.stats.items()),
                      reverse=True)[:top]
        row["cprofile"] = {"total_s": total, "stages_cum_s": cum, "top_exclusive_s": [[n_, t] for t, n_ in excl]}
    if with_landing and bif is not None:
        row["landing"] = landing(res, n, N, fr)
    if compare and fr is not None:
        row["compare"] = compare_modes(res, chk, N, mode, out, fr)
    if compare_axisym and fr is not None:
        row["compare_axisym_first"] = compare_axisym_first(res, chk, N, mode, out, fr)
    return row


def _blocks(r: dict) -> str:
    """`` + N blocks`` for a row whose model formed diagonal blocks of its tangent (else empty)."""
    b = r.get("block_assemblies")
    return f" + {b} blocks" if b else ""


def _fmt(v: Any, nd: int = 3) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.{nd}g}"
    return str(v)


def set_constant(item: str) -> None:
    """``MODULE.NAME=VALUE``: set the constant ``NAME`` of module ``MODULE`` to the literal ``VALUE``
    (it must exist already)."""
    import ast
    import importlib

    target, _, value = item.partition("=")
    module, _, name = target.rpartition(".")
    mod = importlib.import_module(module)
    if not hasattr(mod, name):
        raise SystemExit(f"--set: {module} has no constant {name!r}")
    setattr(mod, name, ast.literal_eval(value))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.profile.follow", description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", default=["B"], help="named designs A..D or caps of CAPS (default B)")
    ap.add_argument("--sample", type=Path, default=None, help="a sweep config whose design list to take rows from")
    ap.add_argument("--rows", type=int, nargs="+", default=[0], help="rows of --sample (0-based)")
    ap.add_argument("--N", type=int, default=0, help="highest harmonic kept (default 4 n_c, as the sweep)")
    ap.add_argument("--mode", choices=("actuator", "full"), default="actuator", help="solver.follow_mode")
    ap.add_argument("--compare", action="store_true",
                    help="also solve with the other follow mode: its CPU, the answer values that differ, the lower states' distance")
    ap.add_argument("--compare-axisym-first", action="store_true",
                    help="also solve without the axisymmetric inverted state taken first (trace.axisym_lower_landing, "
                         "trace.AXISYM_BEFORE_DESCENT, followed.AXISYM_FIRST_ALL): its CPU, the answer values that differ, the lower states' distance")
    ap.add_argument("--landing", action="store_true",
                    help="also stop the branch at its upper state and search the landing state at fixed volume")
    ap.add_argument("--cprofile", type=int, nargs="?", const=15, default=None, metavar="K",
                    help="also break the followed solve down under cProfile (the K functions with most exclusive time)")
    ap.add_argument("--condensed", action="store_true",
                    help="trace the branches with the condensed element pressures in the Newton matrix "
                         "(snapjump_cli.fe.branch.trace.MIXED_TANGENT = False), as before the mixed one")
    ap.add_argument("--repeat", type=int, default=3,
                    help="warm axisymmetric solves and checks timed; the least is the ratio's denominator (default 3)")
    ap.add_argument("--repeat-followed", type=int, default=1, metavar="K",
                    help="followed solves timed (each again only while one takes at most "
                         f"{REPEAT_FOLLOWED_BELOW_S:g} CPU-s); the least is the ratio's numerator (default 1)")
    ap.add_argument("--set", action="append", default=[], metavar="MODULE.NAME=VALUE",
                    help="set a module constant first (a Python literal), e.g. "
                         "snapjump_cli.fe.branch.trace.MICRO_FOLD_LANDING_FIRST=False: the run with one way "
                         "of the solver switched off, for --json runs compared by bench.profile.answers")
    ap.add_argument("--debug", action="append", default=[], metavar="LOGGER",
                    help="print that logger's debug messages (e.g. snapjump_cli.fe.axisym.descent: each "
                         "descent iteration; snapjump_cli.fe.branch.trace: a branch's first step and folds)")
    ap.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    a = ap.parse_args(argv)
    if a.debug:
        logging.basicConfig(level=logging.WARNING, format="%(name)s: %(message)s")
        for name in a.debug:
            logging.getLogger(name).setLevel(logging.DEBUG)
    for item in a.set:
        set_constant(item)
    if a.condensed:
        from snapjump_cli.fe.branch import trace

        trace.MIXED_TANGENT = False
    rows = []
    print("| design | n_c | axisym + check CPU-s (first / warm) | followed CPU-s | ratio | steps | assemblies "
          "| kind | dE_J | note |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label, scene, mesh, solver in scenes(a.scenes, a.sample, a.rows):
        r = profile_one(label, scene, mesh, solver, a.N, a.mode, a.cprofile, a.landing, a.compare, a.compare_axisym_first,
                        a.repeat, a.repeat_followed)
        rows.append(r)
        print(f"| {label} | {_fmt(r.get('asym_n'))} | {r['cpu_axisym_check_first_s']:.3f} / "
              f"{r['cpu_axisym_check_s']:.3f} | {_fmt(r.get('cpu_followed_s'))} | {_fmt(r.get('ratio'))} "
              f"| {_fmt(r.get('steps'))} | {_fmt(r.get('assemblies'))}{_blocks(r)} | {_fmt(r.get('follow_kind'))} "
              f"| {_fmt(r.get('dE_J'), 4)} | {r.get('follow_note') or ('stays axisymmetric' if not r['asym_first'] else '')} |",
              flush=True)
    for r in rows:
        for b in r.get("branches", []):
            print(f"{r['design']}: branch {b['kind'] or '-'} (harmonics up to {b['harmonics'][-1]}, {b['dofs']} dofs): "
                  f"{b['points']} points, {b['before_upper']} before its upper state; lower state: "
                  f"{b['lower'] or '-'} {b['lower_note'] or ''}")
        if "landing" in r:
            print(f"{r['design']}: landing from the upper state: {r['landing']}")
        for key in ("compare", "compare_axisym_first"):
            if key not in r:
                continue
            c = r[key]
            print(f"{r['design']}: --mode {c['mode']} {c['cpu_s']:.3g} CPU-s ({c['cpu_s'] / r['cpu_followed_s']:.2f}x this "
                  f"solve's); {len(c['differ'])} of {c['values']} answer values differ {c['differ'] or ''} "
                  f"(largest relative difference {c['largest_rel_diff']:.2g}; "
                  f"{', '.join(f'{k} {v:.2g}' for k, v in c.get('answers_rel_diff', {}).items())}); "
                  f"lower states' distance {c.get('landing_distance', float('nan')):.2g}")
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
